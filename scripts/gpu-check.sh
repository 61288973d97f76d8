#!/usr/bin/env bash
# Runs on the lent GPU machine, in one call: checks the carried binaries need nothing missing,
# runs the GPU tests, renders every asset on the GPU and benchmarks the Cornell box (open and
# closed), the glass/mirror box and the bunny box. Figures go to $OUT (at most 8 files).
#   here:   scripts/build-device.sh      (builds .devbuild/dist)
#   device: run(command="scripts/gpu-check.sh", carry=[".devbuild/dist"])
# When the tree and the dist pass the carry's 64 MiB: carry a gzip of it instead,
#   here:   tar -cf - -C .devbuild dist | gzip -6 > .devbuild/dist.tar.gz
#   device: run(command="tar xzf .devbuild/dist.tar.gz -C .devbuild && scripts/gpu-check.sh",
#               carry=[".devbuild/dist.tar.gz"])
# A build variant (tracer/integrator/gpu_options.h) runs the same way from its own folder, e.g.
#   here:   VARIANT=unfused EXTRA_CXX_FLAGS=-DTRACER_VARIANT_UNFUSED scripts/build-device.sh
#   device: run(command="DIST=.devbuild/dist-unfused scripts/gpu-check.sh bench", ...)
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/gpu-check}
mkdir -p "$OUT"
DIST=${DIST:-.devbuild/dist}
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
# Blender's world maps likewise, where the tests and env_sunrise.json look for them.
W=/usr/share/blender/datafiles/studiolights/world
if [ -d "$DIST/world" ] && [ ! -d "$W" ]; then
  mkdir -p "$W" 2>/dev/null && cp "$DIST/world/"*.exr "$W/" || echo "cannot install the world maps in $W"
fi
BUNNIES=/tmp/cornell_bunnies.json
sed "s|/usr/share/glmark2/models/bunny.obj|$PWD/$DIST/bunny.obj|" \
  assets/scenes/cornell_bunnies.json > $BUNNIES
scene() {
  case "$1" in
    cornell_bunnies) echo $BUNNIES ;;
    textured) echo assets/scenes/textured.gltf ;;
    *) echo assets/scenes/$1.json ;;
  esac
}

MODE=${1:-all}  # all | tests | render | gui | bench | error | sanitize | bitterli | suite | instances | denoise | denoise-classroom | subsurface-exit | guiding | caustics | light | mpi (the last eleven not part of all)
if [ "$MODE" = all ] || [ "$MODE" = tests ]; then
  echo "== GPU tests"
  $DIST/cuda_test 2>&1 | grep -vE "^\[ RUN|^\[       OK" || echo "cuda_test FAILED"
fi

if [ "$MODE" = all ] || [ "$MODE" = render ]; then
  echo "== renders (CUDA backend); sidecars stay in /tmp (8 files come back at most)"
  for s in cornell_spheres subsurface rough_materials cornell_bunnies smallpt; do
    $DIST/pathtracer render "$(scene $s)" --backend cuda --spp 1024 --out "/tmp/$s.png"
    cp "/tmp/$s.png" "$OUT/"
  done
fi

if [ "$MODE" = all ] || [ "$MODE" = gui ]; then
  echo "== workbench: EGL off-screen, CUDA backend, CUDA/GL interop, 1280x720 image"
  # An edit at frame 300 measures the first image after a reset.
  printf '300: set materials.white.albedo=0.6,0.6,0.6\n' > /tmp/gui.script
  export __EGL_VENDOR_LIBRARY_FILENAMES=${__EGL_VENDOR_LIBRARY_FILENAMES:-/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json}
  $DIST/pathtracer gui --egl --backend cuda --window 1600 --window-height 900 --frames 600 \
    --set render.width=1280 --set render.height=720 --set render.spp=0 --script /tmp/gui.script \
    --stats-json "$OUT/gui_stats.jsonl" --screenshot "$OUT/gui_gpu.png" || echo "gui FAILED"
  python3 - "$OUT/gui_stats.jsonl" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
