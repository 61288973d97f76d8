#!/usr/bin/env bash
# Runs on the lent GPU machine: per-instruction execution counts of the specialised megakernel
# (Nsight Compute source counters) on a 1080p Cornell box sample, joined with the inline call
# chains of a line-info disassembly, then split by stage (scripts/sass_split.py).
# Build with line info first: VARIANT=x EXTRA_CUDA_FLAGS=-lineinfo scripts/build-device.sh
#   device: run(command="bash .devbuild/dist-x/gpu-source-profile.sh", carry=[".devbuild/dist-x"])
set -uo pipefail
D=${DIST:-$(dirname "$0")}
BIN=${BIN:-pathtracer}
OUT=${OUT:-out/source-profile}
SCENE=${SCENE:-assets/scenes/cornell_box.json}
mkdir -p "$OUT"
export TRACER_SOURCE_DIR=$PWD
NCU=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu /usr/local/cuda/bin/ncu 2>/dev/null | head -1)
nvidia-smi --query-gpu=name,clocks.sm,clocks.max.sm,driver_version --format=csv,noheader
date -u
# Line-info disassembly of every kernel, with the chain of inlined call sites per instruction.
# (cuobjdump and nvdisasm are also on PyPI as nvidia-cuda-cuobjdump / nvidia-cuda-nvdisasm, to
# disassemble a carried binary on the build machine instead.)
CUDA_BIN=$(dirname "$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)")
W=/tmp/sass
rm -rf "$W" && mkdir -p "$W" && (cd "$W" && "$CUDA_BIN/cuobjdump" -xelf all "$OLDPWD/$D/$BIN" > /dev/null)
for f in "$W"/*.cubin; do
  "$CUDA_BIN/nvdisasm" -c -gi "$f" 2>/dev/null | grep -q megakernel &&
    "$CUDA_BIN/nvdisasm" -c -gi "$f" > "$OUT/disasm.txt"
done
timeout 240 "$NCU" --clock-control none -k regex:megakernel --launch-skip 3 --launch-count 1 \
  --section SourceCounters --section InstructionStats --section WarpStateStats \
  --section LaunchStats --section Occupancy --import-source yes \
  --metrics smsp__inst_executed.sum,smsp__thread_inst_executed.sum,gpu__time_duration.sum \
  -o /tmp/mk -f "$D/$BIN" render "$SCENE" --backend cuda --kernel megakernel --spp 6 \
  --width 1920 --height 1080 -q --out /tmp/p.png 2>&1 | tail -3
"$NCU" -i /tmp/mk.ncu-rep --page details 2>&1 | grep -E "inst_executed|Duration|Registers|Occupancy|Local" | head -20
"$NCU" -i /tmp/mk.ncu-rep --page source --csv --print-source sass > "$OUT/sass.csv" 2> "$OUT/sass.err"
head -c 600 "$OUT/sass.csv"; echo; head -5 "$OUT/sass.err"
ls -la "$OUT"
python3 "$D/sass_split.py" "$OUT/disasm.txt" "$OUT/sass.csv" | tee "$OUT/split.txt"
