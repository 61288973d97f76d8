#!/usr/bin/env bash
# The benchmark suite of real scenes (docs/BENCHMARKS.md#the-suite-of-real-scenes): for each
# scene its size, BVH build, memory, time to the first image, ray rates, path segments per second
# at 1920x1080 depth 8, and time to relMSE 1e-2 against a reference rendered on the spot. Writes
# one JSON object per scene to $OUT/suite.jsonl; scripts/suite_table.py turns that into the table.
#   on the GPU machine: scripts/gpu-check.sh suite        (carry .devbuild/dist and .devbuild/bitterli)
#   anywhere (slow on a CPU): PATHTRACER=build/pathtracer SUITE="engine bunnies" scripts/bench-suite.sh
# Scenes whose files are missing are listed as skipped, with the reason.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/suite}
mkdir -p "$OUT"
PT=${PATHTRACER:-.devbuild/dist/pathtracer}
B=${BITTERLI:-../shared/scenes/bitterli}
[ -d "$B" ] || B=.devbuild/bitterli
ENGINE=${ENGINE:-/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb}
BUNNY=${BUNNY:-/usr/share/glmark2/models/bunny.obj}
SPP=${SUITE_SPP:-16}              # timed samples of `bench`
REF_SPP=${SUITE_REF_SPP:-4096}    # samples of each scene's reference for the error sweep
TIME_LIMIT=${SUITE_TIME_LIMIT:-8} # seconds of the error sweep
ERR_SIZE=${SUITE_ERROR_SIZE:-640x360}
CPU_SPP=${SUITE_CPU_SPP:-1}       # samples of the CPU row (0: none)
ERR_CONFIG=${SUITE_ERROR_CONFIG:-auto}  # `bench --error` configuration (cpu on a machine without GPU)
WORK=${SUITE_WORK:-/tmp/bench-suite}
mkdir -p "$WORK"

BUNNIES=$WORK/cornell_bunnies.json
sed "s|/usr/share/glmark2/models/bunny.obj|$BUNNY|" assets/scenes/cornell_bunnies.json > "$BUNNIES"

# name -> scene file; a missing file prints why and is skipped.
scene_file() {
  case "$1" in
    bunnies) [ -f "$BUNNY" ] && echo "$BUNNIES" ;;
    engine) [ -f "$ENGINE" ] && echo "$ENGINE" ;;
    terrain_10m) echo assets/scenes/terrain_10m.json ;;
    *) [ -f "$B/$1/scene-v4.pbrt" ] && echo "$B/$1/scene-v4.pbrt" ;;
  esac
}

: > "$OUT/suite.jsonl"
for name in ${SUITE:-cornell-box veach-mis coffee water-caustic classroom bunnies engine terrain_10m}; do
  f=$(scene_file "$name")
  if [ -z "$f" ]; then
    echo "---- $name: skipped (its file is absent: install the package or copy ../shared/scenes/bitterli)"
    printf '{"name": "%s", "skipped": "scene file absent"}\n' "$name" >> "$OUT/suite.jsonl"
    continue
  fi
  echo "---- $name ($f)"
  rm -rf "$WORK/$name" && mkdir -p "$WORK/$name"
  W=$WORK/$name
  "$PT" info "$f" --json > "$W/info.json" 2> "$W/info.err" || { cat "$W/info.err"; continue; }
  # Time from the command to the first image on disk: load, BVH, upload, one sample, write.
  t0=$(date +%s.%N)
  "$PT" render "$f" --spp 1 --width 1920 --height 1080 --out "$W/first.exr" > "$W/first.log" 2>&1
  t1=$(date +%s.%N)
  "$PT" bench "$f" --width 1920 --height 1080 --max-depth 8 --spp "$SPP" --cpu-spp "$CPU_SPP" \
    --json "$W/bench.json" > "$W/bench.log" 2>&1 || tail -5 "$W/bench.log"
  grep -E "^(megakernel|wavefront|auto|cpu) |intersect: camera" "$W/bench.log" | head -20
  # Error against time of the default design (auto) at a smaller size, against a reference
  # rendered first with an independent seed.
  "$PT" bench --error "$f" --configs "$ERR_CONFIG" --set render.width=${ERR_SIZE%x*} \
    --set render.height=${ERR_SIZE#*x} --set render.max_depth=8 --reference-spp "$REF_SPP" \
    --max-spp 65536 --time-limit "$TIME_LIMIT" --flip off --out "$W/error" > "$W/error.log" 2>&1 \
    || tail -5 "$W/error.log"
  grep -E "time to|relMSE 1e-2" "$W/error.log" | head -4
  python3 - "$name" "$f" "$W" "$(awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }')" >> "$OUT/suite.jsonl" <<'PY'
import json, os, sys
name, path, w, first = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
def load(p):
    try:
        with open(p) as f: return json.load(f)
    except Exception as e: return {"error": str(e)}
info, bench, err = load(f"{w}/info.json"), load(f"{w}/bench.json"), load(f"{w}/error/bench.json")
rec = {"name": name, "file": path, "first_image_s": first,
       "triangles": info.get("triangles"), "spheres": info.get("spheres"),
       "bvh": info.get("bvh"), "features": info.get("features"),
       "device": bench.get("device"), "scene_device_bytes": bench.get("scene_device_bytes"),
       "path_state_bytes_per_pixel": bench.get("path_state_bytes_per_pixel"),
       "bvh_bytes_per_triangle": bench.get("bvh_bytes_per_triangle"),
       "rows": [{k: r.get(k) for k in ("config", "kernel", "ms_per_spp", "M_segments_per_s",
                                       "M_rays_per_s", "ray_rates_M_per_s", "note")}
                for r in bench.get("results", [])],
       "error": err}
print(json.dumps(rec))
PY
done
echo "suite: $OUT/suite.jsonl (scripts/suite_table.py makes the table)"
