#!/usr/bin/env bash
# usage: run_install_test.sh BUILD_DIR CONSUMER_SRC C_COMPILER
set -euo pipefail
build="$1"; consumer="$2"; cc="$3"
work="$build/install-test"
rm -rf "$work"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
# 1. CMake package
cmake -S "$consumer" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_C_COMPILER="$cc" >/dev/null
cmake --build "$work/cmake-build" >/dev/null
"$work/cmake-build/consumer_shared"
"$work/cmake-build/consumer_static"
# 2. pkg-config
libdir="$(ls -d "$work"/prefix/lib*/pkgconfig | head -n 1)"
PKG_CONFIG_PATH="$libdir" "$cc" -std=c17 -Wall -Werror "$consumer/main.c" -o "$work/consumer_pc" \
    $(PKG_CONFIG_PATH="$libdir" pkg-config --cflags --libs weft)
LD_LIBRARY_PATH="$(dirname "$libdir")" "$work/consumer_pc"
echo "install test: 3 consumers built and ran"
