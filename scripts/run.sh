#!/usr/bin/env bash
# The README's first command: set up, build, and open the workbench window on the built-in
# Cornell box. Without a display it renders the scene headless to out/default.png instead.
# The CUDA backend is compiled only where it can run (nvcc and an NVIDIA GPU): its kernels take
# most of a first build's time.
set -euo pipefail
cd "$(dirname "$0")/.."
nvcc=$(command -v nvcc || { [ -x /usr/local/cuda/bin/nvcc ] && echo /usr/local/cuda/bin/nvcc; } || true)
gpu=$(nvidia-smi -L 2>/dev/null | head -1 || true)
export BUILD_DIR=${BUILD_DIR:-build}
if grep -q "tracer_cuda" "$BUILD_DIR/build.ninja" 2>/dev/null; then
  why="the build folder already includes the CUDA backend"
elif [ -n "$nvcc" ] && [ -n "$gpu" ]; then
  why="with the CUDA backend ($nvcc; $gpu)"
  export TRACER_CUDA=ON
elif [ -n "$nvcc" ]; then
  why="CPU backend only: nvcc is here but no NVIDIA GPU is (scripts/test.sh still compiles CUDA)"
  export TRACER_CUDA=OFF
else
  why="CPU backend only: no nvcc"
fi
scripts/setup.sh >&2
first=""
[ -x "$BUILD_DIR/pathtracer" ] || first=" (a first build takes a few minutes on 2 cores)"
echo "run: building pathtracer, $why$first" >&2
cmake --build "$BUILD_DIR" --target pathtracer
mkdir -p out
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  exec "$BUILD_DIR/pathtracer" gui "$@"
fi
echo "run: no display, so the built-in Cornell box is rendered to out/default.png" >&2
"$BUILD_DIR/pathtracer" render --out out/default.png "$@"
echo "run: wrote out/default.png (settings in out/default.png.json)" >&2
