#!/usr/bin/env bash
# The README's test command: system packages, formatting, lints, and every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-system.sh
# The outputs test must read run.h5 from Python too (h5py installed above).
export PLUGFLOW_REQUIRE_H5PY=1
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release --features plugflow-dem-liggghts/liggghts -- -D warnings
# The ABI engines' shared libraries (cdylibs) are built by `cargo build`, not by
# `cargo test`; the engine tests load them from target/release/.
cargo build --release --workspace --features plugflow-dem-liggghts/liggghts
log=$(mktemp)
# Unit and integration tests (the benchmark is not a test: cargo bench --bench dem_bench).
# The LIGGGHTS shim (GPL crate) builds only with its feature; the cross-code tests load it.
cargo test --workspace --release --features plugflow-dem-liggghts/liggghts --lib --bins --tests 2>&1 | tee "$log"
# One closing line with the totals of every test binary.
awk '/^test result:/ { p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' "$log"
