#!/usr/bin/env bash
# Installs the system packages plugflow needs (as root or through sudo, idempotent; packages
# already present are left alone).
#   --base  only what building and running plugflow needs: the HDF5 C library (run.h5)
#           and pkg-config, which finds it.
#   (none)  also what the tests and the benchmark need: LIGGGHTS with its headers and
#           OpenMPI (reference engine), YADE with Python 3.11's headers (the YADE shim embeds
#           Debian's Python to drive it; ~770 MB), procps (pgrep/kill in the isolation
#           test), h5py (reads run.h5 back from Python) and Python's vtk (reads the ParaView
#           files back).
set -euo pipefail
pkgs=(libhdf5-dev pkg-config)
if [ "${1:-}" != "--base" ]; then
  pkgs+=(liggghts libliggghts-dev libopenmpi-dev yade python3-yade libpython3.11-dev procps)
fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
if [ ${#missing[@]} -gt 0 ]; then
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi
if [ "${1:-}" != "--base" ]; then
  python3 -c "import h5py" 2>/dev/null || python3 -m pip install -q --root-user-action=ignore h5py
  # VTK's own readers, to read the ParaView files back in the outputs test (~140 MB wheel).
  python3 -c "import vtk" 2>/dev/null || python3 -m pip install -q --root-user-action=ignore vtk
fi
