#!/usr/bin/env bash
# Installs the Debian packages the project builds and tests with (only the missing ones; silent
# when everything is present), then configures the CMake build in build/ (or $BUILD_DIR).
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  cmake ninja-build g++ pkg-config ccache
  libglm-dev nlohmann-json3-dev libtinyobjloader-dev libtinygltf-dev libstb-dev libtinyexr-dev
  libcli11-dev libgtest-dev libbenchmark-dev
  libimgui-dev libglfw3-dev xvfb xauth
  glmark2-data assimp-testmodels python3-tinyobjloader
  libopenexr-dev blender-data
  libopenmpi-dev openmpi-bin
)

scripts/install-packages.sh setup "${PACKAGES[@]}"

# Intel Open Image Denoise, loaded at run time by tracer/image/denoise.cpp: Debian has no package
# (it needs ISPC), so it comes from PyPI's pyoidn wheel (the library with its CPU and CUDA
# devices and weights) into .deps/oidn. Optional: without it the denoiser says it is absent and
# its tests skip, so a failed download only prints a note.
OIDN_VERSION=2.5.1
if [ ! -e .deps/oidn/pyoidn/oidn/lib/libOpenImageDenoise.so.2 ] && [ -z "${TRACER_NO_OIDN:-}" ]; then
  echo "setup: installing Open Image Denoise $OIDN_VERSION (PyPI pyoidn) into .deps/oidn" >&2
  rm -rf .deps/oidn
  python3 -m pip install -q --disable-pip-version-check --root-user-action=ignore --no-deps --target .deps/oidn \
    "pyoidn==$OIDN_VERSION" >&2 ||
    echo "setup: note: pyoidn could not be installed; the denoiser will be absent" >&2
fi

BUILD_DIR=${BUILD_DIR:-build}
# TRACER_CUDA=ON/OFF chooses whether the CUDA backend is built (default: whenever nvcc is found);
# an existing build folder is reconfigured only when the choice changes.
cuda=()
[ -z "${TRACER_CUDA:-}" ] || cuda=(-DTRACER_ENABLE_CUDA="$TRACER_CUDA")
if [ ! -f "$BUILD_DIR/build.ninja" ]; then
  launcher=()
  if command -v ccache >/dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache)
  fi
  # nvcc lives outside PATH on some machines.
  if ! command -v nvcc >/dev/null && [ -x /usr/local/cuda/bin/nvcc ]; then
    launcher+=(-DCMAKE_CUDA_COMPILER=/usr/local/cuda/bin/nvcc)
  fi
  cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "${cuda[@]}" \
    >/dev/null
elif [ -n "${TRACER_CUDA:-}" ] &&
     ! grep -qx "TRACER_ENABLE_CUDA:BOOL=$TRACER_CUDA" "$BUILD_DIR/CMakeCache.txt"; then
  cmake -S . -B "$BUILD_DIR" "${cuda[@]}" >/dev/null
fi
