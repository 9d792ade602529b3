#!/usr/bin/env bash
# Sets up everything hairrecon needs on a fresh machine, idempotently:
#   - .venv/ (Python 3.11) with bpy, numpy, maturin, pytest (requirements-dev.txt);
#   - the release build of the `hairrecon` CLI (target/release/hairrecon);
#   - the Python module `hairrecon`: one abi3 wheel built by maturin (target/wheels-hairrecon/), installed
#     into .venv; the Blender extension's tests bundle the same wheel;
#   - with --blender42: also .venv-blender42 with bpy 4.2 (requirements-blender42.txt), the oldest Blender the
#     extension supports, for the extension's tests (scripts/test.sh);
#   - with --tests: the CLI built together with the Rust tests, as `cargo test --release --tests` builds them
#     (the dev-dependencies add features to shared crates, so a CLI built alone is compiled twice); the
#     examples are benchmarks and studies, not tests: clippy checks that they compile.
# Needs: a Rust toolchain (cargo) and CPython 3.11 with venv and pip.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
BLENDER42=0
TESTS=0
for arg in "$@"; do
  case "$arg" in
    --blender42) BLENDER42=1 ;;
    --tests) TESTS=1 ;;
    *) echo "setup: error: unknown argument '$arg' (the options are --blender42 and --tests)" >&2; exit 2 ;;
  esac
done

PY=${PYTHON:-}
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)'; then
      PY=$cand; break
    fi
  done
fi
if [ -z "$PY" ]; then
  echo "setup: error: Python 3.11 is needed (bpy 5.0 is built for 3.11); install it or set PYTHON=/path/to/python3.11" >&2
  exit 1
fi
command -v cargo >/dev/null 2>&1 || { echo "setup: error: cargo not found; install Rust (rustup) first" >&2; exit 1; }

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $PY (at ${SECONDS} s)"
  "$PY" -m venv .venv
fi
stamp=.venv/.requirements.sha
want=$(sha256sum requirements-dev.txt | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: installing Python packages (requirements-dev.txt) (at ${SECONDS} s)"
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -r requirements-dev.txt
  echo "$want" > "$stamp"
fi

if [ "$TESTS" = 1 ]; then
  echo "setup: building the hairrecon CLI with the Rust tests (release) (at ${SECONDS} s)"
  cargo build --release --quiet --workspace --exclude hairrecon-python --lib --bins --tests
else
  echo "setup: building the hairrecon CLI (release) (at ${SECONDS} s)"
  cargo build --release --quiet -p hairrecon-cli
fi

echo "setup: building the Python module (abi3 wheel, maturin, release) and installing it into .venv (at ${SECONDS} s)"
rm -rf target/wheels-hairrecon
.venv/bin/maturin build --release --quiet -m rust/python/Cargo.toml -o target/wheels-hairrecon >/dev/null
wheel=$(ls target/wheels-hairrecon/hairrecon-*.whl | head -n 1)
.venv/bin/python -m pip install --quiet --force-reinstall --no-deps "$wheel"
.venv/bin/python -c 'import hairrecon, bpy; print("setup: ok (hairrecon", hairrecon.__version__ + ", bpy", bpy.app.version_string + ")")'

if [ "$BLENDER42" = 1 ]; then
  stamp42=.venv-blender42/.requirements.sha
  want42=$(sha256sum requirements-blender42.txt | cut -d' ' -f1)
  if [ ! -x .venv-blender42/bin/python ] || [ "$(cat "$stamp42" 2>/dev/null)" != "$want42" ]; then
    echo "setup: installing bpy 4.2 into .venv-blender42 (requirements-blender42.txt) (at ${SECONDS} s)"
    [ -x .venv-blender42/bin/python ] || "$PY" -m venv .venv-blender42
    .venv-blender42/bin/python -m pip install --quiet --upgrade pip
    .venv-blender42/bin/python -m pip install --quiet -r requirements-blender42.txt
    echo "$want42" > "$stamp42"
  fi
  .venv-blender42/bin/python -c 'import bpy, sys
if bpy.app.version[:2] != (4, 2):
    sys.exit(f"setup: error: .venv-blender42 holds bpy {bpy.app.version_string}, not 4.2; delete .venv-blender42")
print("setup: ok (.venv-blender42: bpy", bpy.app.version_string + ")")'
fi
echo "setup: done (at ${SECONDS} s)"
