#!/usr/bin/env bash
# Runs on the lent GPU machine: Nsight Compute on the megakernel and the wavefront kernels of a
# 1080p Cornell box frame (occupancy, issue utilisation, stall reasons, memory throughput).
# Usage there: scripts/gpu-profile.sh [SCENE]; reports go to $OUT.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/gpu-profile}
mkdir -p "$OUT"
DIST=${DIST:-.devbuild/dist}
SCENE=${1:-assets/scenes/cornell_box.json}
NCU=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
SECTIONS="--metrics smsp__inst_executed.sum,smsp__thread_inst_executed.sum,sm__cycles_elapsed.avg --section SpeedOfLight --section Occupancy --section WarpStateStats --section SchedulerStats --section LaunchStats --section MemoryWorkloadAnalysis"
for k in megakernel intersect_kernel shade_kernel shadow_kernel; do
  mode=wavefront
  [ $k = megakernel ] && mode=megakernel
  $NCU --clock-control none -k regex:$k --launch-skip 3 --launch-count 1 $SECTIONS \
    $DIST/pathtracer render "$SCENE" --backend cuda --kernel $mode --spp 6 --width 1920 \
    --height 1080 -q --out /tmp/p.png > "/tmp/ncu_$k.txt" 2>&1
  grep -E "Duration|Achieved Occupancy|Theoretical Occupancy|Registers Per|Issue Slots Busy|No Eligible|Memory Throughput|Compute \(SM\) Throughput|L1/TEX Hit|L2 Hit|Warp Cycles Per Issued|Active Warps Per Scheduler|Eligible Warps|Avg. Active Threads|inst_executed|cycles_elapsed" "/tmp/ncu_$k.txt" | sed "s/^/[$k] /"
done
