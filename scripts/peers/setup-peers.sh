#!/usr/bin/env bash
# Installs the peer renderers compared in docs/BENCHMARKS.md (Blender Cycles, Embree's tutorial
# path tracer) from Debian, only the missing ones; silent when everything is present.
set -euo pipefail

PACKAGES=(blender embree-tools python3-numpy)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup-peers: installing ${missing[*]}" >&2
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq >/dev/null
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
