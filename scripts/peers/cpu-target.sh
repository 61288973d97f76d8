#!/usr/bin/env bash
# The issue 6 CPU target in one call: time to relMSE 1e-2 on the Cornell box at 512x512, depth 8,
# two threads, for this project's CPU backend (`pathtracer bench --error`) and for Blender Cycles
# (a sample sweep, each image compared with `pathtracer compare`), both against the SAME
# reference: a 32768-spp GPU render with its variance image (`scripts/gpu-check.sh error` makes
# it: error-bench/cornell_512/reference-cornell_box-512x512-d8.exr). Run on a quiet machine.
#
#   REF=path/to/reference.exr scripts/peers/cpu-target.sh [OUT_DIR]     (default out/cpu-target)
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:-out/cpu-target}
REF=${REF:?set REF to the 512x512 reference EXR}
[ -f "$REF" ] || { echo "cpu-target: $REF does not exist (scripts/gpu-check.sh error makes it)" >&2; exit 1; }
PATHTRACER=${PATHTRACER:-build/pathtracer}
SWEEP=${SWEEP:-1,2,4,8,16,32,64,128}
CONFIGS=${CONFIGS:-cpu}
scripts/peers/setup-peers.sh
mkdir -p "$OUT"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)" | tee "$OUT/environment.txt"

# Ours: the bench sweeps 1, 2, 4, ... spp and interpolates the time to 1e-2 itself.
"$PATHTRACER" bench --error assets/scenes/cornell_box.json --backend cpu --threads 2 \
  --width 512 --height 512 --max-depth 8 --configs "$CONFIGS" --reference "$REF" \
  --max-spp "${MAX_SPP:-256}" --time-limit 60 --flip off --out "$OUT/ours" | tee "$OUT/ours.txt"

# Cycles: one Blender process renders the sweep; render time excludes start-up and scene build.
blender -b --factory-startup --python-exit-code 1 --python scripts/peers/cycles_scene.py -- \
  assets/scenes/cornell_box.json --width 512 --height 512 --max-depth 8 --threads 2 --seed 0 \
  --spp "$SWEEP" --out "$OUT/cycles" > "$OUT/cycles.log" 2>&1
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/environment.txt"

python3 - "$OUT" "$PATHTRACER" "$REF" <<'PY'
import json, math, subprocess, sys
out, exe, ref = sys.argv[1:4]
runs = json.load(open(f"{out}/cycles.json"))["runs"]
pts = []
for r in runs:
    j = subprocess.run([exe, "compare", "--json", f"{out}/{r['file']}", ref], check=True,
                       capture_output=True, text=True).stdout
    j = json.loads(j[j.index("{"):])
    pts.append((r["spp"], r["render_s"], j["relmse"]))
# The reference's own noise, as the bench subtracts it.
floor = json.load(open(f"{out}/ours/bench.json"))["reference_floor_relmse"]
def t_to(target):
    prev = None
    for spp, t, e in pts:
        e = max(e - floor, 1e-30)
        if e <= target and prev:
            (t0, e0) = prev
            f = (math.log(e0) - math.log(target)) / (math.log(e0) - math.log(e))
            return math.exp(math.log(t0) + f * (math.log(t) - math.log(t0)))
        prev = (t, e)
    return float("nan")
ours = json.load(open(f"{out}/ours/bench.json"))["configs"]
print("\nrenderer | spp | render s | relMSE (reference noise subtracted)")
for spp, t, e in pts:
    print(f"cycles | {spp} | {t:.3f} | {e - floor:.4g}")
tc = t_to(1e-2)
print(f"\nCycles: time to relMSE 1e-2 = {tc:.2f} s")
for c in ours:
    to = c["time_to_1e-2_s"]
    if to < 0 or not tc == tc:
        print(f"{c['config']}: time to relMSE 1e-2 not measured (never reached, or Cycles' sweep "
              f"too short)")
        continue
    print(f"{c['config']}: time to relMSE 1e-2 = {to:.2f} s; ours / Cycles = {to / tc:.2f} "
          f"(target <= 0.5)")
PY
