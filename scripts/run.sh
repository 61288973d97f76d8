#!/usr/bin/env bash
# The README's first command: set up, build, and run the workbench on the built-in Cornell box.
# Without a display (or until the window exists) it renders the scene headless to out/default.png.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --build build --target pathtracer
mkdir -p out
./build/pathtracer render --out out/default.png "$@"
echo "run: the built-in Cornell box is in out/default.png (settings in out/default.png.json)"
