#!/usr/bin/env bash
# Runs the whole peer comparison in one call: the project's CPU backend and Blender Cycles on the
# same scene and settings, a sample-count sweep of each timed, a two-seed high-sample reference
# of each, relMSE of every sweep image against both references, the time to relMSE 1e-2
# (log-log interpolation), and mean radiance per region of the two references. Also probes
# Embree's tutorial path tracer (see docs/BENCHMARKS.md, "Peers", for why it is not timed).
#
#   scripts/peers/run-peers.sh [OUT_DIR]        (default out/peers)
#
# Environment: SCENE (assets/scenes/cornell_box.json), WIDTH/HEIGHT (512), DEPTH (8, the
# project's --max-depth), THREADS (2), SWEEP ("1 2 4 8 16 32 64 128 256"), REF_SPP (512 per
# seed; the reference is the mean of seeds 1 and 2), PATHTRACER (build-peers/pathtracer, else
# build/pathtracer). Run it on a quiet machine: every figure is wall time.
set -euo pipefail
cd "$(dirname "$0")/../.."
HERE=scripts/peers

OUT=${1:-out/peers}
SCENE=${SCENE:-assets/scenes/cornell_box.json}
WIDTH=${WIDTH:-512}
HEIGHT=${HEIGHT:-512}
DEPTH=${DEPTH:-8}
THREADS=${THREADS:-2}
SWEEP=${SWEEP:-"1 2 4 8 16 32 64 128 256"}
REF_SPP=${REF_SPP:-512}
if [ -z "${PATHTRACER:-}" ]; then
  for p in build-peers/pathtracer build/pathtracer; do [ -x "$p" ] && PATHTRACER=$p && break; done
fi
# /usr/bin/pathtracer is Embree's tutorial (embree-tools), not this project's binary.
[ -x "${PATHTRACER:-}" ] || { echo "run-peers: build the project first (PATHTRACER=...)" >&2; exit 1; }

"$HERE/setup-peers.sh"
mkdir -p "$OUT"
BLENDER=(blender -b --factory-startup --python-exit-code 1)
log() { echo "run-peers: $*" >&2; }
t_start=$(date +%s)
{
  echo "date: $(date -u +%FT%TZ)"
  echo "host: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "pathtracer: $PATHTRACER ($(git rev-parse --short HEAD))"
  echo "blender: $(blender --version 2>/dev/null | head -1)"
  echo "settings: $SCENE ${WIDTH}x${HEIGHT}, max depth $DEPTH, $THREADS threads, sweep $SWEEP, reference 2 x $REF_SPP spp"
} > "$OUT/environment.txt"

render_ours() {  # spp seed file
  "$PATHTRACER" render "$SCENE" --spp "$1" --seed "$2" --width "$WIDTH" --height "$HEIGHT" \
    --max-depth "$DEPTH" --backend cpu --threads "$THREADS" -q --out "$3"
}

# ---- the project's CPU backend ---------------------------------------------------------------
log "ours: sweep $SWEEP"
for spp in $SWEEP; do render_ours "$spp" 0 "$OUT/ours_spp$spp.exr"; done
log "ours: reference 2 x $REF_SPP spp"
render_ours "$REF_SPP" 1 "$OUT/ours_ref_a.exr"
render_ours "$REF_SPP" 2 "$OUT/ours_ref_b.exr"

# ---- Blender Cycles ----------------------------------------------------------------------------
cycles() {  # seed spp-list prefix
  "${BLENDER[@]}" --python "$HERE/cycles_scene.py" -- "$SCENE" --width "$WIDTH" \
    --height "$HEIGHT" --max-depth "$DEPTH" --threads "$THREADS" --seed "$1" --spp "$2" \
    --out "$3" > "$3.log" 2>&1 || { tail -20 "$3.log" >&2; exit 1; }
}
"${BLENDER[@]}" --python "$HERE/cycles_scene.py" -- --emission-test --out "$OUT/cycles" \
  2>&1 | grep "emission test" > "$OUT/cycles_emission_test.txt"
log "cycles: sweep $SWEEP"
cycles 0 "$(echo $SWEEP | tr ' ' ,)" "$OUT/cycles"
log "cycles: reference 2 x $REF_SPP spp"
cycles 1 "$REF_SPP" "$OUT/cycles_ref_a"
cycles 2 "$REF_SPP" "$OUT/cycles_ref_b"
mv "$OUT/cycles_ref_a_spp$REF_SPP.exr" "$OUT/cycles_ref_a.exr"
mv "$OUT/cycles_ref_b_spp$REF_SPP.exr" "$OUT/cycles_ref_b.exr"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/environment.txt"

# ---- references, images, regions ---------------------------------------------------------------
img() { "${BLENDER[@]}" --python "$HERE/peers_images.py" -- "$@" > /dev/null 2>&1; }
for r in ours cycles; do
  img avg "$OUT/${r}_ref.exr" "$OUT/${r}_ref_a.exr" "$OUT/${r}_ref_b.exr"
  img png "$OUT/${r}_ref.exr" "$OUT/${r}_ref.png"
done
"${BLENDER[@]}" --python "$HERE/peers_images.py" -- regions --grid 4 --csv "$OUT/regions.csv" \
  "$OUT/cycles_ref_a.exr" "$OUT/cycles_ref_b.exr" "$OUT/ours_ref_a.exr" "$OUT/ours_ref_b.exr" \
  2>/dev/null | sed -n '/^region/,/^all/p' > "$OUT/regions.txt"
"$PATHTRACER" compare "$OUT/cycles_ref.exr" "$OUT/ours_ref.exr" > "$OUT/refs_compare.txt"

# ---- Embree's tutorial path tracer: a probe, not timed ----------------------------------------
EMB="$OUT/embree"
if args=$(python3 "$HERE/embree_scene.py" "$SCENE" "$EMB" 2>"$EMB.log"); then
  # shellcheck disable=SC2086
  (cd "$EMB" && /usr/bin/pathtracer -i scene.xml $args --size "$WIDTH" "$HEIGHT" --spp 16 \
     --max-path-length $((DEPTH - 1)) --threads "$THREADS" -o embree_spp16.pfm) >> "$EMB.log" 2>&1 || true
  if [ -f "$EMB/embree_spp16.pfm" ]; then
    img pfm2exr "$EMB/embree_spp16.pfm" "$EMB/embree_spp16.exr"
    "$PATHTRACER" compare "$EMB/embree_spp16.exr" "$OUT/ours_ref.exr" > "$OUT/embree_probe.txt" || true
  fi
fi

# ---- table -----------------------------------------------------------------------------------
python3 "$HERE/peers_table.py" "$OUT" "$PATHTRACER" "$SWEEP" > "$OUT/table.md"
cat "$OUT/table.md"
log "done in $(($(date +%s) - t_start)) s; results in $OUT"
