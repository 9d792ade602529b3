#!/usr/bin/env bash
# The main job on the bundled default head (see scripts/demo.py): sets up the environment, then
# renders a small synthetic head, reconstructs it, evaluates it, and writes strands, a .blend and a picture.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_env.sh
exec .venv/bin/python scripts/demo.py "$@"
