#!/usr/bin/env bash
# The whole test suite, from a fresh Debian 12 machine (as root, or with sudo):
#   1. installs missing Debian packages (tools/debian-packages.txt);
#   2. AArch64 cross build of the core + kernels, tests run under qemu-user (NEON twins);
#   3. clang build with ASan + UBSan, full suite, plus a bounded libFuzzer run per fuzz target
#      (tools/fuzz.sh: seeds from tests/fuzz/corpus/<target>, its dictionary and -max_len);
#   4. gcc Release build with warnings as errors, full suite (its ctest summary closes the run).
# Environment: WEFT_TEST_QUICK=1 skips steps 2-3; WEFT_FUZZ_SECONDS (default 300) caps each target,
# WEFT_FUZZ_RUNS (default 60000; gltf a tenth) and WEFT_FUZZ_SEED (default 1) fix its inputs.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash tools/install-deps.sh
jobs="$(nproc)"

step() { printf '\n=== %s ===\n' "$*"; }

if [ "${WEFT_TEST_QUICK:-0}" != "1" ]; then
    step "AArch64 (NEON) core and kernels under qemu-user"
    cmake --preset arm64 >/dev/null
    cmake --build build-arm64 -j"$jobs"
    ctest --test-dir build-arm64 -j"$jobs" --output-on-failure

    step "clang + ASan/UBSan: full suite"
    cmake --preset asan >/dev/null
    cmake --build build-asan -j"$jobs"
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
        ctest --test-dir build-asan -j"$jobs" --output-on-failure --timeout 1200

    step "libFuzzer: bounded runs"
    # every build-asan/tests/fuzz_* on a copy of tests/fuzz/corpus/<target> with its dictionary
    # and -max_len; fails on any crash (artifacts kept under build-asan/fuzz-runs/test-sh)
    # a fixed seed and input count (60,000 inputs a target, 6,000 for gltf; about 2 min for all): assimp (not
    # instrumented, docs/TESTING.md) still holds faults a random run of a few minutes can reach,
    # and the check should not depend on the machine's speed
    # gltf forks a child per input (assimp runs isolated, about 100 inputs a second under ASan),
    # so it gets a tenth of the inputs
    rm -rf build-asan/fuzz-runs/test-sh
    fast_targets=()
    for exe in build-asan/tests/fuzz_*; do
        name="$(basename "$exe" | sed 's/^fuzz_//')"
        if [ "$name" != gltf ]; then
            fast_targets+=("$name")
        fi
    done
    WEFT_FUZZ_OUT=build-asan/fuzz-runs/test-sh \
        WEFT_FUZZ_ARGS="-seed=${WEFT_FUZZ_SEED:-1} -runs=${WEFT_FUZZ_RUNS:-60000} ${WEFT_FUZZ_ARGS:-}" \
        bash tools/fuzz.sh "${WEFT_FUZZ_SECONDS:-300}" "${fast_targets[@]}"
    WEFT_FUZZ_OUT=build-asan/fuzz-runs/test-sh \
        WEFT_FUZZ_ARGS="-seed=${WEFT_FUZZ_SEED:-1} -runs=$(( ${WEFT_FUZZ_RUNS:-60000} / 10 )) ${WEFT_FUZZ_ARGS:-}" \
        bash tools/fuzz.sh "${WEFT_FUZZ_SECONDS:-300}" gltf
fi

step "gcc Release: full suite"
cmake --preset release >/dev/null
cmake --build build -j"$jobs"
ctest --test-dir build -j"$jobs" --output-on-failure
