#!/usr/bin/env bash
# Runs every test of hairrecon on a fresh machine: sets up the environment first (scripts/setup_env.sh,
# which builds the Rust tests with the CLI),
# then formatting, the documentation's links and API docs, lints, the Rust tests (with every reader on
# the committed fuzzing corpus; the coverage-guided run is scripts/fuzz.sh), and the Python tests
# (bpy + Cycles, headless), the extension's tests a second time with Blender 4.2 (bpy 4.2).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
step() { echo "== $* (at $(( $(date +%s) - start )) s)"; }
bash scripts/setup_env.sh --blender42 --tests
# pytest keeps the temporary folders of failed tests only (a passing run leaves no 1.5 GB in /tmp);
# the test-preset capture is rendered once and shared by both pytest runs (tests/python/conftest.py)
HAIRRECON_TEST_CAPTURE_CACHE="$(mktemp -d)"
export HAIRRECON_TEST_CAPTURE_CACHE
trap 'rm -rf "$HAIRRECON_TEST_CAPTURE_CACHE"' EXIT

step "cargo fmt --check"
cargo fmt --all -- --check
step "links in README.md, docs/ and research/; the README's results table against docs/results"
.venv/bin/python scripts/check_links.py
.venv/bin/python scripts/results_table.py --straight docs/results/paper_straight.json \
  --curly docs/results/paper_curly.json --check README.md
# doc and clippy in the release profile: they reuse the proc macros that setup built for it (the dev
# profile compiles every dependency, proc macros included, at opt-level 3: 186 s against 68 s here)
step "cargo doc (no warnings)"
RUSTDOCFLAGS="-D warnings" cargo doc --release --quiet --workspace --no-deps
step "cargo clippy (all targets, -D warnings)"
cargo clippy --release --quiet --workspace --all-targets -- -D warnings
# the unit and integration tests, then the doc tests (the examples are not built: clippy checked them)
step "cargo test (release profile; every reader on the fuzzing corpus; the Python module is tested from Python)"
cargo test --release --workspace --exclude hairrecon-python --tests
cargo test --release --workspace --exclude hairrecon-python --doc
export HAIRRECON_BIN="${CARGO_TARGET_DIR:-$(pwd)/target}/release/hairrecon"
export HAIRRECON_WHEEL="$(ls "$(pwd)"/target/wheels-hairrecon/hairrecon-*.whl | head -n 1)"
# The two pytest sessions run at once: the extension's tests with Blender 4.2 (bpy 4.2, the oldest Blender
# the extension supports) in the background, with its own temporary folder and log, printed when it ends
# (both took 378 s against 457 s one after the other with the environments set up; 443 s against 455 s
# on a fresh clone, where both are CPU-bound for longer).
step "pytest tests/python, and tests/python/test_addon.py with Blender 4.2 beside it"
PYTEST42_TMP="$(mktemp -d)"
trap 'rm -rf "$HAIRRECON_TEST_CAPTURE_CACHE" "$PYTEST42_TMP"' EXIT
TMPDIR="$PYTEST42_TMP" HAIRRECON_TEST_PYTHON="$(pwd)/.venv-blender42/bin/python" .venv/bin/python -m pytest -q \
  -o tmp_path_retention_policy=failed --durations=8 tests/python/test_addon.py > "$PYTEST42_TMP/log" 2>&1 &
pytest42=$!
status=0
.venv/bin/python -m pytest -q -o tmp_path_retention_policy=failed --durations=12 tests/python || status=$?
status42=0
wait "$pytest42" || status42=$?
echo "== pytest tests/python/test_addon.py with Blender 4.2 (bpy 4.2), run beside the session above:"
cat "$PYTEST42_TMP/log"
if [ "$status" != 0 ] || [ "$status42" != 0 ]; then
  echo "== pytest failed: tests/python exit $status, test_addon.py with Blender 4.2 exit $status42" >&2
  exit 1
fi
echo "== all tests passed in $(( $(date +%s) - start )) s"
