#!/usr/bin/env bash
# The main job, from a fresh Debian 12 machine (as root, or with sudo): installs missing Debian
# packages, builds weft (Release) and runs the render sample: the default avatar performs a
# motion wearing simulated cloth; frames and a contact sheet are written as PNG to out/.
# Extra arguments go to the sample (e.g. --motion run --garment dress --frames 120).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash tools/install-deps.sh
cmake --preset release >/dev/null
cmake --build build -j"$(nproc)"
if [ -x build/bin/avatar_render ]; then
    exec build/bin/avatar_render --out out/avatar_render "$@"
else
    exec build/bin/game_loop "$@"
fi
