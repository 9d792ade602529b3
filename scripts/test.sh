#!/usr/bin/env bash
# Runs every test of hairrecon on a fresh machine: sets up the environment first (scripts/setup_env.sh),
# then formatting and lints, the Rust tests, and the Python tests (bpy + Cycles, headless).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
bash scripts/setup_env.sh

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (all targets, -D warnings)"
cargo clippy --quiet --workspace --all-targets -- -D warnings
echo "== cargo test (release profile; the Python module is tested from Python)"
cargo test --release --workspace --exclude hairrecon-python
echo "== pytest tests/python"
export HAIRRECON_BIN="${CARGO_TARGET_DIR:-$(pwd)/target}/release/hairrecon"
export HAIRRECON_WHEEL="$(ls "$(pwd)"/target/wheels-hairrecon/hairrecon-*.whl | head -n 1)"
.venv/bin/python -m pytest -q tests/python
echo "== all tests passed in $(( $(date +%s) - start )) s"
