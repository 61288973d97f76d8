tar -xzf .devbuild/dist.tar.gz -C .devbuild
OUT=$OUT/t scripts/gpu-check.sh tests > $OUT/tests.txt 2>&1; grep -E "PASSED|FAILED|tests from|Skipped" $OUT/tests.txt | tail -5; grep -E "light tracing|LightTracing" $OUT/tests.txt | head -8
SCENES="smallpt materials" REF_SPP=8192 TIME_LIMIT=5 PIC_TIME=0.3 CONFIGS=auto,auto+light_tracing=on OUT=$OUT scripts/gpu-check.sh light > $OUT/light.txt 2>&1; grep -E "^====|^configuration|^auto|^wavefront|chi2|PASSED|FAILED" $OUT/light.txt | head -20
