"""How much strands turn along their length: the angle between successive segments after resampling every
2 mm of arc, median and mean per 4 cm of arc from the root.

Usage: .venv/bin/python scripts/turn_by_arc.py STRANDS.hair [EVERY]

EVERY: take every n-th strand only (default 1; 50 is plenty for 50,000 ground-truth strands). A helix of
radius r and period p per turn along its axis turns 2 mm * r / (r^2 + (p / 2 pi)^2) radians per 2 mm: the
curly preset's ringlets (6.5 mm, 22 mm) 13.7 degrees, steadily; a wiggling strand turns as much or more but
in no steady direction. Needs only numpy.
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _hairio  # noqa: E402

STEP = 0.002
BIN = 0.04


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    every = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    points, counts = _hairio.read_hair(sys.argv[1])
    offsets = _hairio.strand_offsets(counts)
    bins = {}
    for i in range(0, len(counts), every):
        s, length = _hairio.resample_by_arc(points[offsets[i] : offsets[i] + counts[i]].astype(np.float64), STEP)
        if length < 3 * STEP:
            continue
        t = np.diff(s, axis=0)
        t /= np.linalg.norm(t, axis=1, keepdims=True) + 1e-12
        turn = np.degrees(np.arccos(np.clip((t[1:] * t[:-1]).sum(axis=1), -1.0, 1.0)))
        for j, a in enumerate(turn):
            bins.setdefault(min(int(j * STEP / BIN), 7), []).append(a)
    print(f"{sys.argv[1]}: turn per {STEP * 1000:.0f} mm of arc, degrees")
    for b, v in sorted(bins.items()):
        hi = "" if b == 7 else f"{4 * b + 4}"
        print(f"  {4 * b}-{hi} cm: median {np.median(v):.1f}, mean {np.mean(v):.1f} (n {len(v)})")


if __name__ == "__main__":
    main()
