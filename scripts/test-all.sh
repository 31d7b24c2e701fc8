#!/usr/bin/env bash
# The README's test command: system packages, formatting, lints, and every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-system.sh
# The outputs test must read run.h5 from Python too (h5py installed above).
export PLUGFLOW_REQUIRE_H5PY=1
# and the ParaView files with VTK's readers (Python's vtk, installed above).
export PLUGFLOW_REQUIRE_PYTHON_VTK=1
# The external engines' shims (GPL crates) build only with their features.
features="plugflow-dem-liggghts/liggghts,plugflow-dem-yade/yade"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release --features "$features" -- -D warnings
# The ABI engines' shared libraries (cdylibs) are built by `cargo build`, not by
# `cargo test`; the engine tests load them from target/release/.
cargo build --release --workspace --features "$features"
log=$(mktemp)
# Unit and integration tests (the benchmark is not a test: cargo bench --bench dem_bench).
# The cross-code tests load the LIGGGHTS and YADE shims built above.
cargo test --workspace --release --features "$features" --lib --bins --tests 2>&1 | tee "$log"
# One closing line with the totals of every test binary.
awk '/^test result:/ { p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' "$log"
