#!/usr/bin/env bash
# The README's second command: set up, build everything and run every test with ctest.
# GPU tests (label `gpu`) skip with a reason when no CUDA device is present.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --build build
cd build
ctest --output-on-failure -j "$(nproc)" "$@"
