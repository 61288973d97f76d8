#!/usr/bin/env bash
# Runs on the lent GPU machine, in one call: checks the carried binaries need nothing missing,
# runs the GPU tests, renders every asset on the GPU and benchmarks the Cornell box (open and
# closed), the glass/mirror box and the bunny box. Figures go to $OUT (at most 8 files).
#   here:   scripts/build-device.sh      (builds .devbuild/dist)
#   device: run(command="scripts/gpu-check.sh", carry=[".devbuild/dist"])
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/gpu-check}
mkdir -p "$OUT"
DIST=.devbuild/dist
export TRACER_SOURCE_DIR=$PWD
LOG=$OUT/gpu-check.log
exec > >(tee "$LOG") 2>&1

echo "== device"
nvidia-smi --query-gpu=name,memory.total,clocks.sm,clocks.max.sm,driver_version --format=csv
date -u
echo "== shared libraries (nothing may be 'not found')"
ldd $DIST/pathtracer | grep -E "not found|tiny|stb|cuda" || true
if ldd $DIST/pathtracer | grep -q "not found"; then echo "MISSING LIBRARIES"; fi

# The bunny scene names Debian's glmark2 bunny; the device has no Debian packages, so point it at
# the copy carried in $DIST.
BUNNIES=/tmp/cornell_bunnies.json
sed "s|/usr/share/glmark2/models/bunny.obj|$PWD/$DIST/bunny.obj|" \
  assets/scenes/cornell_bunnies.json > $BUNNIES
scene() { if [ "$1" = cornell_bunnies ]; then echo $BUNNIES; else echo assets/scenes/$1.json; fi; }

MODE=${1:-all}
if [ "$MODE" = all ] || [ "$MODE" = tests ]; then
  echo "== GPU tests"
  $DIST/cuda_test 2>&1 | grep -vE "^\[ RUN|^\[       OK" || echo "cuda_test FAILED"
fi

if [ "$MODE" = all ] || [ "$MODE" = render ]; then
  echo "== renders (CUDA backend)"
  for s in cornell_box cornell_spheres depth_of_field; do
    $DIST/pathtracer render assets/scenes/$s.json --backend cuda --spp 1024 --out "$OUT/$s.png"
  done
  $DIST/pathtracer render $BUNNIES --backend cuda --spp 256 \
    --out "$OUT/cornell_bunnies.png"
fi

if [ "$MODE" = all ] || [ "$MODE" = bench ]; then
  echo "== benchmarks (1920x1080, max depth 8)"
  : > "$OUT/bench.jsonl"
  for s in cornell_box cornell_closed cornell_spheres cornell_bunnies; do
    echo "---- $s"
    $DIST/pathtracer bench "$(scene $s)" --width 1920 --height 1080 --max-depth 8 \
      --spp 16 --cpu-spp 1 --json "$OUT/b.json"
    tr -d '\n' < "$OUT/b.json" >> "$OUT/bench.jsonl"
    echo >> "$OUT/bench.jsonl"
  done
  rm -f "$OUT/b.json"
fi
echo "== done"
