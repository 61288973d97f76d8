#!/usr/bin/env bash
# Fuzzes the JSON, OBJ, glTF/GLB, PLY and pbrt scene loaders with libFuzzer (clang from Debian) under ASan and
# UBSan for a bounded time each: scripts/fuzz.sh [SECONDS per format, default 60].
# The seed corpus is tests/fuzz/corpus/<format> plus the packaged OBJ/glTF/GLB test files; new
# inputs found go to build-fuzz/corpus/.
# Exits non-zero on a crash, a hang (> 10 s on one input), a leak or a sanitizer report.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
scripts/setup.sh >/dev/null
for p in clang libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || {
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
    $SUDO apt-get install -y -qq "$p" >/dev/null; }
done
OUT=build-fuzz
mkdir -p "$OUT"
clang++ -std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
  -Itracer -I/usr/include/stb \
  tests/fuzz/fuzz_loaders.cpp tracer/scene/*.cpp tracer/bvh/*.cpp tracer/core/*.cpp \
  tracer/image/image.cpp tracer/image/image_io.cpp \
  -ltinyobjloader -ltinygltf -lstb -ltinyexr -o "$OUT/fuzz_loaders"
status=0
for fmt in json obj gltf glb ply pbrt; do
  mkdir -p "$OUT/corpus/$fmt" "$OUT/seeds/$fmt"
  # Seeds: the project's own (tests/fuzz/corpus) and the real files the corpus test renders
  # (assimp-testmodels, glmark2-data) and the shared Bitterli scenes that fit the input limit,
  # named by content.
  find /usr/share/assimp/models /usr/share/glmark2/models ../shared/scenes -type f -iname "*.$fmt" -size -64k \
      2>/dev/null | while read -r f; do
    cp "$f" "$OUT/seeds/$fmt/$(md5sum < "$f" | cut -c1-16).$fmt"
  done
  seeds=("$OUT/seeds/$fmt")
  [ -d "tests/fuzz/corpus/$fmt" ] && seeds+=("tests/fuzz/corpus/$fmt")
  echo "fuzz: $fmt for ${SECONDS_EACH}s ($(ls "${seeds[@]}" | grep -c "\.") seed files)"
  if ! FUZZ_FORMAT=$fmt "$OUT/fuzz_loaders" "$OUT/corpus/$fmt" "${seeds[@]}" \
      -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=4096 -max_len=65536 \
      -artifact_prefix="$OUT/crash-$fmt-" -print_final_stats=1 > "$OUT/$fmt.log" 2>&1; then
    echo "fuzz: $fmt FAILED; see $OUT/$fmt.log and $OUT/crash-$fmt-*"
    tail -30 "$OUT/$fmt.log"
    status=1
  else
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$OUT/$fmt.log" | sed "s/^/fuzz: $fmt /"
  fi
done
exit $status
