#!/usr/bin/env bash
# Runs the libFuzzer targets of the asan build, one after another, each on a copy of its seeds.
#
#   bash tools/fuzz.sh [SECONDS] [TARGET...]      (default: 3600 s, every build-asan/tests/fuzz_*)
#
# Builds nothing: configure and build first with `cmake --preset asan && cmake --build build-asan`.
# Per target it uses tests/fuzz/corpus/<target>/ (copied, so the seeds stay as committed),
# tests/fuzz/<target>.dict when present, and a -max_len that fits its seeds. Prints one line
# per target: executions, executions per second, coverage (cov: edges, ft: features) and corpus
# size from libFuzzer's last status line, and the crash files. Exits 1 when any target crashed
# (a crash, leak, timeout or out-of-memory artifact, or a fuzzer that failed to run).
#
# Environment:
#   WEFT_FUZZ_BIN   folder of the fuzz_* binaries (default build-asan/tests)
#   WEFT_FUZZ_OUT   where each run keeps log, grown corpus and artifacts, one folder per target
#                   (default build-asan/fuzz-runs/<date-time>); relative paths start at the
#                   repository root
#   WEFT_FUZZ_ARGS  extra libFuzzer options for every target, e.g. '-fork=1 -ignore_crashes=1'
#                   to keep going after a crash (artifacts are still kept and reported)
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root" || exit 2

seconds="${1:-3600}"
[ $# -gt 0 ] && shift
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ]; then
    echo "usage: bash tools/fuzz.sh [SECONDS] [TARGET...]" >&2
    exit 2
fi
bin="${WEFT_FUZZ_BIN:-build-asan/tests}"
out="${WEFT_FUZZ_OUT:-build-asan/fuzz-runs/$(date +%Y%m%d-%H%M%S)}"

targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    for exe in "$bin"/fuzz_*; do
        [ -f "$exe" ] && [ -x "$exe" ] && targets+=("$(basename "$exe" | sed 's/^fuzz_//')")
    done
fi
if [ ${#targets[@]} -eq 0 ]; then
    echo "no fuzz targets in $bin: build with 'cmake --preset asan && cmake --build build-asan'" >&2
    exit 2
fi

# Largest input the fuzzer may build: a few times the largest seed.
max_len() {
    case "$1" in
        bvh) echo 16384 ;;
        gltf) echo 16384 ;;
        npz) echo 16384 ;;
        pc2) echo 1024 ;;
        obj) echo 4096 ;;
        *) echo 4096 ;;
    esac
}

# Per-target options. The assimp targets skip libFuzzer's per-input leak check: assimp leaks
# half-built scenes on most malformed files (suppressed, tests/assets/lsan_assimp.supp), and the
# leak scan that each of those inputs triggers costs more than the input (bvh: about 380 instead
# of 4,300 inputs per second). The ctest replays (fuzz.bvh_replay, fuzz.gltf_replay) keep
# LeakSanitizer on over the seeds and their mutations. WEFT_FUZZ_ARGS=-detect_leaks=1 restores it.
# What assimp leaks also stays in the process: an hour of bvh (1.39 million inputs) grew to
# libFuzzer's default 2 GB RSS limit and stopped there with no input at fault, so the assimp
# targets get 8 GB.
target_options() {
    case "$1" in
        bvh | gltf) echo "-detect_leaks=0 -rss_limit_mb=8192" ;;
    esac
}

status=0
for name in "${targets[@]}"; do
    exe="$bin/fuzz_$name"
    if [ ! -x "$exe" ]; then
        echo "$name: no $exe" >&2
        status=1
        continue
    fi
    work="$out/$name"
    mkdir -p "$work/corpus" "$work/artifacts"
    seeds="tests/fuzz/corpus/$name"
    [ -d "$seeds" ] && cp -r "$seeds"/. "$work/corpus"/
    args=(-max_total_time="$seconds" -print_final_stats=1 -timeout=60 -max_len="$(max_len "$name")"
          -artifact_prefix="$work/artifacts/")
    [ -f "tests/fuzz/$name.dict" ] && args+=(-dict="tests/fuzz/$name.dict")
    # assimp leaks parts of half-built scenes when it throws (tests/assets/lsan_assimp.supp)
    lsan="${LSAN_OPTIONS:-}"
    case "$name" in
        bvh | gltf) lsan="suppressions=$root/tests/assets/lsan_assimp.supp${lsan:+:$lsan}" ;;
    esac
    # shellcheck disable=SC2086,SC2046
    LSAN_OPTIONS="$lsan" "$exe" "${args[@]}" $(target_options "$name") ${WEFT_FUZZ_ARGS:-} "$work/corpus" \
        >"$work/log" 2>&1
    rc=$?

    # final stats when libFuzzer printed them, else (fork mode) the last status line
    stat() { sed -n "s/^stat::$1: *//p" "$work/log" | tail -n 1; }
    last="$(grep -E '^#[0-9]+' "$work/log" | grep -E 'cov: [0-9]+' | tail -n 1)"
    execs="$(stat number_of_executed_units)"
    [ -n "$execs" ] || execs="$(sed -n 's/^#\([0-9]*\).*/\1/p' <<<"$last")"
    rate="$(stat average_exec_per_sec)"
    [ -n "$rate" ] || rate="$(sed -n 's/.* exec\/s:* \([0-9]*\).*/\1/p' <<<"$last")"
    cov="$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")"
    ft="$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")"
    corp="$(sed -n 's/.* corp: \([0-9]*\(\/[0-9]*[a-zA-Z]*\)*\).*/\1/p' <<<"$last")"
    crashes=""
    for artifact in "$work"/artifacts/crash-* "$work"/artifacts/leak-* "$work"/artifacts/timeout-* \
        "$work"/artifacts/oom-*; do
        [ -e "$artifact" ] && crashes+="$(basename "$artifact") "
    done
    if [ -n "$crashes" ] || [ $rc -ne 0 ]; then
        status=1
        [ -z "$crashes" ] && crashes="(exit status $rc, see $work/log)"
        crashes="$crashes in $work/artifacts"
    fi
    printf '%-12s %4ss  execs %-10s execs/s %-7s cov %-6s ft %-7s corpus %-12s crashes %s\n' "$name" "$seconds" \
        "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}" "${crashes:-0}"
done
exit $status
