#!/usr/bin/env bash
# Installs the peer renderers compared in docs/BENCHMARKS.md (Blender Cycles, Embree's tutorial
# path tracer) from Debian, only the missing ones; silent when everything is present.
set -euo pipefail

PACKAGES=(blender embree-tools python3-numpy)

"$(dirname "$0")/../install-packages.sh" setup-peers "${PACKAGES[@]}"
