"""How far a strand set moved from a starting one with the same strands and point counts (DR's
output against its init): each point's distance to its own strand's starting polyline (the move
*across* the strand) and to its own starting point (pointwise), as percentiles in millimetres.

The pointwise distance also counts the slide along the strand of DR's final even resampling, which
leaves the curve as it was (the metric resamples by arc length): on the paper curly init, DR with a
zero learning rate moves the children 3.8 mm pointwise at the median and 0.0 mm across (session 31,
docs/curly-study.md).

    .venv/bin/python scripts/strand_moves.py BEFORE.hair AFTER.hair [--every 40] [--json]

``--every N`` scores every N-th strand (default 40: 1,220 of the paper preset's 48,784 children).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _hairio import read_hair, strand_offsets  # noqa: E402

PERCENTILES = (10, 50, 90, 99)


def across(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Each of ``points``' distance to the polyline (its segments; a single point if it has one)."""
    if len(polyline) < 2:
        return np.linalg.norm(points - polyline[:1], axis=1)
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    rel = points[:, None, :] - a[None]
    t = np.clip((rel * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-18)[None], 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.sqrt(((points[:, None, :] - closest) ** 2).sum(-1)).min(axis=1)


def moves(before: tuple, after: tuple, every: int = 40) -> dict:
    """``{"across": {p: mm}, "pointwise": {p: mm}, "strands": n}`` for every ``every``-th strand."""
    (p0, c0), (p1, c1) = before, after
    if len(c0) != len(c1) or not np.array_equal(c0, c1):
        raise ValueError("the two sets differ in strands or point counts: not one set before and after")
    o = strand_offsets(c0)
    acr, pw = [], []
    picked = range(0, len(c0), max(every, 1))
    for s in picked:
        a, b = p0[o[s]:o[s] + c0[s]], p1[o[s]:o[s] + c0[s]]
        acr.append(across(b, a))
        pw.append(np.linalg.norm(b - a, axis=1))
    acr, pw = np.concatenate(acr) * 1e3, np.concatenate(pw) * 1e3
    pct = lambda d: {p: float(v) for p, v in zip(PERCENTILES, np.percentile(d, PERCENTILES))}  # noqa: E731
    return {"across": pct(acr), "pointwise": pct(pw), "strands": len(picked)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--every", type=int, default=40)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    try:
        m = moves(read_hair(a.before), read_hair(a.after), a.every)
    except (OSError, ValueError) as e:
        print(f"strand_moves: {e}", file=sys.stderr)
        return 1
    if a.json:
        print(json.dumps(m))
    else:
        for k in ("across", "pointwise"):
            print(f"{k:>9} (mm): " + ", ".join(f"{p}th {v:.2f}" for p, v in m[k].items()) + f"  ({m['strands']} strands)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
