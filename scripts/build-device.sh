#!/usr/bin/env bash
# Builds the headless binaries for the lent GPU machine (sm_90 + PTX) into .devbuild/ and gathers
# them with the Debian shared libraries they need into .devbuild/dist (carried to the device).
# The CUDA runtime is linked statically; the device only needs its driver.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh >/dev/null
# VARIANT=name EXTRA_CUDA_FLAGS=... EXTRA_CXX_FLAGS=... builds an experimental variant into
# .devbuild/dist-name: kernel macros (e.g. -DTRACER_MEGA_MIN_BLOCKS=3) go in EXTRA_CUDA_FLAGS, the
# GPU build variants of tracer/integrator/gpu_options.h (e.g. -DTRACER_VARIANT_UNFUSED, read by
# host code) in EXTRA_CXX_FLAGS. The flags are set when VARIANT's build folder is configured.
# DEVICE_BUILD=build reuses the host's build folder (configured Release for sm_90 as here).
BUILD=${DEVICE_BUILD:-.devbuild/build${VARIANT:+-$VARIANT}}
DIST=.devbuild/dist${VARIANT:+-$VARIANT}
if [ ! -f "$BUILD/build.ninja" ]; then
  cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 \
    -DCMAKE_CUDA_FLAGS="${EXTRA_CUDA_FLAGS:-}" -DCMAKE_CXX_FLAGS="${EXTRA_CXX_FLAGS:-}" \
    -DCMAKE_CUDA_COMPILER=/usr/local/cuda/bin/nvcc \
    -DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache >/dev/null
fi
cmake --build "$BUILD" --target pathtracer cuda_test
rm -rf "$DIST"
mkdir -p "$DIST/lib"
cp "$BUILD/pathtracer" "$BUILD/tests/cuda_test" "$DIST/"
# Ship every library that is not part of the C/C++ runtime every Linux has.
for bin in "$DIST/pathtracer" "$DIST/cuda_test"; do
  ldd "$bin" | awk '/=> \//{print $3}' | while read -r lib; do
    case "$(basename "$lib")" in
      libc.so*|libm.so*|libstdc++.so*|libgcc_s.so*|libpthread.so*|libdl.so*|librt.so*|ld-linux*) ;;
      *) [ -e "$DIST/lib/$(basename "$lib")" ] || cp -L "$lib" "$DIST/lib/" ;;
    esac
  done
done
# ImGui's OpenGL loader dlopens libGL.so.1 (glvnd), which needs libGLX.so.0.
for lib in libGL.so.1 libGLX.so.0; do cp -L "/usr/lib/x86_64-linux-gnu/$lib" "$DIST/lib/"; done
cp /usr/share/glmark2/models/bunny.obj "$DIST/"  # for assets/scenes/cornell_bunnies.json
# Blender's world maps (Debian blender-data) for the environment tests and env_sunrise.json;
# gpu-check.sh puts them where the Debian package would.
W=/usr/share/blender/datafiles/studiolights/world
if [ -d "$W" ]; then mkdir -p "$DIST/world" && cp "$W"/*.exr "$DIST/world/"; fi
du -sh "$DIST"
ls "$DIST/lib"
# The suite's carry (gpu-check.sh suite; the 64 MiB limit leaves room for .devbuild/bitterli
# beside it, not beside all of $DIST): pathtracer, its libraries, the bunny and Debian's engine.
if [ -n "${SUITE_DIST:-}" ]; then
  S=.devbuild/dist-suite
  rm -rf "$S" && mkdir -p "$S"
  cp -r "$DIST/pathtracer" "$DIST/lib" "$DIST/bunny.obj" "$S/"
  cp /usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb "$S/"
  du -sh "$S"
fi
# Open Image Denoise for the device (OIDN_DIST=1): the library, its core (with the weights) and
# its CUDA device, 54 MB: carried on its own (.devbuild/oidn) because with the binaries it would
# pass the 64 MiB carry limit; gpu-check.sh points TRACER_OIDN_LIBRARY at it.
if [ -n "${OIDN_DIST:-}" ]; then
  L=.deps/oidn/pyoidn/oidn/lib
  rm -rf .devbuild/oidn && mkdir -p .devbuild/oidn/lib
  cp -L "$L/libOpenImageDenoise.so.2" "$L/libOpenImageDenoise_core.so.2.5.1" \
    "$L/libOpenImageDenoise_device_cuda.so.2.5.1" .devbuild/oidn/lib/
  du -sh .devbuild/oidn
fi
