"""How often the directed 3D points' signs agree with the ground truth, per band of height.

Usage: .venv/bin/python scripts/direction_by_height.py OUT/points_directed.ply CAPTURE/gt/strands.hair [BAND_M]

A point is judged when some ground-truth point within 3 mm runs parallel to it (within 30 degrees, undirected,
among the 8 nearest); it agrees when most of those run its way. Prints the share overall and per band of height
(z, metres, the capture's frame: z up), top ten bands. Needs scipy (`.venv/bin/pip install scipy`; not part of the
test environment).
"""

import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import hairrecon

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _hairio  # noqa: E402


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    band = float(sys.argv[3]) if len(sys.argv) > 3 else 0.03
    try:
        pos, tan = _hairio.read_oriented_points(sys.argv[1])
    except ValueError as e:
        sys.exit(str(e))
    g, cnt = hairrecon.read_strands(sys.argv[2])
    g = np.asarray(g, np.float64)
    off = np.concatenate([[0], np.cumsum(np.asarray(cnt).astype(np.int64))])
    gt = np.zeros_like(g)
    for a, b in zip(off[:-1], off[1:]):
        t = np.gradient(g[a:b], axis=0) if b - a > 1 else np.zeros((b - a, 3))
        gt[a:b] = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    _, idx = cKDTree(g).query(pos, k=8, distance_upper_bound=0.003)
    agree, zs = [], []
    cos30 = np.cos(np.radians(30))
    for j in range(len(pos)):
        ok = idx[j] < len(g)
        if not ok.any():
            continue
        c = gt[idx[j][ok]] @ tan[j]
        m = np.abs(c) > cos30
        if m.any():
            agree.append((c[m] > 0).mean() > 0.5)
            zs.append(pos[j, 2])
    agree, zs = np.array(agree), np.array(zs)
    print(f"judged {len(agree)} of {len(pos)} points: {agree.mean() * 100:.1f}% agree")
    top = zs.max()
    for lo in np.arange(top - 10 * band, top, band):
        m = (zs >= lo) & (zs < lo + band)
        if m.sum():
            print(f"z {lo:+.3f} .. {lo + band:+.3f} m: {m.sum():7d} points, {agree[m].mean() * 100:5.1f}% agree")


if __name__ == "__main__":
    main()