if not rows:
    sys.exit("no frames")
reset = next((i for i in range(1, len(rows)) if rows[i]["resets"] != rows[i - 1]["resets"]), None)
steady = rows[50:reset] if reset else rows[50:]
fm = statistics.median(r["frame_ms"] for r in steady)
span = steady[-1]["t"] - steady[0]["t"]
spps = (steady[-1]["spp"] - steady[0]["spp"]) / span if span > 0 else 0
print(f"frames {len(rows)}, interop {rows[-1]['interop']}, kernel {rows[-1]['kernel']}")
print(f"steady state: median frame {fm:.2f} ms ({1000/fm:.0f} UI fps), {spps:.0f} spp/s at 1280x720")
if reset:
    r = rows[reset]
    print(f"edit at frame {reset}: that frame took {r['frame_ms']:.2f} ms and showed {r['spp']} spp")
PY
fi

if [ "$MODE" = all ] || [ "$MODE" = bench ]; then
  echo "== benchmarks (1920x1080, max depth 8)"
  : > "$OUT/bench.jsonl"
  # SCENES and CPU_SPP narrow a run (e.g. SCENES="cornell_box smallpt" CPU_SPP=0).
  for s in ${SCENES:-cornell_box cornell_closed cornell_spheres cornell_bunnies rough_materials subsurface textured smallpt}; do
    echo "---- $s"
    $DIST/pathtracer bench "$(scene $s)" --width 1920 --height 1080 --max-depth 8 \
      --spp 16 --cpu-spp ${CPU_SPP:-1} --json "$OUT/b.json"
    tr -d '\n' < "$OUT/b.json" >> "$OUT/bench.jsonl"
    echo >> "$OUT/bench.jsonl"
  done
  rm -f "$OUT/b.json"
fi
if [ "$MODE" = all ] || [ "$MODE" = error ]; then
  # Error against time (issue 6): references of 32768 samples (GPU), then each configuration's
  # sweep. Everything of a run goes into one tarball ($OUT holds at most 8 files).
  echo "== error against time"
  E=/tmp/error-bench
  rm -rf $E
  echo "---- cornell_box 1920x1080 depth 8 (the GPU target: relMSE 1e-3 in under 1 s)"
  $DIST/pathtracer bench --error "$(scene cornell_box)" --width 1920 --height 1080 --max-depth 8 \
    --reference-spp 32768 --max-spp 4096 --time-limit 10 --out $E/cornell_1080p
  echo "---- cornell_box 512x512 depth 8 (the reference for the CPU and peer comparison)"
  $DIST/pathtracer bench --error "$(scene cornell_box)" --width 512 --height 512 --max-depth 8 \
    --reference-spp 32768 --max-spp 8192 --time-limit 5 \
    --configs megakernel,wavefront,megakernel+nee=off,megakernel+max_depth=4,cpu --out $E/cornell_512
  echo "---- cornell_spheres 960x540 depth 8 (glass and mirror: caustics, Schlick)"
  $DIST/pathtracer bench --error "$(scene cornell_spheres)" --width 960 --height 540 \
    --max-depth 8 --reference-spp 32768 --max-spp 4096 --time-limit 5 \
    --configs megakernel,wavefront,wavefront+sort=on,megakernel+mis=off,megakernel+schlick,megakernel+clamp=10 \
    --out $E/spheres_540p
  # The 512x512 reference comes back (the CPU and peer comparison use it); larger ones stay there.
  tar czf "$OUT/error-bench.tgz" -C /tmp --exclude='*1920x1080*.exr' --exclude='*960x540*.exr' \
    error-bench
