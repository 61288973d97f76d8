#!/usr/bin/env bash
# The README's first command: set up, build, and open the workbench window on the built-in
# Cornell box. Without a display it renders the scene headless to out/default.png instead.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --build build --target pathtracer
mkdir -p out
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  exec ./build/pathtracer gui "$@"
fi
./build/pathtracer render --out out/default.png "$@"
echo "run: no display, so the built-in Cornell box was rendered to out/default.png" \
  "(settings in out/default.png.json)"
