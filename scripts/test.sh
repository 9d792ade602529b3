#!/usr/bin/env bash
# Runs every test of hairrecon on a fresh machine: sets up the environment first (scripts/setup_env.sh),
# then formatting and lints, the Rust tests, and the Python tests (bpy + Cycles, headless), the
# extension's tests a second time with Blender 4.2 (bpy 4.2).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
bash scripts/setup_env.sh --blender42

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
echo "== pytest tests/python/test_addon.py with Blender 4.2 (bpy 4.2, the oldest Blender the extension supports)"
HAIRRECON_TEST_PYTHON="$(pwd)/.venv-blender42/bin/python" .venv/bin/python -m pytest -q tests/python/test_addon.py
echo "== all tests passed in $(( $(date +%s) - start )) s"
