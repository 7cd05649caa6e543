#!/bin/bash
# One lent GPU window turned into progress on the worn-garment model, in one command.
#
#   tools/train/gpu_data.sh bundle                 here: weft, libweft.so.0 and their libraries
#                                                  into .dev (the machine has no libcjson or cglm)
#   tools/train/gpu_window.sh                      there (device run, carry .dev): data, training,
#                                                  results into $OUT; ends within WINDOW_MIN minutes
#
# What it does, all inside WINDOW_MIN minutes of wall time (default 9, for a 10-minute call):
#   1. data on the machine's cores (all but two) for GEN_MIN minutes (default 3): garment
#      sequences of the mocap library's train clips (`weft simgen --mocap train`: real motion,
#      body parts, no arm spread), the validation windows (the same in every window) on one
#      process, the training windows beside procedural garments (`weft simgen --all --only
#      garment --tier 1k --split train`), one simgen per core, a new slice of the plans in each
#      window (ROTATE); then the S tracks of the skinned prior (LBS rollouts);
#   2. training continues from the committed resumable checkpoint (RESUME, default
#      tools/train/resume/garment.pt: weights, and optimiser state and step when a window wrote
#      it) on the GPU (CPU when there is none), validating first and every EVAL_EVERY steps,
#      keeping the best weights, until MARGIN_S seconds before the window's end (train.py also
#      keeps back its longest step and validation so far, so the last ones end inside it);
#   3. $OUT (or DEST) gets ckpt.pt (the next resumable checkpoint: commit it as RESUME), best.pt
#      (export.py input), log.csv, train.err and window.md (one row for docs/TRAINING.md's table:
#      date, device, minutes, steps, validation MVE before -> after).
#
# With a prepared set (PACK, default data/window_pack, made here by `tools/train/gpu_data.sh
# window-pack` and carried: its val/ folder and one train/partN folder, within the 64 MiB a call
# carries) step 1 is skipped (GEN_MIN defaults to 0, no weft binary is needed) and the whole window
# trains on the pack's real-motion windows and procedural garments, validating on its val windows;
# GEN_MIN > 0 generates training windows beside it as above (the pack's val replaces the val run).
#
# It also runs on two CPU cores (slower, same files): WINDOW_MIN=20 GEN_MIN=8 tools/train/gpu_window.sh
# Env: WINDOW_MIN, GEN_MIN, MARGIN_S (default 40), EVAL_EVERY (default 200), EVAL_FRAMES (default
# 120), BATCH (default 64 on a GPU, 32 on CPU), LR (default 2e-4), ROLLOUT (default 10), JOBS (default: cores - 2),
# DATA (default data/window), BUNDLE (default .dev; none: build/bin/weft), RESUME, ROTATE (default
# 8), WINDOW_INDEX (default: the checkpoint's step / 500), PACK (default data/window_pack).
set -u
cd "$(dirname "$0")/../.." || exit 1
T0=$(date +%s)
WINDOW_MIN=${WINDOW_MIN:-9}
PACK=${PACK:-data/window_pack}
npack=$(find "$PACK" -name '*.wpk.npz' 2>/dev/null | wc -l)
if [ "$npack" -gt 0 ]; then GEN_MIN=${GEN_MIN:-0}; else GEN_MIN=${GEN_MIN:-3}; fi
MARGIN_S=${MARGIN_S:-40}
DATA=${DATA:-data/window}
RESUME=${RESUME:-tools/train/resume/garment.pt}
DEST=${DEST:-${OUT:-out/window}}
B=${BUNDLE:-.dev}
RUN=$DATA/run
mkdir -p "$DATA" "$RUN" "$DEST" || exit 1
if [ -x "$B/weft" ]; then
    W=$PWD/$B/weft
    export LD_LIBRARY_PATH=$PWD/$B${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
else
    W=$PWD/build/bin/weft
fi
gen_s=$(awk "BEGIN{print int(${GEN_MIN} * 60)}")
if [ "$gen_s" -gt 0 ]; then
    [ -x "$W" ] || { echo "gpu_window: no weft ($B/weft or build/bin/weft); run tools/train/gpu_data.sh bundle" >&2; exit 1; }
    ldd "$W" | grep 'not found' && exit 3
fi
[ -f "$RESUME" ] || { echo "gpu_window: no resumable checkpoint $RESUME" >&2; exit 1; }
PY=${PYTHON:-python3}
export WEFT_MOCAP_DIR=$PWD/samples/mocap PYTHONUNBUFFERED=1
T_END=$(awk "BEGIN{print int($T0 + ${WINDOW_MIN} * 60)}")
left_s() { echo $((T_END - $(date +%s))); }
log() { echo "[$(( $(date +%s) - T0 )) s] $*" | tee -a "$DEST/window.log"; }

# 1. data: one simgen per core, mocap and procedural shards side by side. A window makes only
# a few dozen sequences and a machine starts bare, so each window takes another slice of the plans:
# the plans are cut into ROTATE times as many shards as processes, and window k (the checkpoint's
# step / 500, or WINDOW_INDEX) takes slice k mod ROTATE.
n=${JOBS:-$(( $(nproc) > 3 ? $(nproc) - 2 : 1 ))}
nm=$(( n * 2 / 3 > 1 ? n * 2 / 3 - 1 : 1 )); np=$(( n - nm - 1 > 0 ? n - nm - 1 : 1 ))
R=${ROTATE:-8}
ckpt_step() {  # the training step a checkpoint holds (-1 when there is none)
    [ -f "$1" ] || { echo -1; return; }
    "$PY" -c "import sys, torch
try: c = torch.load(sys.argv[1], map_location='cpu', weights_only=False)
except TypeError: c = torch.load(sys.argv[1], map_location='cpu')
print(int(c.get('step', 0)))" "$1" 2>/dev/null || echo 0
}
resume_step=$(ckpt_step "$RESUME")
k=${WINDOW_INDEX:-$(( resume_step / 500 ))}
slice=$(( k % R ))
if [ "$gen_s" -gt 0 ]; then
    nval=$([ "$npack" -gt 0 ] && echo 0 || echo 1)  # a pack brings its own val windows
    log "gen: $nval mocap val + $nm mocap + $np procedural simgen for $gen_s s ($(nproc) cores), plan slice $slice of $R"
    # the validation windows are the same in every window (one process, the plan's first val names),
    # so the start and end figures of different windows compare
    [ "$nval" -eq 1 ] && timeout -s INT "$gen_s" "$W" simgen --out "$DATA/seq" --mocap train --split val \
        > "$DATA/gen_val.log" 2>&1 < /dev/null &
    for i in $(seq 0 $((nm - 1))); do
        timeout -s INT "$gen_s" "$W" simgen --out "$DATA/seq" --mocap train --split train \
            --shard "$((slice * nm + i))/$((R * nm))" > "$DATA/gen_m$i.log" 2>&1 < /dev/null &
    done
    for i in $(seq 0 $((np - 1))); do
        timeout -s INT "$gen_s" "$W" simgen --out "$DATA/seq" --all --only garment --tier 1k --split train \
            --shard "$((slice * np + i))/$((R * np))" > "$DATA/gen_p$i.log" 2>&1 < /dev/null &
    done
    wait
    "$W" simgen --out "$DATA/seq" --manifest-only > /dev/null 2>&1

    # 2. S tracks (LBS rollouts) for the skinned prior (a pack carries its own)
    for s in train val; do
        "$W" eval --seq "$DATA/seq" --split $s --method lbs --ccd off --write-pos "$DATA/skin" > "$DATA/skin_$s.log" 2>&1 &
    done
    wait
    log "skin: $(ls "$DATA/skin" 2>/dev/null | wc -l) S tracks"
fi
acc=$(grep -l '"accepted":[[:space:]]*true' "$DATA"/seq/*/meta.json 2>/dev/null | wc -l)
tot=$(ls "$DATA"/seq/*/meta.json 2>/dev/null | wc -l)
mval=$(grep -l '"accepted":[[:space:]]*true' $(grep -l '"split":[[:space:]]*"val"' "$DATA"/seq/mocap_*/meta.json \
    2>/dev/null) 2>/dev/null | wc -l)
macc=$(grep -l '"accepted":[[:space:]]*true' "$DATA"/seq/mocap_*/meta.json 2>/dev/null | wc -l)
[ "$gen_s" -gt 0 ] && log "gen: $acc accepted of $tot finished ($mval mocap val); $macc mocap accepted"
if [ "$npack" -gt 0 ]; then  # packs hold accepted sequences only
    pval=$(find "$PACK/val" -name 'mocap_*.wpk.npz' 2>/dev/null | wc -l)
    log "pack: $npack sequences under $PACK ($(find "$PACK" -name 'mocap_*.wpk.npz' | wc -l) mocap, $pval of them val)"
    acc=$((acc + npack)); mval=$((mval + pval))
fi
[ "$acc" -gt 0 ] || { log "gen: nothing accepted; stopping"; exit 1; }

# 3. training from the resumable checkpoint until the margin
# a run folder left by an earlier call on this machine continues unless RESUME is further along
[ "$(ckpt_step "$RUN/ckpt.pt")" -ge "$resume_step" ] || cp "$RESUME" "$RUN/ckpt.pt"
rows0=$(cat "$RUN/log.csv" 2>/dev/null | wc -l)
train_s=$(( $(left_s) - MARGIN_S ))
[ "$train_s" -gt 30 ] || { log "train: only $train_s s left; stopping"; exit 1; }
dev=--cuda batch=${BATCH:-64}
$PY -c 'import torch,sys; sys.exit(0 if torch.cuda.is_available() else 1)' 2>/dev/null || { dev=""; batch=${BATCH:-32}; }
log "train: $train_s s on ${dev:-cpu} at batch $batch from $RESUME"
if [ -n "$dev" ] && command -v nvidia-smi > /dev/null; then  # how busy the GPU is (docs/TRAINING.md)
    nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader -l 5 > "$DEST/gpu_util.csv" 2>&1 &
    smi=$!
fi
"$PY" tools/train/train.py --data "$DATA/seq" "$PACK" --skin "$DATA/skin" --out "$RUN" --resume $dev --threads 2 \
    --steps 1000000 --max-minutes "$(awk "BEGIN{print ${train_s} / 60}")" --scenarios garment --pins \
    --batch "$batch" --lr "${LR:-2e-4}" --rollout-max "${ROLLOUT:-10}" --rollout-min "${ROLLOUT:-10}" \
    --noise-std 5e-4 --lambda-strain 100 --eval-first --eval-every "${EVAL_EVERY:-200}" \
    --eval-frames "${EVAL_FRAMES:-120}" --keep-best --ckpt-every 200 > "$DEST/train.err" 2>&1
rc=$?
[ -n "${smi:-}" ] && kill "$smi" 2>/dev/null
util=$(awk -F'[ ,%]+' '{s += $1; n++} END {if (n) printf "%.0f %%", s / n}' "$DEST/gpu_util.csv" 2>/dev/null)
[ -n "$util" ] && log "train: mean GPU utilisation $util"
cp "$RUN/ckpt.pt" "$DEST/ckpt.pt" 2>/dev/null
cp "$RUN/best.pt" "$DEST/best.pt" 2>/dev/null
cp "$RUN/log.csv" "$DEST/log.csv" 2>/dev/null
# this call's rows of the run's log (an earlier call on the machine wrote the ones before)
new_rows() { tail -n +$(( rows0 > 0 ? rows0 + 1 : 2 )) "$RUN/log.csv" 2>/dev/null; }
first=$(new_rows | awk -F, '$9 != "" {print $9; exit}')
best=$(new_rows | awk -F, '$9 != "" {print $9}' | sort -g | head -1)
s0=$(new_rows | awk -F, '{print $1; exit}')
s1=$(new_rows | awk -F, '{s = $1} END {print s}')
gpu=$(command -v nvidia-smi > /dev/null && nvidia-smi --query-gpu=name --format=csv,noheader | head -1)
mins=$(awk "BEGIN{printf \"%.1f\", ($(date +%s) - $T0) / 60}")
echo "| $(date -u +%Y-%m-%d) | ${gpu:-$(nproc)-core CPU} | $mins | $s0 -> $s1 | $acc ($mval mocap val) | ${first:-?} -> ${best:-?} |" \
    | tee "$DEST/window.md"
log "train: exit $rc"
exit $rc
