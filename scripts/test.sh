#!/usr/bin/env bash
# The README's second command: set up, build everything and run every test with ctest.
# GPU tests (label `gpu`) skip with a reason when no CUDA device is present; the reason is
# printed after the run.
set -euo pipefail
cd "$(dirname "$0")/.."
# Everything is built, the CUDA backend too wherever nvcc is (so CI checks that it compiles).
if command -v nvcc >/dev/null || [ -x /usr/local/cuda/bin/nvcc ]; then export TRACER_CUDA=ON; fi
scripts/setup.sh
echo "test: building every target${TRACER_CUDA:+, the CUDA backend included}" >&2
cmake --build build
rc=0
(cd build && ctest --output-on-failure -j "$(nproc)" "$@") || rc=$?
if [ -x build/tests/cuda_test ]; then
  why=$(build/tests/cuda_test --gtest_filter=Gpu.ResetIsComplete 2>&1 | grep -m1 "GPU test skipped" || true)
  [ -z "$why" ] || echo "note: tests labelled gpu were skipped: ${why#*: }"
fi
exit "$rc"
