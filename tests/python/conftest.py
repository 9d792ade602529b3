"""Shared pytest fixtures for the Python-side tests.

``test_capture`` (session scope) renders ONE synthetic capture with the ``test`` preset (about 2,000
strands, 16 views, 256 px high) into a temporary folder, once per test session, and returns its path.
It needs:

- the ``hairrecon`` binary: ``$HAIRRECON_BIN`` if set, else ``target/release/hairrecon``, built with
  ``cargo build --release -p hairrecon-cli`` (a no-op when it is up to date);
- the head fixture ``blend_fixtures/head.ply`` and ``scalp.ply``;
- hair from ``hairrecon synth-hair --style straight`` (2,000 strands, seed 0).

Set ``HAIRRECON_TEST_CAPTURE`` to an existing capture folder to skip the render (for development).
Set ``HAIRRECON_TEST_CAPTURE_CACHE`` to a folder to render the capture there once and reuse it in later
pytest runs (``scripts/test.sh`` runs two pytest sessions at once, with bpy 5.0 and 4.2, on one render:
the first to need it renders it under a lock, the other waits).
"""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPTS = REPO / "scripts"
sys.path.insert(0, str(SCRIPTS))


def hairrecon_bin() -> Path:
    """The hairrecon binary to use; builds the release binary unless HAIRRECON_BIN is set."""
    env = os.environ.get("HAIRRECON_BIN")
    if env:
        return Path(env)
    subprocess.run(
        ["cargo", "build", "--release", "-p", "hairrecon-cli"], cwd=REPO, check=True, stdout=subprocess.DEVNULL
    )
    return REPO / "target" / "release" / "hairrecon"


def head_files() -> tuple[Path, Path]:
    """The bundled head and scalp (blend_fixtures/)."""
    head = REPO / "blend_fixtures" / "head.ply"
    scalp = REPO / "blend_fixtures" / "scalp.ply"
    for f in (head, scalp):
        if not f.is_file():
            raise FileNotFoundError(f"{f} is missing; it is part of the repository (blend_fixtures/README.md)")
    return head, scalp


def straight_hair(exe: Path, tmp: Path, strands: int, name: str = "gt.hair") -> Path:
    """``hairrecon synth-hair --style straight --seed 0`` on the bundled head, written as ``tmp/name``."""
    out = tmp / name
    cmd = [str(exe), "synth-hair", "--style", "straight", "--strands", str(strands), "--seed", "0", "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0 or not out.is_file():
        raise RuntimeError(f"{' '.join(cmd)} failed: {r.stderr.strip()[-2000:]}")
    return out


@pytest.fixture(scope="session")
def test_capture(tmp_path_factory) -> Path:
    """Path of a rendered test-preset capture folder (see the module doc)."""
    env = os.environ.get("HAIRRECON_TEST_CAPTURE")
    if env:
        return Path(env)
    cache = os.environ.get("HAIRRECON_TEST_CAPTURE_CACHE")
    if not cache:
        return render_test_capture(tmp_path_factory.mktemp("synthetic"), None)
    # the test command runs two pytest sessions at once: one renders, the other waits for it
    with open(Path(cache) / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (Path(cache) / "capture" / "capture.json").is_file():
            return Path(cache) / "capture"
        return render_test_capture(tmp_path_factory.mktemp("synthetic"), cache)


def render_test_capture(tmp: Path, cache: str | None) -> Path:
    """Renders the test-preset capture: in `tmp`, or into the folder `cache` (whole or not at all)."""
    exe = hairrecon_bin()
    head, scalp = head_files()
    hair = straight_hair(exe, tmp, 2000)
    cap = Path(cache) / "capture.partial" if cache else tmp / "capture"
    if cache:
        shutil.rmtree(cap, ignore_errors=True)
    cmd = [sys.executable, str(SCRIPTS / "render_synthetic.py"), str(hair), str(head), str(cap)]
    cmd += ["--preset", "test", "--hairrecon-bin", str(exe), "--scalp", str(scalp)]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    if cache:
        # a whole capture or none: render beside, then rename into place
        os.replace(cap, Path(cache) / "capture")
        return Path(cache) / "capture"
    return cap
