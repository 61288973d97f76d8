#!/usr/bin/env bash
# Runs on the lent GPU machine: A/B benchmark of two builds carried in one dist folder
# (pathtracer-base and pathtracer) on the four Cornell scenes, Nsight Compute instruction counts
# of the megakernel on the open box, then the GPU tests of the new build.
#   device: run(command="bash .devbuild/dist-perf/perf-ab.sh", carry=[".devbuild/dist-perf"])
set -uo pipefail
D=${DIST:-.devbuild/dist-perf}
OUT=${OUT:-out/perf-ab}
mkdir -p "$OUT"
export TRACER_SOURCE_DIR=$PWD
nvidia-smi --query-gpu=name,clocks.sm,clocks.max.sm,driver_version --format=csv,noheader
date -u
sed "s|/usr/share/glmark2/models/bunny.obj|$PWD/$D/bunny.obj|" assets/scenes/cornell_bunnies.json \
  > /tmp/cornell_bunnies.json
W=/usr/share/blender/datafiles/studiolights/world  # Blender's maps, as gpu-check.sh does
if [ -d "$D/world" ] && [ ! -d "$W" ]; then mkdir -p "$W" && cp "$D/world/"*.exr "$W/"; fi
bench() {  # binary scene-file
  echo "==== $1 $(basename "$2" .json)"
  "$D/$1" bench "$2" --width 1920 --height 1080 --max-depth 8 --spp 16 --cpu-spp 0 \
    > /tmp/b.txt 2>&1
  cat /tmp/b.txt >> "$OUT/bench.log"
  grep -E "^(megakernel|wavefront|auto)|bounce rays|bytes_per|bvh" /tmp/b.txt | cut -c1-100
}
# SCENES narrows or widens the run (names in assets/scenes, cornell_bunnies, textured); each scene
# runs the binaries alternately, so drift in the machine's clocks hits both.
scene_file() {
  case "$1" in
    cornell_bunnies) echo /tmp/cornell_bunnies.json ;;
    textured) echo assets/scenes/textured.gltf ;;
    engine) echo "$D/2CylinderEngine.glb" ;;  # Debian's assimp-testmodels, carried in $D
    *) echo "assets/scenes/$1.json" ;;
  esac
}
for name in ${SCENES:-cornell_box cornell_closed cornell_spheres cornell_bunnies cornell_box}; do
  s=$(scene_file "$name")
  for b in ${BINS:-pathtracer-base pathtracer}; do bench "$b" "$s"; done
done
NCU=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu /usr/local/cuda/bin/ncu 2>/dev/null | head -1)
if [ -n "$NCU" ] && [ -z "${NO_NCU:-}" ]; then
  for b in ${BINS:-pathtracer-base pathtracer}; do
    echo "==== ncu megakernel $b"
    timeout 120 "$NCU" --clock-control none -k regex:megakernel --launch-skip 3 --launch-count 1 \
      --metrics smsp__inst_executed.sum,smsp__thread_inst_executed.sum,gpu__time_duration.sum,sm__warps_active.avg.pct_of_peak_sustained_active,smsp__issue_active.avg.pct_of_peak_sustained_active \
      "$D/$b" render assets/scenes/cornell_box.json --backend cuda --kernel megakernel --spp 6 \
      --width 1920 --height 1080 -q --out /tmp/p.png 2>&1 | grep -E "inst_executed|duration|warps_active|issue_active"
  done
fi
echo "==== cuda_test"
"$D/cuda_test" 2>&1 | tee "$OUT/cuda_test.log" | grep -E "PASSED|FAILED|tests ran|Failure" | head -20
