"""The measures of Test Hair Physics (addon/hairrecon/core/physics_measures.py, no Blender needed): strands
made by hand, moved by hand, and the figures each motion must give."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import addon_core  # noqa: E402

pm = addon_core.load("physics_measures")


def two_strands():
    """A straight strand along +X (4 points, 3 cm) and a bent one (3 points, 1 cm then 2 cm up)."""
    a = np.array([[0, 0, 0], [0.01, 0, 0], [0.02, 0, 0], [0.03, 0, 0]], float)
    b = np.array([[0, 0.1, 0], [0.01, 0.1, 0], [0.01, 0.1, 0.02]], float)
    return np.concatenate([a, b]), np.array([4, 3])


def test_resample_spaces_points_evenly_and_keeps_the_ends():
    pts, counts = two_strands()
    r = pm.resample(pts, counts, np.array([0, 1]), 7)
    assert r.shape == (2, 7, 3)
    seg = np.linalg.norm(np.diff(r, axis=1), axis=2)
    assert np.allclose(seg[0], 0.005) and np.allclose(seg[1], 0.005)
    assert np.allclose(r[1, 0], pts[4]) and np.allclose(r[1, -1], pts[6])
    # the bent strand's corner (1 cm along) is its third resampled point
    assert np.allclose(r[1, 2], [0.01, 0.1, 0.0])
    with pytest.raises(pm.PhysicsInputError, match="no length"):
        pm.resample(np.zeros((3, 3)), np.array([3]), np.array([0]), 5)


def test_pick_is_seeded_and_skips_single_points():
    counts = np.array([5, 1, 5, 5, 5, 5])
    a, b = pm.pick(counts, 3, seed=4), pm.pick(counts, 3, seed=4)
    assert list(a) == list(b) and len(a) == 3 and 1 not in a and list(a) == sorted(a)
    assert list(pm.pick(counts, 10, seed=0)) == [0, 2, 3, 4, 5]
    with pytest.raises(pm.PhysicsInputError):
        pm.pick(np.array([1, 1]), 3, seed=0)


def test_head_keys_turn_and_nod_within_the_frames():
    keys = pm.head_keys(48, 45.0, 20.0)
    frames = [k[0] for k in keys]
    assert frames[0] == 1 and frames[-1] == 48 and frames == sorted(set(frames))
    assert max(k[1] for k in keys) == 45.0 and min(k[1] for k in keys) == -45.0
    assert max(k[2] for k in keys) == 20.0 and keys[-1][1:] == (0.0, 0.0)
    assert all(yaw == 0.0 or pitch == 0.0 for _, yaw, pitch in keys)
    with pytest.raises(pm.PhysicsInputError):
        pm.head_keys(8, 45.0, 20.0)


def test_measures_of_known_motions():
    rest = pm.resample(*two_strands(), np.array([0, 1]), 5)
    m = pm.Measures()
    m.add(1, rest, np.full(rest.shape[:2], -0.01))
    # frame 2: the straight strand's last segment stretched by 50 %, its tip 1 cm into the head
    f2 = rest.copy()
    f2[0, -1] += (f2[0, -1] - f2[0, -2]) * 0.5
    depth = np.full(rest.shape[:2], -0.01)
    depth[0, -1] = 0.01
    row = m.add(2, f2, depth)
    assert row["stretch_max_pct"] == pytest.approx(50.0)
    assert row["inside_pct"] == pytest.approx(100.0 / 8)  # one of the 8 points past the roots
    assert row["inside_depth_max_mm"] == pytest.approx(10.0)
    assert row["root_max_mm"] == 0.0 and not row["exploded"]
    # frame 3: the bent strand's root slides 0.5 mm along its scalp
    f3 = rest.copy()
    f3[1] += [0.0005, 0, 0]
    assert m.add(3, f3, np.full(rest.shape[:2], -0.01))["root_max_mm"] == pytest.approx(0.5)
    s = m.summary()
    assert s["frames"] == 3 and s["ok"] is False
    assert set(s["failed"]) == {"root_max_mm", "stretch_p95_pct", "inside_max_pct"}
    assert s["stretch_max_pct"] == pytest.approx(50.0)
    assert s["tip_motion_median_mm"] > 0


def test_an_exploded_simulation_is_caught():
    rest = pm.resample(*two_strands(), np.array([0, 1]), 5)
    m = pm.Measures(rest)
    far = rest.copy()
    far[1, -1] = [5.0, 0, 0]  # 5 m from a 3 cm strand's root
    assert m.add(1, far, np.zeros(rest.shape[:2]))["exploded"]
    nan = rest.copy()
    nan[0, 2] = np.nan
    assert m.add(2, nan, np.zeros(rest.shape[:2]))["finite"] is False
    s = m.summary()
    assert s["exploded"] and not s["finite"] and "exploded" in s["failed"]
    assert "exploded" in pm.describe(s)


def test_a_still_strand_passes():
    rest = pm.resample(*two_strands(), np.array([0, 1]), 5)
    m = pm.Measures()
    for f in range(1, 4):
        m.add(f, rest, np.full(rest.shape[:2], -0.01))
    s = m.summary()
    assert s["ok"] and s["failed"] == [] and s["tip_motion_median_mm"] == 0.0
