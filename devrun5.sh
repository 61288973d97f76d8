tar -xzf .devbuild/dist.tar.gz -C .devbuild
OUT=$OUT/t scripts/gpu-check.sh tests > $OUT/tests.txt 2>&1; grep -E "PASSED|FAILED" $OUT/tests.txt | tail -3; grep -E "light tracing" $OUT/tests.txt | head -6
SCENES="glass_lamp cornell_spheres materials smallpt" REF_SPP=16384 TIME_LIMIT=5 PIC_TIME=0.3 CONFIGS=auto,auto+light_tracing=on OUT=$OUT scripts/gpu-check.sh light > $OUT/light.txt 2>&1; grep -E "^====|^configuration|^auto|^wavefront" $OUT/light.txt | head -24
for sc in glass_lamp cornell_spheres materials; do .devbuild/dist/pathtracer bench assets/scenes/$sc.json --cpu-spp 0 --spp 8 --set render.light_tracing=on > $OUT/bench-$sc.txt 2>&1; echo "== $sc"; grep -E "^(wavefront|auto|megakernel) " $OUT/bench-$sc.txt | head -3; grep -E "^  light" $OUT/bench-$sc.txt | head -1; done
