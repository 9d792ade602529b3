"""A study tool for the curly init: how precise are strands traced through directed 3D points alone?

Traces one strand from the start of every strand of GUIDES (its first SKIP points are kept, then it
steps STEP metres at a time along the confidence-free weighted mean direction of the directed points
within R metres of it whose tangent is within acos(MINCOS) of its own, weighted by cos^POW and by
1 - d²/R²; no flow field, no outer surface, no gravity), ends it after 10 steps without such points,
writes the traced strands to OUT (.hair), and prints their undirected precision against GT at
2 mm/20° (every strand resampled every 1 mm; pooled over all samples) per band of arc length.

    .venv/bin/python scripts/trace_points.py POINTS.ply GUIDES.hair OUT.hair GT.hair [r=0.002]
        [step=0.001] [mincos=0.5] [pow=4] [skip=3] [maxlen=0.6]

POINTS.ply: `points_directed.ply` of a `hairrecon reconstruct` run, or the ground-truth oracle of
`examples/oracle_points … all`. Needs numpy and scipy (both in the project's virtual env).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _hairio  # noqa: E402


def resampled(path, step=0.001):
    """Every strand resampled every `step` metres: points, unit tangents, arc length from the root."""
    pts, counts = _hairio.read_hair(path)
    off = _hairio.strand_offsets(counts)
    P, T, A = [], [], []
    for i in range(len(counts)):
        r, _ = _hairio.resample_by_arc(pts[off[i] : off[i + 1]].astype(np.float64), step)
        if len(r) == 0:
            continue
        g = np.gradient(r, axis=0) if len(r) > 1 else np.zeros_like(r)
        g /= np.linalg.norm(g, axis=1, keepdims=True) + 1e-12
        P.append(r)
        T.append(g)
        A.append(np.arange(len(r)) * step)
    return np.concatenate(P), np.concatenate(T), np.concatenate(A)


def trace(X, T, tree, starts, r, step, mincos, power, maxlen):
    """All strands step together; `starts`: per strand the kept first points (at least two)."""
    paths = [list(s) for s in starts]
    P = np.array([s[-1] for s in starts])
    D = np.array([s[-1] - s[-2] for s in starts])
    D /= np.linalg.norm(D, axis=1, keepdims=True) + 1e-12
    alive = np.ones(len(starts), bool)
    miss = np.zeros(len(starts), int)
    for _ in range(int(maxlen / step)):
        idx = np.flatnonzero(alive)
        if len(idx) == 0:
            break
        for i, near in zip(idx, tree.query_ball_point(P[idx], r)):
            d = D[i]
            found = False
            if near:
                t = T[near]
                c = t @ d
                m = c > mincos
                if m.any():
                    o = X[near][m] - P[i]
                    w = c[m] ** power * np.maximum(0.0, 1.0 - (o * o).sum(1) / (r * r))
                    if w.sum() > 1e-9:
                        nd = (t[m] * w[:, None]).sum(0)
                        d = nd / np.linalg.norm(nd)
                        found = True
            miss[i] = 0 if found else miss[i] + 1
            if miss[i] > 10:
                alive[i] = False
                continue
            D[i] = d
            P[i] = P[i] + step * d
            paths[i].append(P[i].copy())
    return paths


def main(argv):
    if len(argv) < 4:
        raise SystemExit(__doc__)
    points, guides, out, gt = argv[:4]
    opt = {"r": 0.002, "step": 0.001, "mincos": 0.5, "pow": 4.0, "skip": 3, "maxlen": 0.6}
    for kv in argv[4:]:
        k, _, v = kv.partition("=")
        if k not in opt:
            raise SystemExit(f"unknown key {k!r}; keys: {', '.join(opt)}")
        opt[k] = float(v)
    try:
        X, T = _hairio.read_oriented_points(points)
    except ValueError as e:
        raise SystemExit(str(e)) from None
    gpts, gc = _hairio.read_hair(guides)
    off = _hairio.strand_offsets(gc)
    skip = int(opt["skip"])
    starts = [
        gpts[off[i] : off[i] + max(2, min(skip, gc[i] - 1) + 1)].astype(np.float64)
        for i in range(len(gc))
        if gc[i] >= 2
    ]
    paths = trace(X, T, cKDTree(X), starts, opt["r"], opt["step"], opt["mincos"], opt["pow"], opt["maxlen"])
    counts = np.array([len(p) for p in paths])
    _hairio.write_hair(out, np.concatenate([np.asarray(p, np.float32) for p in paths]), counts)
    lengths = (counts - 1) * opt["step"]
    print(f"{len(paths)} strands, mean length {lengths.mean():.3f} m -> {out}")

    gp, gtan, _ = resampled(gt)
    gtree = cKDTree(gp)
    P, Tp, A = resampled(out)
    cos20 = np.cos(np.radians(20))
    ok = np.array(
        [bool(l) and bool((np.abs(gtan[l] @ Tp[i]) >= cos20).any()) for i, l in enumerate(gtree.query_ball_point(P, 0.002))]
    )
    print(f"undirected precision at 2 mm/20 deg: {100 * ok.mean():.1f}% of {len(P)} samples")
    for a, b in [(0, 2), (2, 5), (5, 10), (10, 20), (20, 30), (30, 40), (40, 60)]:
        m = (A * 100 >= a) & (A * 100 < b)
        if m.any():
            print(f"  arc {a:>2}-{b:<2} cm: {100 * m.mean():5.1f}% of samples, {100 * ok[m].mean():5.1f}% precise")


if __name__ == "__main__":
    main(sys.argv[1:])
