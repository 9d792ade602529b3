"""Shared pytest fixtures for the Python-side tests.

``test_capture`` (session scope) renders ONE synthetic capture with the ``test`` preset (about 2,000
strands, 16 views, 256 px high) into a temporary folder, once per test session, and returns its path.
It needs:

- the ``hairrecon`` binary: ``$HAIRRECON_BIN`` if set, else ``target/release/hairrecon``, built with
  ``cargo build --release -p hairrecon-cli`` (a no-op when it is up to date);
- the head fixture ``blend_fixtures/head.ply`` (and ``scalp.ply`` if present); without it, the raw
  head of ``/work/shared/data/heads/woman_head.ply`` (or ``$HAIRRECON_RAW_HEAD``) brought to the
  fixture's frame;
- hair from ``hairrecon synth-hair --style straight``; if that subcommand is not available, toy hair
  from ``scripts/_toyhair.py`` (the fixture says so on stdout).

Set ``HAIRRECON_TEST_CAPTURE`` to an existing capture folder to skip the render (for development).
"""

from __future__ import annotations

import os
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


def _head(tmp: Path) -> tuple[Path, Path | None]:
    head = REPO / "blend_fixtures" / "head.ply"
    scalp = REPO / "blend_fixtures" / "scalp.ply"
    if head.is_file():
        return head, scalp if scalp.is_file() else None
    import _hairio as hio
    import _toyhair as th

    raw = Path(os.environ.get("HAIRRECON_RAW_HEAD", "/work/shared/data/heads/woman_head.ply"))
    v, f = hio.read_ply(raw)
    out = tmp / "head.ply"
    hio.write_ply(out, th.fixture_head(v), f)
    return out, None


def _hair(exe: Path, head: Path, tmp: Path, strands: int) -> Path:
    out = tmp / "gt.hair"
    r = subprocess.run(
        [str(exe), "synth-hair", "--style", "straight", "--strands", str(strands), "--seed", "0", "--out", str(out)],
        capture_output=True,
        text=True,
    )
    if r.returncode == 0 and out.is_file():
        return out
    print(f"test_capture: synth-hair unavailable ({r.stderr.strip()[:200]}); using toy hair", flush=True)
    import _hairio as hio
    import _toyhair as th

    v, f = hio.read_ply(head)
    pts, counts = th.toy_hair(v, f, strands, seed=0)
    hio.write_hair(out, pts, counts)
    return out


@pytest.fixture(scope="session")
def test_capture(tmp_path_factory) -> Path:
    """Path of a rendered test-preset capture folder (see the module doc)."""
    env = os.environ.get("HAIRRECON_TEST_CAPTURE")
    if env:
        return Path(env)
    tmp = tmp_path_factory.mktemp("synthetic")
    exe = hairrecon_bin()
    head, scalp = _head(tmp)
    hair = _hair(exe, head, tmp, 2000)
    cap = tmp / "capture"
    cmd = [sys.executable, str(SCRIPTS / "render_synthetic.py"), str(hair), str(head), str(cap)]
    cmd += ["--preset", "test", "--hairrecon-bin", str(exe)]
    if scalp:
        cmd += ["--scalp", str(scalp)]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return cap
