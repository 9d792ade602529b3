"""scripts/curl_resynth.py: a window of one turn recovers a helix's axis, the helix it sweeps has the
asked radius and handedness, at the strand's own phase with phase=own; bad input gets an error and no
output file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

import _hairio as hio

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "curl_resynth.py"
R, PERIOD = 0.0065, 0.022


def _helix(tmp_path: Path, hand: float, phase: float = 0.0) -> Path:
    # One strand: a helix of the curly preset's radius and period about the -z axis, 200 mm of axis,
    # 2,000 points (finer than the script's 1 mm resampling).
    z = np.linspace(0.0, 0.2, 2000)
    phi = phase + hand * 2 * np.pi * z / PERIOD
    pts = np.stack([R * np.cos(phi), R * np.sin(phi), -z], 1)
    path = tmp_path / f"in_{phase}.hair"
    hio.write_hair(path, pts.astype(np.float32), np.array([len(pts)]))
    return path


def _run(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True)


def _middle(out: Path) -> np.ndarray:
    pts, counts = hio.read_hair(out)
    assert len(counts) == 1
    return pts[(pts[:, 2] < -0.03) & (pts[:, 2] > pts[:, 2].min() + 0.03)].astype(np.float64)


def test_centreline_of_one_turn_is_the_axis(tmp_path):
    out = tmp_path / "c.hair"
    r = _run(_helix(tmp_path, 1.0), out, 46, 6.5, 22, "hand=0")
    assert r.returncode == 0, r.stderr
    mid = _middle(out)
    assert len(mid) > 20
    # Off the axis by under 0.5 mm (the strand itself is 6.5 mm off everywhere).
    assert np.hypot(mid[:, 0], mid[:, 1]).max() < 0.0005


def test_helix_has_the_radius_and_the_handedness(tmp_path):
    src = _helix(tmp_path, 1.0)
    for hand in (1, -1):
        out = tmp_path / f"h{hand}.hair"
        r = _run(src, out, 46, 6.5, 22, f"hand={hand}", "ramp_mm=0", "seed=3")
        assert r.returncode == 0, r.stderr
        mid = _middle(out)
        radial = np.hypot(mid[:, 0], mid[:, 1])
        assert np.abs(radial - R).max() < 0.0008
        # About the root-to-tip axis (-z), right-handed: (radial x tangent) . axis > 0.
        t = np.gradient(mid, axis=0)
        rad = mid.copy()
        rad[:, 2] = 0.0
        turn = np.cross(rad, t)[:, 2] * -1.0
        assert np.sign(np.median(turn)) == hand
        # About 22 mm of axis per turn: the angle advances 2 pi per 22 mm.
        ang = np.unwrap(np.arctan2(mid[:, 1], mid[:, 0]))
        per_m = abs(ang[-1] - ang[0]) / abs(mid[-1, 2] - mid[0, 2])
        assert abs(per_m - 2 * np.pi / PERIOD) < 0.05 * 2 * np.pi / PERIOD


def test_own_phase_follows_the_strand(tmp_path):
    # phase=own puts the swept helix on the strand it replaces, whatever the strand's phase; a random
    # phase (seeds 0-3) leaves it millimetres off. (`_helix(..., -1.0)` turns right-handed about the
    # root-to-tip direction -z in the script's sense: clockwise seen from +z.)
    def farthest(src: Path, out: Path) -> float:
        a = _middle(out)
        b, _ = hio.read_hair(src)
        return max(np.linalg.norm(b - p, axis=1).min() for p in a)

    for phase in (0.0, 2.0, -2.5):
        src = _helix(tmp_path, -1.0, phase)
        out = tmp_path / "own.hair"
        r = _run(src, out, 46, 6.5, 22, "phase=own")
        assert r.returncode == 0, r.stderr
        assert farthest(src, out) < 0.0005, phase
    src = _helix(tmp_path, -1.0, 2.0)
    for seed in range(4):
        out = tmp_path / f"random{seed}.hair"
        r = _run(src, out, 46, 6.5, 22, f"seed={seed}")
        assert r.returncode == 0, r.stderr
        assert farthest(src, out) > 0.002, seed


def test_bad_input_gets_an_error_and_no_file(tmp_path):
    out = tmp_path / "out.hair"
    (tmp_path / "bad.hair").write_bytes(b"not hair")
    r = _run(tmp_path / "bad.hair", out, 46, 6.5, 22)
    assert r.returncode == 1 and "not a .hair file" in r.stderr and not out.exists()
    r = _run(_helix(tmp_path, 1.0), out, 46, 6.5, 22, "turns=3")
    assert r.returncode == 1 and "unknown option" in r.stderr and not out.exists()
    r = _run(_helix(tmp_path, 1.0), out, 46, 6.5, 22, "phase=best")
    assert r.returncode == 1 and "phase=random or phase=own" in r.stderr and not out.exists()
    r = _run(_helix(tmp_path, 1.0), out, 46, 6.5, 0)
    assert r.returncode == 1 and "PERIOD_MM" in r.stderr and not out.exists()