fi
if [ "$MODE" = bitterli ]; then
  # The shared Bitterli scenes (docs/BENCHMARKS.md) against their Tungsten references: two seeds
  # per scene at the reference's resolution and depth, Tungsten's tent filter of radius 1, then
  # compare's 4x4 regions with the two renders' noise. Not part of `all`: the scenes travel
  # separately (copy ../shared/scenes/bitterli to .devbuild/bitterli here, carry it with $DIST).
  # The seed-1 render of each scene comes back as NAME.exr, the tables in the log and
  # bitterli-compare.tgz (NAME.compare.json).
  B=${BITTERLI:-.devbuild/bitterli}
  # name:max_depth:spp per seed:WxH[:EDIT+EDIT...]. max_depth = the original pbrt maxdepth - 1
  # (the segments the references hold; ../shared/scenes/bitterli/README.md); WxH = the
  # reference's size; EDITs (--set) restore what the pbrt-v4 conversion changed (BENCHMARKS.md).
  for row in ${BITTERLI_SCENES:-cornell-box:64:8192:1024x1024 veach-mis:2:8192:1280x720 water-caustic:8:8192:1024x1024 coffee:16:8192:800x1000 classroom:16:4096:1280x720}; do
    IFS=: read -r name depth spp size edits <<< "$row"
    sets=()
    for e in ${edits//+/ }; do sets+=(--set "$e"); done
    [ -f "$B/$name/scene-v4.pbrt" ] || { echo "---- $name: absent from $B"; continue; }
    echo "---- $name (max depth $depth, 2 x $spp spp${edits:+; $edits})"
    for seed in 1 2; do
      $DIST/pathtracer render "$B/$name/scene-v4.pbrt" --backend cuda --spp "$spp" \
        --max-depth "$depth" --width "${size%x*}" --height "${size#*x}" --seed $seed \
        --filter tent --filter-radius 1 "${sets[@]}" \
        --out /tmp/$name.$seed.exr 2>&1 | grep -vE "^$" | tail -4
    done
    $DIST/pathtracer compare --grid 4x4 --test2 /tmp/$name.2.exr /tmp/$name.1.exr \
      "$B/$name/TungstenRender.exr"
    $DIST/pathtracer compare --json --grid 4x4 --test2 /tmp/$name.2.exr /tmp/$name.1.exr \
      "$B/$name/TungstenRender.exr" > "/tmp/$name.compare.json"
    cp /tmp/$name.1.exr "$OUT/$name.exr"
  done
  (cd /tmp && tar czf "$OUT/bitterli-compare.tgz" *.compare.json)  # $OUT holds at most 8 files
fi
if [ "$MODE" = suite ]; then
  # The benchmark suite of real scenes (scripts/bench-suite.sh; docs/BENCHMARKS.md). Carry
  # .devbuild/dist-suite (scripts/build-device.sh's pathtracer and lib, the bunny and Debian's
  # 2CylinderEngine.glb: `SUITE_DIST=1 scripts/build-device.sh` makes it) and .devbuild/bitterli.
  # scripts/suite_table.py OUT/suite.jsonl makes the table here.
  PATHTRACER=$DIST/pathtracer BUNNY=$PWD/$DIST/bunny.obj ENGINE=$PWD/$DIST/2CylinderEngine.glb \
    BITTERLI=${BITTERLI:-.devbuild/bitterli} OUT=$OUT scripts/bench-suite.sh
  python3 scripts/suite_table.py "$OUT/suite.jsonl"
fi
if [ "$MODE" = instances ]; then
  # Instances against flattening (docs/BENCHMARKS.md#instances-against-flattening): 16 tiles of a
  # 1M-triangle landscape placed by instances, the same 16 written out as 16M triangles (run
  # alternately, twice), then the 100M-triangle instanced landscape.
  for s in grid16_inst grid16_flat grid16_inst grid16_flat; do
    echo "==== bench $s"
    $DIST/pathtracer bench scripts/instances/$s.json --width 1920 --height 1080 --max-depth 8 \
      --spp 16 --cpu-spp 0 --json /tmp/$s.json > /tmp/b.txt 2>&1
    grep -E "^scene|^(megakernel|wavefront|auto) " /tmp/b.txt | head -4; grep -m2 "bounce rays" /tmp/b.txt
    python3 -c "import json; print('GPU bytes', json.load(open('/tmp/$s.json')).get('scene_device_bytes'))"
    TIMEFORMAT="first image %R s"; time $DIST/pathtracer render scripts/instances/$s.json --backend cuda --spp 1 --out /tmp/f.png > /dev/null 2>&1
  done
  echo "==== instanced_100m"
  TIMEFORMAT="first image %R s"; time $DIST/pathtracer render assets/scenes/instanced_100m.json --backend cuda --spp 1 --width 1920 --height 1080 --out /tmp/f.png > /dev/null 2>&1
  $DIST/pathtracer bench assets/scenes/instanced_100m.json --width 1920 --height 1080 --max-depth 8 \
    --spp 16 --cpu-spp 0 --json /tmp/i100.json > /tmp/b.txt 2>&1
  grep -E "^scene|^(megakernel|wavefront|auto) " /tmp/b.txt | head -4; grep -m2 "bounce rays" /tmp/b.txt
  python3 -c "import json; print('GPU bytes', json.load(open('/tmp/i100.json')).get('scene_device_bytes'))"
  $DIST/pathtracer render assets/scenes/instanced_100m.json --backend cuda --spp 256 --out "$OUT/instanced_100m.png" | tail -1
  rm -f "$OUT/instanced_100m.png.json"
fi
if [ "$MODE" = denoise ] || [ "$MODE" = denoise-classroom ]; then
  # AOVs and the denoiser (docs/BENCHMARKS.md#denoised-previews). Open Image Denoise travels on
  # its own: `OIDN_DIST=1 scripts/build-device.sh` makes .devbuild/oidn (54 MB), carried in one
  # call with $DIST; it stays on the machine while it is warm, so `denoise-classroom` (carry
  # $DIST and .devbuild/bitterli) follows at once. Everything comes back in $OUT/denoise*.tgz.
  export TRACER_OIDN_LIBRARY=${TRACER_OIDN_LIBRARY:-$PWD/.devbuild/oidn/lib}
  D=/tmp/dn && mkdir -p $D
  $DIST/pathtracer render --backend cuda --spp 1 --width 64 --height 64 --denoise on --out $D/probe.png 2>&1 | tail -2
  if [ "$MODE" = denoise ]; then
    echo "== GPU tests"
    $DIST/cuda_test 2>&1 | grep -vE "^\[ RUN|^\[       OK" || echo "cuda_test FAILED"
    echo "== the AOVs' cost: 1920x1080, 256 spp, without and with (wall time of the render)"
    for sc in cornell_box cornell_spheres cornell_bunnies; do
      for aov in "" "--aov albedo"; do
        $DIST/pathtracer render "$(scene $sc)" --backend cuda --spp 256 --width 1920 --height 1080 \
          $aov --quiet --out $D/cost.exr
        python3 -c "import json; j=json.load(open('$D/cost.exr.json')); print('$sc', '${aov:-no AOVs}', 'wall', round(j['wall_time_s'],3), 's', j['gpu_run']['kernel'])"
      done
    done
    echo "== where the denoiser fails: caustics, fine texture, subsurface (16 spp denoised, 4096 raw)"
    for sc in cornell_spheres textured subsurface; do
      $DIST/pathtracer render "$(scene $sc)" --backend cuda --spp 16 --denoise both --out $D/fail-$sc.16.png 2>&1 | grep -E "denoised|error"
      $DIST/pathtracer render "$(scene $sc)" --backend cuda --spp 4096 --quiet --out $D/fail-$sc.4096.png
    done
    (cd $D && tar czf "$OUT/denoise-fail.tgz" fail-*.png)
    SCENES="cornell_box cornell_spheres"
    CONFIGS=${CONFIGS:-megakernel,megakernel+denoise,wavefront+denoise}
  else
    B=${BITTERLI:-.devbuild/bitterli}
    SCENES="$B/classroom/scene-v4.pbrt"
    CONFIGS=${CONFIGS:-wavefront,wavefront+denoise}  # the classroom's faster kernel (suite)
  fi
  for sc in $SCENES; do
    path=$sc; [ -f "$path" ] || path=$(scene $sc)
    name=$(basename "$(dirname "$path")"); [ "$name" = scenes ] && name=$sc
    echo "==== bench --error $name, 1920x1080"
    $DIST/pathtracer bench "$path" --error --width 1920 --height 1080 --backend cuda \
      --reference-spp ${REF_SPP:-8192} --configs $CONFIGS \
      --time-limit ${TIME_LIMIT:-20} --out $D/$name 2>&1 | grep -vE "^\s*$" | tail -12
    # Pictures: raw and denoised at 4, 16 and 64 spp, and the reference (PNG).
    for spp in 4 16 64; do
      $DIST/pathtracer render "$path" --backend cuda --width 1920 --height 1080 --spp $spp \
        --denoise both --aov albedo,normal --out $D/$name.$spp.png 2>&1 | grep -E "denoised|error"
    done
    (cd $D && tar czf "$OUT/$MODE-$name.tgz" $name.4.png $name.4.denoised.png $name.64.denoised.png)
  done
  (cd $D && tar czf "$OUT/$MODE-data.tgz" --exclude='*.exr' --exclude='*.png' .)
fi
if [ "$MODE" = subsurface-exit ]; then
  # The subsurface scene's error against time with the smooth exit and the diffuse exit (issue 24),
  # each against a reference of its own model. Carry $DIST.
  D=/tmp/sss && rm -rf $D && mkdir -p $D
  for exit in smooth diffuse; do
    echo "==== bench --error subsurface, $exit exit"
    $DIST/pathtracer bench "$(scene subsurface)" --error --backend cuda \
      --set materials.wax.exit=$exit --set materials.jade.exit=$exit \
      --reference-spp ${REF_SPP:-16384} --configs megakernel,wavefront --time-limit ${TIME_LIMIT:-20} \
      --out $D/$exit 2>&1 | grep -vE "^\s*$" | tail -8
    $DIST/pathtracer render "$(scene subsurface)" --backend cuda --spp 64 \
      --set materials.wax.exit=$exit --set materials.jade.exit=$exit --out $D/sss-$exit-64.png | tail -1
    $DIST/pathtracer render "$(scene subsurface)" --backend cuda --spp 8192 -q \
      --set materials.wax.exit=$exit --set materials.jade.exit=$exit --out $D/sss-$exit-8192.png
  done
  (cd $D && tar czf "$OUT/subsurface-exit.tgz" --exclude='*.exr' .)
fi
if [ "$MODE" = guiding ] || [ "$MODE" = caustics ] || [ "$MODE" = light ]; then
  # Path guiding, manifold NEE and light tracing (issue 24): error against time without and with
  # the technique (caustics, light: also with guiding beside it) on the caustic scenes (the lamp behind glass, glass
  # and mirror spheres, rough materials, Bitterli's water caustic: copy it to
  # .devbuild/bitterli/water-caustic and carry it) and the diffuse Cornell box; then the
  # same-time pictures. Carry $DIST (and the Bitterli folder). BENCH_ARGS go to bench (e.g.
  # "--width 512 --height 512 --set render.light_tracing=on": the reference, and every
  # configuration without light_tracing=off, light-traced: the water caustic's plain reference
  # never converges).
  if [ "$MODE" = guiding ]; then
    FLAG=--guiding; DEFAULT_CONFIGS=wavefront,wavefront+guiding=on
  elif [ "$MODE" = caustics ]; then
    FLAG=--mnee; DEFAULT_CONFIGS=wavefront,wavefront+mnee=on,wavefront+guiding=on+mnee=on
  else
    FLAG=--light-tracing
    DEFAULT_CONFIGS=auto,auto+light_tracing=on,wavefront+guiding=on+light_tracing=on
  fi
  D=/tmp/$MODE && rm -rf $D && mkdir -p $D
  B=${BITTERLI:-.devbuild/bitterli}
  T=${TIME_LIMIT:-10}
  for sc in ${SCENES:-glass_lamp cornell_spheres rough_materials cornell_box $B/water-caustic/scene-v4.pbrt}; do
    path=$sc; [ -f "$path" ] || path=$(scene $sc)
    [ -f "$path" ] || { echo "skipped $sc: $path not found"; continue; }
    name=$(basename "$(dirname "$path")"); [ "$name" = scenes ] && name=$sc
    echo "==== bench --error $name"
    $DIST/pathtracer bench "$path" --error --backend cuda --reference-spp ${REF_SPP:-16384} \
      --configs ${CONFIGS:-$DEFAULT_CONFIGS} --time-limit $T --out $D/$name ${BENCH_ARGS:-} 2>&1 |
      grep -vE "^\s*$" | tail -10
    for g in off on; do
      $DIST/pathtracer render "$path" --backend cuda $FLAG $g --time ${PIC_TIME:-2} \
        --out $D/$name-${FLAG#--}-$g.png 2>&1 | tail -1
    done
  done
  case $MODE in guiding) TESTS='*Guid*' ;; caustics) TESTS='*Manifold*' ;; *) TESTS='*LightTracing*' ;; esac
  $DIST/cuda_test --gtest_filter="$TESTS" 2>&1 | tail -15
  (cd $D && tar czf "$OUT/$MODE.tgz" --exclude='*.exr' .)
