#!/bin/bash
# Training runs sharing one lent GPU machine, for a machine that is held for a fixed time.
#
#   tools/train/gpu_runs.sh launch     start the runs detached (setsid), so they outlive the call
#                                      that launched them; each ends after BUDGET minutes (23)
#   tools/train/gpu_runs.sh collect    print each run's progress and validation rows, and pack each
#                                      run folder as RUN.tgz into $OUT (or DEST) to bring it back
#
# Data: the packed set (tools/train/pack.py) under data/pack. Runs go to data/gpu/runs/NAME.
# These four are the runs the shipped models came from (docs/MODEL.md, "Training").
set -u
cd "$(dirname "$0")/../.." || exit 1
R=data/gpu/runs
RUNS="game_ft unified_ft game_prev unified_prev"

launch() {
    export PYTHONUNBUFFERED=1
    mkdir -p $R
    local common="--data data/pack --steps 1000000 --budget-minutes ${BUDGET:-23} --eval-every 2000
                  --ckpt-every 500 --cuda --threads 2 --noise-std 5e-4 --lambda-strain 100"
    go() {
        local name=$1; shift
        # shellcheck disable=SC2086
        setsid nohup "${PYTHON:-python3}" tools/train/train.py $common --out $R/$name "$@" \
            > $R/$name.err 2>&1 < /dev/null &
    }
    go game_ft --preset game --init-from tools/train/models/game.ckpt.pt --batch 32 --lr 5e-4
    go unified_ft --preset unified --init-from tools/train/models/unified.ckpt.pt --batch 32 --lr 5e-4
    go game_prev --preset game --config '{"prior":"previous"}' --batch 32 --lr 1e-3
    go unified_prev --preset unified --config '{"prior":"previous"}' --batch 32 --lr 1.5e-3
    sleep 5
    echo "$(pgrep -fc '[t]ools/train/train.py') runs started"
}

collect() {
    local dest=${DEST:-${OUT:-}}
    command -v nvidia-smi > /dev/null && nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader
    for n in $RUNS; do
        echo "== $n: $(grep -c . $R/$n/log.csv 2>/dev/null) log rows"
        tail -c 400 $R/$n.err 2>/dev/null | tr '\r' '\n' | tail -3
        awk -F, '$9 != ""' $R/$n/log.csv 2>/dev/null | tail -3
        if [ -n "$dest" ] && [ -d $R/$n ]; then tar czf "$dest/$n.tgz" -C $R $n $n.err; fi
    done
}

case "${1:-}" in
    launch) launch ;;
    collect) collect ;;
    *) echo "usage: $0 launch|collect" >&2; exit 2 ;;
esac
