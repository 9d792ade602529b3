"""Runs Blender (the bpy module) in a subprocess for the add-on tests.

bpy can be imported once per process and an extension installs into the user folder that
BLENDER_USER_RESOURCES names before ``import bpy``; so each test runs ``addon_worker.py`` in a fresh
Python with its own temporary user folder, and gets the worker's results back as JSON (the last
stdout line starting with ``RESULT ``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WORKER = Path(__file__).with_name("addon_worker.py")
# The Python that runs Blender: the project's .venv (bpy 5.0), or HAIRRECON_TEST_PYTHON, a Python with another
# bpy (scripts/test.sh runs these tests a second time with .venv-blender42: bpy 4.2, the oldest Blender the
# extension supports).
PYTHON = Path(os.environ.get("HAIRRECON_TEST_PYTHON") or ROOT / ".venv" / "bin" / "python")


def run_worker(task: str, user_dir: Path, timeout: float = 600, **params) -> dict:
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = str(user_dir)
    user_dir.mkdir(parents=True, exist_ok=True)
    py = str(PYTHON if PYTHON.exists() else sys.executable)
    proc = subprocess.run(
        [py, str(WORKER), task, json.dumps(params)],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=str(user_dir),
    )
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    if proc.returncode != 0 or not lines:
        raise AssertionError(
            f"worker task {task!r} failed (exit {proc.returncode})\n--- stdout ---\n{proc.stdout[-6000:]}\n"
            f"--- stderr ---\n{proc.stderr[-6000:]}"
        )
    out = json.loads(lines[-1][len("RESULT "):])
    out["_stdout"] = proc.stdout
    out["_stderr"] = proc.stderr
    return out
