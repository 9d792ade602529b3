"""A toy head and toy hair in numpy, for developing and testing the renderer without the Rust
generator (``hairrecon synth-hair``), which is the real source of benchmark hair.

- :func:`fixture_head` turns the raw head of Cem Yuksel's models (``woman_head.ply``: Y down, face
  along +X, arbitrary units) into the project's frame: metres, Z up, face toward -Y, 0.155 m wide.
- :func:`toy_hair` grows strands from the top of the head: out along the normal, then falling under
  a gravity-like pull, kept outside an ellipsoid around the head.
"""

from __future__ import annotations

import numpy as np

HEAD_WIDTH_M = 0.155


def fixture_head(vertices: np.ndarray) -> np.ndarray:
    """Maps the raw head's vertices to the fixture frame: new = (z, -x, -y) * s, s = 0.155 m / width."""
    v = np.asarray(vertices, np.float64)
    new = np.stack([v[:, 2], -v[:, 0], -v[:, 1]], axis=1)
    s = HEAD_WIDTH_M / (new[:, 0].max() - new[:, 0].min())
    return new * s


def toy_hair(vertices: np.ndarray, triangles: np.ndarray, n: int, seed: int = 0, points: int = 32):
    """Returns (points float32 (n*points, 3), counts) of n strands rooted on the top of the head."""
    rng = np.random.default_rng(seed)
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2 * area[:, None], 1e-12)
    centre = 0.5 * (v.min(0) + v.max(0))
    lo, hi = v.min(0), v.max(0)
    cent = (a + b + c) / 3
    # Scalp: the upper part of the head, away from the face (the face looks toward -Y).
    rel = (cent - centre) / (0.5 * (hi - lo))
    scalp = (rel[:, 2] > 0.15) & ~((rel[:, 1] < -0.55) & (rel[:, 2] < 0.55)) & (normal[:, 2] > -0.2)
    idx = np.flatnonzero(scalp)
    tri = rng.choice(idx, size=n, p=area[idx] / area[idx].sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    roots = (1 - s)[:, None] * a[tri] + (s * (1 - r2))[:, None] * b[tri] + (s * r2)[:, None] * c[tri]
    nrm = normal[tri]
    semi = 0.5 * (hi - lo) + 0.004  # keep strands 4 mm outside the head's bounding ellipsoid
    length = rng.uniform(0.12, 0.2, n)
    step = length / (points - 1)
    pts = np.zeros((n, points, 3))
    pts[:, 0] = roots
    d = nrm.copy()
    down = np.array([0.0, 0.0, -1.0])
    for k in range(1, points):
        w = min(1.0, 0.15 * k)
        d = (1 - w) * nrm + w * (down + 0.35 * (roots - centre) * [1, 1, 0] / 0.08)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        p = pts[:, k - 1] + step[:, None] * d
        q = (p - centre) / semi
        r = np.linalg.norm(q, axis=1)
        inside = r < 1.0
        if k > 1 and inside.any():
            p[inside] = centre + q[inside] / r[inside, None] * semi
        pts[:, k] = p
    counts = np.full(n, points, np.int64)
    return pts.reshape(-1, 3).astype(np.float32), counts
