#!/usr/bin/env bash
# The README's test command: system packages, formatting, lints, and every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-system.sh
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release -- -D warnings
cargo test --workspace --release