fi
if [ "$MODE" = mpi ]; then
  # Distributed rendering (issue 25) with the Open MPI carried in .devbuild/dist-mpi
  # (MPI_DIST=1 scripts/build-device.sh; run with DIST=.devbuild/dist-mpi, carry it alone):
  # 1. one GPU rank beside two CPU ranks against one process on the GPU (the same samples);
  # 2. scaling over 1, 2, 4, 8 GPUs (as many as the machine has) of a 3840x2160 render of the
  #    Cornell box and the bunny box at SPP (4096) samples: efficiency = T1 / (N TN), and the
  #    reduction's share. Figures: $OUT/mpi-scaling.txt.
  MPIRUN=$DIST/mpirun
  D=/tmp/mpi && rm -rf $D && mkdir -p $D
  GPUS=$(nvidia-smi -L | wc -l)
  echo "== mpi: $GPUS GPUs; $($MPIRUN --version 2>&1 | head -1)"
  echo "==== one GPU rank and two CPU ranks (256x256, 256 spp) against one process on the GPU"
  $MPIRUN -np 3 --oversubscribe $DIST/pathtracer render "$(scene cornell_box)" --width 256 \
    --height 256 --spp 256 --out $D/mixed.exr 2>&1 | tail -4
  $DIST/pathtracer render "$(scene cornell_box)" --backend cuda --width 256 --height 256 \
    --spp 256 -q --out $D/single.exr
  $DIST/pathtracer compare $D/mixed.exr $D/single.exr 2>&1 | head -6
  python3 - $D/mixed.exr.json <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
