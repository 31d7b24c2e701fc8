#!/usr/bin/env bash
# Installs the system packages plugflow's tests and benchmarks need (as root, idempotent):
# LIGGGHTS (reference engine for the benchmark and the cross-code tests) with its headers
# and OpenMPI. Packages already present are left alone.
set -euo pipefail
pkgs=(liggghts libliggghts-dev libopenmpi-dev)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi
