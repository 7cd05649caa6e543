#!/bin/bash
# One machine window turned into FNOpt training progress, in one command:
#
#   tools/fnopt/window.sh
#
# Continues training (tools/fnopt/train.py, the run-3 settings of docs/FNOPT.md) for WINDOW_MIN
# minutes of wall time in all (default 9, for a 10-minute device call), then writes to OUT
# (default $OUT, else out/fnopt_window):
#   run/            the resumable state (checkpoint.pt, loss_log.csv): carry it to the next window
#                   and pass it as RESUME=<that folder>, so that window continues from here
#   fnopt_32.safetensors   the weights (copy to tools/fnopt/models/ and regenerate the goldens to ship)
#   window.md       one row for docs/FNOPT.md's runs table: date, machine, minutes, optimizer steps
#                   before -> after, e3D on the xy scene (90 frames, 32 x 32) before -> after
# Without RESUME it starts from the shipped weights (fresh optimizer and pool). train.py runs on
# the CPU (THREADS, default all cores but one): on a lent GPU machine it uses the 16 cores.
# The e3D needs the weft CLI (WEFT, default build/bin/weft); without it the row says "-".
# Env: WINDOW_MIN, MARGIN_S (default 30), OUT, RESUME, THREADS, WEFT, PYTHON (default /usr/bin/python3).
set -u
cd "$(dirname "$0")/../.." || exit 1
T0=$(date +%s)
WINDOW_MIN=${WINDOW_MIN:-9}
MARGIN_S=${MARGIN_S:-30}
DEST=${OUT:-out/fnopt_window}
W=${WEFT:-build/bin/weft}
PY=${PYTHON:-/usr/bin/python3}
SHIPPED=tools/fnopt/models/fnopt_32.safetensors
n=$(nproc)
THREADS=${THREADS:-$(( n > 2 ? n - 1 : 1 ))}
mkdir -p "$DEST/run" || exit 1
if [ -n "${RESUME:-}" ]; then
    [ -f "$RESUME/checkpoint.pt" ] || { echo "window: no checkpoint.pt in RESUME=$RESUME" >&2; exit 1; }
    [ "$(cd "$RESUME" && pwd)" = "$(cd "$DEST/run" && pwd)" ] || cp "$RESUME"/checkpoint.pt "$RESUME"/loss_log.csv "$DEST/run/" || exit 1
fi

# the weights the window starts from: the carried run's export, else the shipped ones
START=$SHIPPED
[ -f "${RESUME:-/nonexistent}/fnopt_32.safetensors" ] && START=$RESUME/fnopt_32.safetensors
steps() { "$PY" - "$1" <<'EOF'
import json, struct, sys
with open(sys.argv[1], 'rb') as f:
    meta = json.loads(f.read(struct.unpack('<Q', f.read(8))[0]))['__metadata__']
c = json.loads(meta.get('config', '{}'))
print(int(c.get('batches_done', 0)) + int(c.get('init_batches', 0)))
EOF
}
e3d() {
    if [ -x "$W" ]; then
        "$W" fnopt run --frames 90 --gt --material 100,3,5 --model "$1" | tail -1 | cut -d, -f19
    else
        echo "-"
    fi
}
s0=$(steps "$START") || exit 1
e0=$(e3d "$START")

left=$(( T0 + WINDOW_MIN * 60 - MARGIN_S - $(date +%s) - 20 )) # 20 s for the evaluation after
[ "$left" -gt 30 ] || { echo "window: no time left to train ($left s)" >&2; exit 1; }
"$PY" tools/fnopt/train.py --out "$DEST/run" --init-from "$START" --epochs 20 --batches 250 --lr 5e-4 \
    --gravity 0.06:0.45 --speed 0.5:3 --threads "$THREADS" --max-seconds "$left" \
    --export "$DEST/fnopt_32.safetensors" > "$DEST/train.log" 2>&1
rc=$?
[ $rc -eq 0 ] && [ -f "$DEST/fnopt_32.safetensors" ] || { echo "window: training failed (rc $rc, $DEST/train.log)" >&2; exit 1; }
cp "$DEST/fnopt_32.safetensors" "$DEST/run/fnopt_32.safetensors"
s1=$(steps "$DEST/fnopt_32.safetensors") || exit 1
e1=$(e3d "$DEST/fnopt_32.safetensors")
mins=$(( ($(date +%s) - T0 + 59) / 60 ))
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')
printf '| %s | %s, %s threads | %s min | %s -> %s | e3D %s -> %s |\n' "$(date -u +%F)" "$cpu" "$THREADS" "$mins" \
    "$s0" "$s1" "$e0" "$e1" | tee "$DEST/window.md"
