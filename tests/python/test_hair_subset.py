"""scripts/hair_subset.py: every n-th strand from a first one, in order, points unchanged; bad input
gets an error and no output file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

import _hairio as hio

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "hair_subset.py"


def _strands(tmp_path: Path) -> Path:
    # 7 strands, strand i has i + 2 points whose x is the strand index and y the point index.
    counts = np.arange(7) + 2
    pts = np.concatenate([np.stack([np.full(c, i), np.arange(c), np.zeros(c)], 1) for i, c in enumerate(counts)])
    path = tmp_path / "in.hair"
    hio.write_hair(path, pts.astype(np.float32), counts)
    return path


def _run(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True)


def test_keeps_every_nth_strand_from_the_first(tmp_path):
    src, out = _strands(tmp_path), tmp_path / "out.hair"
    r = _run(src, out, "--every", "3", "--first", "1")
    assert r.returncode == 0, r.stderr
    pts, counts = hio.read_hair(out)
    assert counts.tolist() == [3, 6]  # strands 1 and 4
    assert pts[:3, 0].tolist() == [1, 1, 1] and pts[3:, 0].tolist() == [4] * 6
    assert pts[3:, 1].tolist() == [0, 1, 2, 3, 4, 5]


def test_bad_input_gets_an_error_and_no_file(tmp_path):
    out = tmp_path / "out.hair"
    (tmp_path / "bad.hair").write_bytes(b"not hair")
    r = _run(tmp_path / "bad.hair", out)
    assert r.returncode == 1 and "not a .hair file" in r.stderr and not out.exists()
    r = _run(_strands(tmp_path), out, "--first", "9")
    assert r.returncode == 1 and "keeps none" in r.stderr and not out.exists()
