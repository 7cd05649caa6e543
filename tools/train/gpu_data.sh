#!/bin/bash
# Training data made on a GPU machine's own cores, for a training machine that starts without data.
# A lent machine has many cores but no libcjson or cglm and no package registry, so the weft
# tool is built here and carried (x86-64 only, like the machine).
#
#   tools/train/gpu_data.sh bundle [DIR]   here: build a minimal `weft` (no samples, tests or
#                                          renderer) and libweft.so.0 into DIR (default .dev) with the shared
#                                          libraries it needs besides libc (.dev is git-ignored;
#                                          name it in the device call's carry)
#   tools/train/gpu_data.sh gen            there: one detached `weft simgen` per core, 1k tier,
#                                          train names on all but two cores, val names on two
#                                          (JOBS=N overrides the core count); returns at once
#   tools/train/gpu_data.sh prepare        there: stop generation, rebuild the manifest, write
#                                          the S tracks (LBS rollouts) the skinned prior needs
#                                          under data/skin; then `SET=long tools/train/gpu_runs.sh
#                                          launch` trains on data/refsim
#   tools/train/gpu_data.sh count          finished and accepted sequences so far
#   tools/train/gpu_data.sh window-pack    here: the prepared set a GPU window carries instead of
#                                          generating (gpu_window.sh PACK): the S tracks of the
#                                          mocap train clips' first windows (MOCAP, default
#                                          data/mocap_train) and of the procedural garments (PROC,
#                                          default data/garments) into SKIN (data/skin_window),
#                                          then PACK (data/window_pack): val/ (the mocap val
#                                          windows' first VAL_FRAMES = 122 frames, what the
#                                          validation scores) and train/part0, part1, ... (mocap and
#                                          procedural spread evenly, each part with val/ within CARRY_MB,
#                                          default 62); a window carries val/ and one part
#
# ONLY=drop|gripper|garment generates one scenario (simgen --only); DATA=DIR writes elsewhere than
# data/refsim; NO_SKIN=1 makes `prepare` skip the S tracks (priors other than the skinned one).
#
# Generation is resumable and deterministic per name (docs/DATASET.md), so the sequences a lent
# machine makes are the ones `weft simgen --out data/refsim --all --tier 1k` makes anywhere.
set -u
cd "$(dirname "$0")/../.." || exit 1
B=${BUNDLE:-.dev}
W=$PWD/$B/weft
D=${DATA:-data/refsim}
O=${ONLY:+--only $ONLY}
export LD_LIBRARY_PATH=$PWD/$B${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}

case "${1:-}" in
    bundle)
        B=${2:-$B}
        cmake -S . -B build-bundle -DCMAKE_BUILD_TYPE=Release -DWEFT_BUILD_SAMPLES=OFF -DWEFT_BUILD_TESTS=OFF \
            > /dev/null || exit 1
        cmake --build build-bundle -j"$(nproc)" --target weft_cli weft_shared > /dev/null || exit 1
        mkdir -p "$B" && cp build-bundle/bin/weft "$B/" || exit 1
        # the library itself, for training's ctypes binding (WEFT_LIB=$B/libweft.so.0: the CCD loss)
        cp -L build-bundle/lib/libweft.so.0 "$B/" || exit 1
        # every library the binary loads except the C library itself and the loader
        ldd build-bundle/bin/weft | awk '$3 ~ /^\// {print $3}' |
            grep -Ev '/(libc|libm|libpthread|libdl|librt|ld-linux[^/]*)\.so' | xargs -r cp -L -t "$B/"
        ls -la "$B" ;;
    gen)
        ldd "$W" | grep 'not found' && exit 3
        n=${JOBS:-$(nproc)}
        t=$((n > 4 ? n - 2 : n - 1))
        mkdir -p "$D"
        for i in $(seq 0 $((t - 1))); do
            # shellcheck disable=SC2086
            setsid nohup "$W" simgen --out "$D" --all --tier 1k $O --split train --shard "$i/$t" \
                > "/tmp/simgen_train_$i.log" 2>&1 < /dev/null &
        done
        for i in $(seq 0 $((n - t - 1))); do
            # shellcheck disable=SC2086
            setsid nohup "$W" simgen --out "$D" --all --tier 1k $O --split val --shard "$i/$((n - t))" \
                > "/tmp/simgen_val_$i.log" 2>&1 < /dev/null &
        done
        sleep 2
        echo "$(pgrep -fc '[w]eft simgen') simgen processes" ;;
    prepare)
        pkill -f "[w]eft simgen --out $D "   # this set's generators only
        sleep 2
        "$W" simgen --out "$D" --manifest-only 2>&1 | tail -1
        [ -n "${NO_SKIN:-}" ] && exit 0
        for s in train val; do
            "$W" eval --seq "$D" --split $s --method lbs --ccd off --write-pos data/skin 2>&1 | tail -1 &
        done
        wait
        echo "$(ls data/skin | wc -l) S tracks" ;;
    count)
        echo "finished $(find "$D" -name meta.json | wc -l)," \
             "accepted $(grep -l '"accepted":[[:space:]]*true' "$D"/*/meta.json 2>/dev/null | wc -l)" ;;
    window-pack)
        set -o pipefail
        M=${MOCAP:-data/mocap_train}; P=${PROC:-data/garments}; K=${PACK:-data/window_pack}
        S=${SKIN:-data/skin_window}; WL=${WEFT:-$PWD/build/bin/weft}
        for r in "$M" "$P"; do
            [ -f "$r/manifest.json" ] || { echo "window-pack: no $r/manifest.json; make $M with" \
                "'weft simgen --out $M --mocap train --shard I/2 --limit 32' (I = 0, 1) and $P with" \
                "'weft simgen --out $P --all --only garment --tier 1k' (docs/DATASET.md)" >&2; exit 1; }
        done
        [ -x "$WL" ] || { echo "window-pack: no $WL (build first, or WEFT=PATH)" >&2; exit 1; }
        rm -rf "$K" "$S" && mkdir -p "$S" || exit 1
        for r in "$M" "$P"; do
            for s in train val; do  # a split the manifest does not name has no sequences to skin
                grep -q "\"split\":[[:space:]]*\"$s\"" "$r/manifest.json" || continue
                "$WL" eval --seq "$r" --split $s --method lbs --ccd off --write-pos "$S" > /dev/null || exit 1
            done
        done
        PY=${PYTHON:-/usr/bin/python3}
        # validation scores the first EVAL_FRAMES (120) frames of each val window: only those travel
        "$PY" tools/train/pack.py --data "$M" --split val --skin "$S" --out "$K/val" --max-mb 1000 \
            --max-frames "${VAL_FRAMES:-122}" | tail -1 || exit 1
        vmb=$(du -sm "$K/val" | cut -f1)
        part_mb=$(( ${CARRY_MB:-62} - vmb ))
        [ "$part_mb" -ge 8 ] || { echo "window-pack: val/ is $vmb MB, leaving $part_mb MB a part" >&2; exit 1; }
        "$PY" tools/train/pack.py --data "$M" "$P" --split train --interleave --skin "$S" --out "$K/train" \
            --max-mb "$part_mb" | tail -1 || exit 1
        du -sm "$K"/val "$K"/train/part* ;;
    *) echo "usage: $0 bundle [DIR] | gen | prepare | count | window-pack" >&2; exit 2 ;;
esac