for r in d["mpi"]["ranks"]:
    print(f'  rank {r["rank"]}: {r["backend"]:4} {r["device"]:28} {r["samples"]:5} spp '
          f'{r["batches"]:3} batches {r["ms_per_spp"]:8.3f} ms/spp idle {r["idle_s"]:.3f} s')
PY
  for sc in ${SCENES:-cornell_box cornell_bunnies}; do
    for n in 1 2 4 8; do
      [ $n -le $GPUS ] || continue
      echo "==== $sc: $n GPUs, 3840x2160, ${SPP:-4096} spp"
      t0=$(date +%s.%N)
      $MPIRUN -np $n $DIST/pathtracer render "$(scene $sc)" --backend cuda --width 3840 \
        --height 2160 --spp ${SPP:-4096} --out $D/$sc-$n.exr 2>&1 | grep -E "^mpi|wrote|error"
      t1=$(date +%s.%N)
      echo "$sc $n $(python3 -c "print($t1 - $t0)")" >> $D/wall.txt
    done
  done
  python3 - $D <<'PY' | tee "$OUT/mpi-scaling.txt"
import json, os, sys
d = sys.argv[1]
wall = {}
for line in open(os.path.join(d, "wall.txt")):
    sc, n, t = line.split()
    wall[(sc, int(n))] = float(t)
