#!/usr/bin/env bash
# usage: run_install_test.sh BUILD_DIR CONSUMER_SRC C_COMPILER [CLIP.bvh.gz]
# With CLIP, the motion consumer (weft/motion.h, weft_assets) is built both ways and run on it.
set -euo pipefail
build="$1"; consumer="$2"; cc="$3"; clip="${4:-}"
work="$build/install-test"
rm -rf "$work"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
# 1. CMake package
cmake -S "$consumer" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_C_COMPILER="$cc" >/dev/null
cmake --build "$work/cmake-build" >/dev/null
"$work/cmake-build/consumer_shared"
"$work/cmake-build/consumer_static"
n=3
if [ -n "$clip" ]; then
    "$work/cmake-build/consumer_motion" "$clip"
    n=$((n + 1))
fi
# 2. pkg-config
libdir="$(ls -d "$work"/prefix/lib*/pkgconfig | head -n 1)"
PKG_CONFIG_PATH="$libdir" "$cc" -std=c17 -Wall -Werror "$consumer/main.c" -o "$work/consumer_pc" \
    $(PKG_CONFIG_PATH="$libdir" pkg-config --cflags --libs weft)
LD_LIBRARY_PATH="$(dirname "$libdir")" "$work/consumer_pc"
n=$((n + 1))
if [ -n "$clip" ]; then
    PKG_CONFIG_PATH="$libdir" "$cc" -std=c17 -Wall -Werror "$consumer/motion.c" -o "$work/consumer_motion_pc" \
        $(PKG_CONFIG_PATH="$libdir" pkg-config --cflags --libs weft-assets) -lm
    LD_LIBRARY_PATH="$(dirname "$libdir")" "$work/consumer_motion_pc" "$clip"
    n=$((n + 1))
fi
echo "install test: $n consumers built and ran"
