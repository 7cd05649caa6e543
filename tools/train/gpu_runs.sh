#!/bin/bash
# Training runs sharing one lent GPU machine.
#
#   SET=skin MINUTES=7.5 tools/train/gpu_runs.sh train
#       run every run of the set side by side in the foreground for at most MINUTES of training
#       each (they checkpoint and stop; the data loading comes on top), then collect. Run it again
#       on the same machine and each run resumes where it stopped, until its BUDGET minutes of
#       schedule (lr decay, rollout curriculum) are used up.
#   SET=skin tools/train/gpu_runs.sh launch     the same runs detached (setsid, BUDGET minutes),
#                                               for a machine held longer than one call
#   SET=skin tools/train/gpu_runs.sh collect    print each run's progress and validation rows, and
#                                               pack each run folder as RUN.tgz into $OUT (or DEST)
#
# The runs start from checkpoints of earlier models (tools/train/models/NAME.ckpt.pt), which left the
# tree when the models folder kept only shipped weights: `git show 5c87946:tools/train/models/NAME.ckpt.pt
# > tools/train/models/NAME.ckpt.pt` brings one back. The worn-garment model trains with gpu_window.sh.
# Runs go to data/gpu/runs/NAME. Sets (docs/MODEL.md, "Training"):
#   skin     the skinned prior on the grown set, from the first `game` and from scratch (data:
#            pack.py --skin under data/pack179s)
#   skin2    the skin set's game runs continued with longer rollouts (curriculum 1 -> 10), keeping
#            the weights whose 240-frame validation rollouts are best (--keep-best); their starting
#            checkpoints are the skin runs' under data/gpu/init/
#   pins     the skinned prior with the sequences' pins in every training and validation rollout
#            (train.py --pins: grasped and waistband vertices follow the reference, as weft eval
#            --pins all), rollouts to 10, 240-frame keep-best: `game` from
#            scratch with the gripper drawn twice as often, the shipped `game` fine-tuned, and the
#            shipped `game` cut to 16 and 8 latents (cut_latents.py, into data/gpu/init/) fine-tuned
#            at their K (data: pack.py --skin of the grown set, with its pin masks, under
#            data/pack_pins)
#   long     the shipped `game` and `game_k16` fine-tuned with pins and rollouts to 30 steps, one run
#            drawing drops three times as often, one rollouts to 10 with a 10x contact weight
#            (data: sequence folders under data/refsim as `weft simgen` writes them, generated on the
#            GPU machine's own cores, with their S tracks under data/skin)
#   ballistic  drop specialists with the ballistic prior (free fall in the prior, docs/MODEL.md
#            "Ballistic prior: a drop specialist"): `game_k16` fine-tuned on drops with beta 1 and 0.9, one on drops
#            and the gripper, and one from scratch at the game_k16 size; rollouts to 30 steps
#            (data: as for long, the S tracks are not needed)
#   dropgpu  the shipped drop specialist `drop` continued at batch 64 (rollouts 8 -> 20, and
#            8 -> 30 with a 10x contact weight), beside `game_k16` fine-tuned with the ballistic prior
#            as `drop` began; snapshots every 100 steps, chosen afterwards on all 14 validation
#            drops with `weft eval` (data: drops only, ONLY=drop DATA=data/drops gpu_data.sh gen,
#            made on the machine's cores just before; NO_SKIN=1)
set -u
cd "$(dirname "$0")/../.." || exit 1
R=data/gpu/runs
SET=${SET:-skin}
case "$SET" in
    skin) RUNS="game_skin game_skin0"; DATA=${DATA:-data/pack179s}; BUDGET=${BUDGET:-15} ;;
    skin2) RUNS="s0_r10 s_r10 s0_contact ship_skin_r10"; DATA=${DATA:-data/pack179s}; BUDGET=${BUDGET:-7.5}
           EXTRA="--eval-every 500 --eval-frames 238 --keep-best --rollout-max 10" ;;
    pins) RUNS="game_pins0 game_pins_ft game_k16_ft game_k8_ft"; DATA=${DATA:-data/pack_pins}; BUDGET=${BUDGET:-17}
          EXTRA="--eval-every 1000 --eval-frames 238 --keep-best --rollout-max 10 --pins --max-train-vertices 5000" ;;
    long) RUNS="long_r30 long_r30_drop long_contact k16_r30"; DATA=${DATA:-data/refsim}; BUDGET=${BUDGET:-14}
          EXTRA="--skin data/skin --eval-every 400 --eval-frames 238 --keep-best --pins --max-train-vertices 5000" ;;
    ballistic) RUNS="ball_drop ball_drop_b09 ball_dg ball_drop0"; DATA=${DATA:-data/refsim}; BUDGET=${BUDGET:-14}
          EXTRA="--eval-every 400 --eval-frames 238 --keep-best --pins --max-train-vertices 5000 --rollout-max 30" ;;
    dropgpu) RUNS="drop_r20 drop_r30c ball_k16"; DATA=${DATA:-data/drops}; BUDGET=${BUDGET:-5}
          EXTRA="--eval-every 150 --eval-frames 238 --keep-best --snapshot-every 100 --scenarios drop" ;;
    *) echo "unknown SET=$SET (skin|skin2|pins|long|ballistic|dropgpu)" >&2; exit 2 ;;
