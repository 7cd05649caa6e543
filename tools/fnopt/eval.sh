#!/bin/sh
# FNOpt evaluation against the XPBD reference: every table of docs/FNOPT.md, one CSV per table
# under data/fnopt/eval/ (rows are appended; delete a CSV to redo its table). Ground truth is
# cached in data/fnopt/gt/. Run from the repository root after building the weft CLI:
#
#   tools/fnopt/eval.sh build/bin/weft [table ...]
#   tables: baselines sweep motions iters speed handles res lbfgsref resgrid
#
# FNOPT_MODEL=path evaluates other weights (default: the shipped ones), FNOPT_EVAL_OUT=dir
# writes the CSVs elsewhere (default data/fnopt/eval), FNOPT_PRECISION=fp16|int8 runs the
# learned optimizer at reduced precision; FNOPT_NO_GUARD=1 turns the descent guard off and
# FNOPT_MAX_STEP=0 the trust region (together: the paper's update rule).
#
# Then: /usr/bin/python3 tools/fnopt/tables.py data/fnopt/eval > docs tables.
set -e
WEFT=${1:-build/bin/weft}
shift || true
TABLES=${*:-"baselines sweep motions iters speed handles res lbfgsref resgrid"}
OUT=${FNOPT_EVAL_OUT:-data/fnopt/eval}
mkdir -p "$OUT"
# material: the best point of `weft fnopt fit` inside the training ranges (docs/FNOPT.md, "Material fit")
MAT=${FNOPT_MATERIAL:-100,3,5}
run() { nice -n 10 "$WEFT" fnopt run --gt --material "$MAT" ${FNOPT_MODEL:+--model "$FNOPT_MODEL"} \
          ${FNOPT_PRECISION:+--precision "$FNOPT_PRECISION"} ${FNOPT_NO_GUARD:+--no-guard} \
          ${FNOPT_MAX_STEP:+--max-step "$FNOPT_MAX_STEP"} "$@" > /dev/null; }

for t in $TABLES; do
  case $t in
  baselines) # Table 6: classical optimizers vs the learned one at equal iterations, 32 x 32
    for it in 10 50 100 500; do
      run --optimizer gd --lr 0.01 --iters $it --frames 90 --csv $OUT/baselines.csv
      run --optimizer adam --lr 0.02 --iters $it --frames 90 --csv $OUT/baselines.csv
      run --optimizer lbfgs --lr 1 --iters $it --frames 90 --csv $OUT/baselines.csv
    done ;; # the learned rows on the same scene are in iters.csv
  sweep) # step-size sweep of the classical optimizers at 100 iterations (same scene)
    for lr in 0.003 0.03 0.1; do run --optimizer gd --lr $lr --iters 100 --frames 90 --csv $OUT/sweep.csv; done
    for lr in 0.005 0.1; do run --optimizer adam --lr $lr --iters 100 --frames 90 --csv $OUT/sweep.csv; done
    for lr in 0.3; do run --optimizer lbfgs --lr $lr --iters 100 --frames 90 --csv $OUT/sweep.csv; done ;;
  motions) # Table 1: the motion set at the training resolution (90 of the 165 frames: rest,
           # the move out and half of the move back)
    for m in ${FNOPT_MOTIONS:-xy xy_opp yz xz xyz xyz3 rot_h0 rot_h1}; do
      run --motion $m --frames 90 --csv $OUT/motions.csv
    done ;;
  iters) # Table 7: error and ms/frame against the inner iterations (same scene as baselines)
    for it in 5 10 20; do run --iters $it --frames 90 --csv $OUT/iters.csv; done ;;
  speed) # speed generalisation (speed 1 is the xy row of motions)
    for s in 1.2 1.5 2; do run --speed $s --frames 90 --csv $OUT/speed.csv; done ;;
  handles) # handle placements
    for h in corners diagonal middle corner-center single-middle single-center; do
      run --handles $h --frames 60 --csv $OUT/handles.csv
    done ;;
  res) # super-evaluation: trained at 32, run at 64 and 100 (short: the cost grows with res^2)
    run --res 32 --frames 40 --csv $OUT/res.csv
    run --res 64 --frames 40 --csv $OUT/res.csv
    run --res 100 --frames 20 --csv $OUT/res.csv ;;
  lbfgsref) # converged L-BFGS on the same scenes: the gap the FNOpt energy itself leaves
    for h in corners diagonal middle corner-center single-middle single-center; do
      run --handles $h --frames 60 --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/handles_lbfgs.csv
    done
    for m in xy_opp rot_h0 rot_h1 yz xz; do
      run --motion $m --frames 90 --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/motions_lbfgs.csv
    done
    for s in 1.5 2; do
      run --speed $s --frames 90 --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/speed_lbfgs.csv
    done
    run --res 64 --frames 40 --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/res_lbfgs.csv ;;
  resgrid) # stability across resolutions (trained at 32), 40 frames each: the learned optimizer
           # (three precisions, and the paper's rule: no guard, no trust region), the classical ones at equal iterations and the
           # converged solve (L-BFGS, 100 iterations) on xy; x2 speed and the handle placements at
           # the resolutions the CPU budget allows
    for r in 32 64 100 128; do
      run --res $r --frames 40 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --no-guard --max-step 0 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --precision fp16 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --precision int8 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --optimizer gd --lr 0.01 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --optimizer adam --lr 0.02 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --optimizer lbfgs --lr 1 --csv $OUT/resgrid.csv
      run --res $r --frames 40 --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/resgrid.csv
    done
    for m in 1 0.25; do # the trust region's size at 100 x 100; 0 with and without the guard
      run --res 100 --frames 40 --max-step $m --csv $OUT/resgrid_cap.csv
    done
    run --res 100 --frames 40 --max-step 0 --csv $OUT/resgrid_cap.csv
    run --res 100 --frames 40 --max-step 0 --no-guard --csv $OUT/resgrid_cap.csv
    for r in 32 64 100; do
      run --res $r --frames 40 --speed 2 --csv $OUT/resgrid_speed.csv
      run --res $r --frames 40 --speed 2 --precision int8 --csv $OUT/resgrid_speed.csv
      run --res $r --frames 40 --speed 2 --optimizer lbfgs --lr 1 --csv $OUT/resgrid_speed.csv
      run --res $r --frames 40 --speed 2 --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/resgrid_speed.csv
      for h in diagonal middle corner-center single-middle single-center; do
        run --res $r --frames 40 --handles $h --csv $OUT/resgrid_handles.csv
        run --res $r --frames 40 --handles $h --optimizer lbfgs --lr 1 --iters 100 --csv $OUT/resgrid_handles.csv
      done
    done ;;
  esac
done
