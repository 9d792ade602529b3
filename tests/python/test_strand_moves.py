"""scripts/strand_moves.py: a slide along the strand is no move across it; a shift across is."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import strand_moves  # noqa: E402


def helix(n=200, start=0.0):
    t = np.linspace(start, 4 * np.pi, n)
    return np.stack([0.006 * np.cos(t), 0.006 * np.sin(t), -0.0035 * t], axis=1)


def test_a_slide_along_the_helix_moves_points_but_not_across():
    before = (helix(), np.array([200]))
    # The same helix resampled from 0.6 rad on: the points slide along it, by 0.6 rad at the root
    # and none at the tip (about 1.4 mm at the median), and stay on the curve.
    slid = helix(start=0.6)
    m = strand_moves.moves(before, (slid, np.array([200])), every=1)
    assert m["pointwise"][50] == pytest.approx(1000 * 0.3 * np.hypot(0.006, 0.0035), rel=0.05)
    assert m["across"][99] < 0.02


def test_a_shift_across_is_measured_in_millimetres():
    p = helix()
    m = strand_moves.moves((p, np.array([200])), (p + np.array([0.0, 0.0015, 0.0]), np.array([200])), every=1)
    assert m["pointwise"][50] == pytest.approx(1.5, abs=1e-6)
    # Across a helix of 6 mm radius a 1.5 mm shift comes out between a third of it and all of it.
    assert 0.5 < m["across"][50] <= 1.5


def test_sets_that_are_not_one_set_before_and_after_are_refused():
    p = helix()
    with pytest.raises(ValueError, match="differ"):
        strand_moves.moves((p, np.array([200])), (p[:100], np.array([100])), every=1)
