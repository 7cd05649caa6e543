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
    *) echo "usage: $0 bundle [DIR] | gen | prepare | count" >&2; exit 2 ;;
esac
