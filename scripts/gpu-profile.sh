#!/usr/bin/env bash
# Runs on the lent GPU machine: Nsight Compute on the megakernel and the wavefront kernels of a
# 1080p Cornell box frame (occupancy, issue utilisation, stall reasons, memory throughput).
# Usage there: scripts/gpu-profile.sh [SCENE]; reports go to $OUT.
# KERNELS (default: the megakernel and the three wavefront stages) and SKIPS (launches of each
# kernel skipped before the one profiled, default 3; "0 1" profiles bounces 0 and 1 of the first
# sample, which runs every bounce through the stages) choose what is measured.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/gpu-profile}
mkdir -p "$OUT"
DIST=${DIST:-.devbuild/dist}
SCENE=${1:-assets/scenes/cornell_box.json}
NCU=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
SECTIONS="--metrics smsp__inst_executed.sum,smsp__thread_inst_executed.sum,sm__cycles_elapsed.avg,smsp__average_warps_issue_stalled_long_scoreboard_per_issue_active.ratio,smsp__average_warps_issue_stalled_short_scoreboard_per_issue_active.ratio,smsp__average_warps_issue_stalled_wait_per_issue_active.ratio,smsp__average_warps_issue_stalled_not_selected_per_issue_active.ratio,smsp__average_warps_issue_stalled_selected_per_issue_active.ratio,smsp__average_warps_issue_stalled_math_pipe_throttle_per_issue_active.ratio,smsp__average_warps_issue_stalled_mio_throttle_per_issue_active.ratio,smsp__average_warps_issue_stalled_lg_throttle_per_issue_active.ratio,smsp__average_warps_issue_stalled_no_instruction_per_issue_active.ratio,smsp__average_warps_issue_stalled_barrier_per_issue_active.ratio,smsp__average_warps_issue_stalled_drain_per_issue_active.ratio,smsp__average_warps_issue_stalled_imc_miss_per_issue_active.ratio,smsp__average_warps_issue_stalled_dispatch_stall_per_issue_active.ratio,smsp__average_warps_issue_stalled_branch_resolving_per_issue_active.ratio --section ComputeWorkloadAnalysis --section InstructionStats --section SpeedOfLight --section Occupancy --section WarpStateStats --section SchedulerStats --section LaunchStats --section MemoryWorkloadAnalysis"
for k in ${KERNELS:-megakernel intersect_kernel shade_kernel shadow_kernel}; do
  mode=wavefront
  [ $k = megakernel ] && mode=megakernel
  for skip in ${SKIPS:-3}; do
    $NCU --clock-control none -k regex:$k --launch-skip $skip --launch-count 1 $SECTIONS \
      $DIST/pathtracer render "$SCENE" --backend cuda --kernel $mode --spp 6 --width 1920 \
      --height 1080 -q --out /tmp/p.png > "$OUT/ncu_${k}_$skip.txt" 2>&1
    grep -E "Duration|Achieved Occupancy|Theoretical Occupancy|Registers Per|Issue Slots Busy|No Eligible|Memory Throughput|DRAM Throughput|Compute \(SM\) Throughput|L1/TEX Hit|L2 Hit|Warp Cycles Per Issued|Active Warps Per Scheduler|Eligible Warps|Avg. Active Threads|inst_executed|cycles_elapsed|issue_stalled|Pipe|pipe" "$OUT/ncu_${k}_$skip.txt" | sed "s/^/[$k @$skip] /"
  done
done