esac

run_args() {  # the arguments of run $1 (besides the common ones)
    case "$1" in
        game_skin) echo "--init-from tools/train/models/game.ckpt.pt --config '{\"prior\":\"skinned\"}' --batch 32 --lr 5e-4" ;;
        game_skin0) echo "--preset game --config '{\"prior\":\"skinned\"}' --batch 32 --lr 1e-3" ;;
        s0_r10) echo --init-from data/gpu/init/game_skin0.pt --batch 32 --lr 3e-4 ;;
        s_r10) echo --init-from data/gpu/init/game_skin.pt --batch 32 --lr 3e-4 ;;
        s0_contact) echo --init-from data/gpu/init/game_skin0.pt --batch 32 --lr 3e-4 --lambda-contact 0.5 ;;
        ship_skin_r10) echo "--init-from tools/train/models/game.ckpt.pt --config '{\"prior\":\"skinned\"}' --batch 32 --lr 5e-4" ;;
        game_pins0) echo "--preset game --config '{\"prior\":\"skinned\"}' --batch 32 --lr 1e-3 --scenario-weight gripper=2" ;;
        game_pins_ft) echo --init-from tools/train/models/game.ckpt.pt --batch 32 --lr 3e-4 ;;
        game_k16_ft) echo --init-from data/gpu/init/game_k16.pt --batch 32 --lr 3e-4 ;;
        game_k8_ft) echo --init-from data/gpu/init/game_k8.pt --batch 32 --lr 3e-4 ;;
        long_r30) echo --init-from tools/train/models/game.ckpt.pt --batch 32 --lr 3e-4 --rollout-max 30 ;;
        long_r30_drop) echo --init-from tools/train/models/game.ckpt.pt --batch 32 --lr 3e-4 --rollout-max 30 \
                            --scenario-weight drop=3 ;;
        long_contact) echo --init-from tools/train/models/game.ckpt.pt --batch 32 --lr 3e-4 --rollout-max 10 \
                           --lambda-contact 0.5 --scenario-weight drop=2 ;;
        k16_r30) echo --init-from tools/train/models/game_k16.ckpt.pt --batch 32 --lr 3e-4 --rollout-max 30 ;;
        ball_drop) echo "--init-from tools/train/models/game_k16.ckpt.pt --config '{\"prior\":\"ballistic\"}'" \
                        --scenarios drop --batch 32 --lr 3e-4 ;;
        ball_drop_b09) echo "--init-from tools/train/models/game_k16.ckpt.pt" \
                            "--config '{\"prior\":\"ballistic\",\"prior_beta\":0.9}' --scenarios drop --batch 32 --lr 3e-4" ;;
        ball_dg) echo "--init-from tools/train/models/game_k16.ckpt.pt --config '{\"prior\":\"ballistic\"}'" \
                      --scenarios drop,gripper --batch 32 --lr 3e-4 ;;
        drop_r20) echo --init-from tools/train/models/drop.ckpt.pt --batch 64 --lr 1.5e-4 --rollout-min 8 \
                       --rollout-max 20 ;;
        drop_r30c) echo --init-from tools/train/models/drop.ckpt.pt --batch 64 --lr 1.5e-4 --rollout-min 8 \
                        --rollout-max 30 --lambda-contact 0.5 ;;
        ball_k16) echo "--init-from tools/train/models/game_k16.ckpt.pt --config '{\"prior\":\"ballistic\"}'" \
                       --batch 64 --lr 3e-4 --rollout-max 20 ;;
        ball_drop0) echo "--preset game --config '{\"prior\":\"ballistic\",\"K\":16}' --scenarios drop --batch 32 --lr 1e-3" ;;
    esac
}

start() {  # start every run of the set in the background; $1: extra arguments for all
    export PYTHONUNBUFFERED=1
    mkdir -p $R
    local common="--data $DATA --steps 1000000 --budget-minutes $BUDGET --eval-every 2000
                  --ckpt-every 500 --cuda --threads 2 --noise-std 5e-4 --lambda-strain 100 --resume ${EXTRA:-}"
    for n in $RUNS; do
        # shellcheck disable=SC2086,SC2046
        eval setsid nohup "${PYTHON:-python3}" tools/train/train.py $common $1 --out $R/$n $(run_args $n) \
            ">> $R/$n.err 2>&1 < /dev/null &"
    done
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
        # with snapshots the optimizer state (ckpt.pt) stays behind: a returned file is at most 16 MiB
        local x=""
        compgen -G "$R/$n/snap_*.pt" > /dev/null && x=--exclude=ckpt.pt
        if [ -n "$dest" ] && [ -d $R/$n ]; then tar czf "$dest/$n.tgz" $x -C $R $n $n.err; fi
    done
}

case "${1:-}" in
    train)
        start "--max-minutes ${MINUTES:-7.5}"
        while pgrep -f '[t]ools/train/train.py' > /dev/null; do sleep 5; done
        collect ;;
    launch) start "" ;;
    collect) collect ;;
    *) echo "usage: SET=skin|skin2|pins|long|ballistic|dropgpu $0 train|launch|collect" >&2; exit 2 ;;
esac
