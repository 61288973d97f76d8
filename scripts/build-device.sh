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
# Copies into DIR every library FILE... needs that is not part of the C/C++ runtime every Linux
# has.
ship_libs() {
  local dir=$1
  shift
  for bin in "$@"; do
    ldd "$bin" | awk '/=> \//{print $3}' | while read -r lib; do
      case "$(basename "$lib")" in
        libc.so*|libm.so*|libstdc++.so*|libgcc_s.so*|libpthread.so*|libdl.so*|librt.so*|ld-linux*) ;;
        *) [ -e "$dir/$(basename "$lib")" ] || cp -L "$lib" "$dir/" ;;
      esac
    done
  done
}
ship_libs "$DIST/lib" "$DIST/pathtracer" "$DIST/cuda_test"
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
# Open MPI for the device (MPI_DIST=1; gpu-check.sh mpi): the device has no Debian packages, so
# mpirun (orterun), its components and help files and the libraries they need travel in
# .devbuild/dist-mpi beside pathtracer, its libraries and the bunny (no cuda_test: the 64 MiB
# carry limit). Components for network fabrics (UCX, OFI, verbs, PSM) stay behind: one host's
# ranks talk through shared memory (btl vader). dist-mpi/mpirun sets the variables that move
# Open MPI's install directories there.
if [ -n "${MPI_DIST:-}" ]; then
  M=.devbuild/dist-mpi
  rm -rf "$M" && mkdir -p "$M/ompi/bin" "$M/ompi/lib/openmpi3" "$M/ompi/lib/pmix" "$M/ompi/share" \
    "$M/ompi/etc"
  cp -r "$DIST/pathtracer" "$DIST/lib" "$DIST/bunny.obj" "$M/"
  cp -L /usr/bin/orterun "$M/ompi/bin/"
  P=/usr/lib/x86_64-linux-gnu/openmpi/lib/openmpi3
  for so in "$P"/*.so; do
    # Leave out components that need a fabric library (and Java, OpenSHMEM's, the monitoring).
    if ldd "$so" | grep -qE "libucp|libucs|libuct|libfabric|libibverbs|libpsm|librdmacm|libjvm"; then
      continue
    fi
    case "$(basename "$so")" in mca_sshmem*|mca_spml*|mca_atomic*|mca_scoll*|mca_memheap*) continue ;; esac
    cp "$so" "$M/ompi/lib/openmpi3/"
  done
  cp /usr/lib/x86_64-linux-gnu/pmix2/lib/pmix/*.so "$M/ompi/lib/pmix/"
  cp -r /usr/share/openmpi "$M/ompi/share/openmpi"
  cp -r /usr/lib/x86_64-linux-gnu/pmix2/share/pmix "$M/ompi/share/pmix"
  cp /etc/openmpi/openmpi-mca-params.conf "$M/ompi/etc/"
  ship_libs "$M/lib" "$M/ompi/bin/orterun" "$M/ompi/lib/openmpi3/"*.so "$M/ompi/lib/pmix/"*.so
  cat > "$M/mpirun" <<'WRAP'
#!/usr/bin/env bash
# Open MPI's mpirun from this folder (gathered by scripts/build-device.sh MPI_DIST=1).
H=$(cd "$(dirname "$0")" && pwd)
export OPAL_PREFIX=$H/ompi OPAL_EXEC_PREFIX=$H/ompi OPAL_BINDIR=$H/ompi/bin
export OPAL_LIBDIR=$H/lib OPAL_PKGLIBDIR=$H/ompi/lib/openmpi3 OPAL_DATADIR=$H/ompi/share
export OPAL_DATAROOTDIR=$H/ompi/share OPAL_PKGDATADIR=$H/ompi/share/openmpi
export OPAL_SYSCONFDIR=$H/ompi/etc
export PMIX_MCA_mca_base_component_path=$H/ompi/lib/pmix PMIX_INSTALL_PREFIX=$H/ompi
export LD_LIBRARY_PATH=$H/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
export OMPI_MCA_btl=self,vader OMPI_MCA_pml=ob1 OMPI_MCA_mca_base_component_show_load_errors=0
exec "$H/ompi/bin/orterun" --allow-run-as-root "$@"
WRAP
  chmod +x "$M/mpirun"
  du -sh "$M"
fi