print("scene            GPUs  render s  reduce s  reduce %  command s  speed-up  efficiency  max idle s")
base = {}
for (sc, n) in sorted(wall):
    j = json.load(open(os.path.join(d, f"{sc}-{n}.exr.json")))
    t = j["wall_time_s"] + j["mpi"]["reduce_s"]
    if n == 1:
        base[sc] = t
    s = base.get(sc, t) / t
    idle = max(r["idle_s"] for r in j["mpi"]["ranks"])
    print(f'{sc:16} {n:5} {j["wall_time_s"]:9.2f} {j["mpi"]["reduce_s"]:9.3f} '
          f'{100 * j["mpi"]["reduce_s"] / j["wall_time_s"]:8.2f} {wall[(sc, n)]:10.2f} '
          f'{s:9.2f} {s / n:11.3f} {idle:11.3f}')
PY
  for sc in ${SCENES:-cornell_box cornell_bunnies}; do
    [ -f $D/$sc-1.exr ] && [ -f $D/$sc-$GPUS.exr ] &&
      $DIST/pathtracer compare $D/$sc-$GPUS.exr $D/$sc-1.exr 2>&1 | grep -E "relmse|mean"
  done
  (cd $D && tar czf "$OUT/mpi.tgz" --exclude='*.exr' .)
