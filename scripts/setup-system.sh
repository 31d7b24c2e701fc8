#!/usr/bin/env bash
# Installs the system packages plugflow needs (as root or through sudo, idempotent; packages
# already present are left alone), all from Debian 12's archive, and checks the Rust
# toolchain (which Debian's archive does not carry recent enough: see README).
#   --base  only what building and running plugflow needs: a C/C++ compiler and make
#           (build-essential: the HDF5 and Python bindings build C), the HDF5 C library
#           (run.h5) and pkg-config, which finds it.
#   (none)  also what the tests and the benchmark need: LIGGGHTS with its headers and
#           OpenMPI (reference engine; openmpi-bin's `mpirun` runs it on several ranks), YADE with Python 3.11's headers (the YADE shim embeds
#           Debian's Python to drive it; ~770 MB), procps (pgrep/kill in the isolation
#           test), and for Debian's own /usr/bin/python3 h5py (reads run.h5 back), and
#           ParaView's Python (under pvbatch, VTK's XML readers read the ParaView files back
#           and its XDMF reader opens run.xdmf; ParaView itself comes with liggghts, its
#           Python adds ~8 s; it conflicts with python3-vtk9, which it replaces), and
#           LAMMPS (`lmp`, 2022, GRANULAR: `cargo bench --bench chute_bench`). Debian's
#           packages, not pip: a plain
#           Debian 12 refuses pip into the system Python (PEP 668).
set -euo pipefail
# The oldest Rust that builds plugflow: Cargo.toml's rust-version (its dependencies need it).
need_rust=$(sed -n 's/^rust-version = "\(.*\)"/\1/p' "$(dirname "$0")/../Cargo.toml")
pkgs=(build-essential libhdf5-dev pkg-config)
if [ "${1:-}" != "--base" ]; then
  pkgs+=(liggghts libliggghts-dev libopenmpi-dev openmpi-bin yade python3-yade libpython3.11-dev procps
    python3-h5py python3-paraview lammps)
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
# The toolchain: say what to do rather than fail deep inside a dependency's build.
if ! command -v cargo > /dev/null || ! command -v rustc > /dev/null; then
  echo "setup: no Rust toolchain (cargo, rustc) on PATH; plugflow needs Rust >= $need_rust." >&2
  echo "setup: install one with rustup (https://rustup.rs), then open a new shell." >&2
  exit 1
fi
have_rust=$(rustc --version | awk '{print $2}')
if [ "$(printf '%s\n%s\n' "$need_rust" "$have_rust" | sort -V | head -1)" != "$need_rust" ]; then
  echo "setup: rustc $have_rust is older than plugflow's minimum $need_rust." >&2
  echo "setup: update it with \`rustup update stable\` (or install rustup: https://rustup.rs;" >&2
  echo "setup: Debian's own rustc package is too old)." >&2
  exit 1
fi