fi
if [ "$MODE" = sanitize ]; then
  # compute-sanitizer on small renders through every wavefront path: shade-kernel compaction
  # (its shared memory and barriers), CUB, sorting, the megakernel tail, random walks, the BVH,
  # the fused trace stage (rays at their slots; with spheres, and with and without a tail). The
  # baselines that are build variants now (no fetch, rays at ids over the shade kernel's queues,
  # the unfused stages) are sanitized by running this against a variant's DIST.
  CS=$(command -v compute-sanitizer || echo /usr/local/cuda/bin/compute-sanitizer)
  echo "== compute-sanitizer ($CS)"
  for tool in racecheck synccheck memcheck; do
    for cfg in "cornell_box --compaction shade --sort on --tail 0.6" \
               "subsurface --compaction shade --tail 0.3" \
               "subsurface --compaction cub --sort on --tail 0.3" \
               "cornell_box --max-depth 2 --flat off --compaction cub" \
               "cornell_box --compaction shade --tail 0" \
               "cornell_spheres --compaction shade --tail 0.3"; do
      set -- $cfg
      sc=$1; shift
      echo "---- $tool: $sc $*"
      "$CS" --tool $tool --error-exitcode 3 $DIST/pathtracer render "$(scene $sc)" -q \
        --backend cuda --kernel wavefront --width 64 --height 48 --spp 3 "$@" \
        --out /tmp/sanitize.png > /tmp/sanitize.log 2>&1
      rc=$?
      tail -2 /tmp/sanitize.log
      [ $rc = 0 ] || echo "SANITIZER ERRORS ($tool, $sc $*): exit $rc"
    done
  done
fi
echo "== done"
