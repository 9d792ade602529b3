"""Attaching strands to a scalp surface: UV maps and barycentric interpolation (numpy only).

Blender's hair tools and the "Attach Hair Curves to Surface" node find each curve's root on its
surface mesh through a UV coordinate (the ``surface_uv_coordinate`` attribute) in the surface's UV
map. The Blender layer finds the closest surface point of each root (mathutils BVHTree); this module
turns that point and its triangle into a UV, and makes a UV map for a scalp that has none.
"""

from __future__ import annotations

import numpy as np


def barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric weights (N, 3) of points p (N, 3) in triangles (a, b, c) (each (N, 3)); points off
    the plane are projected onto it. Degenerate triangles give (1, 0, 0)."""
    v0, v1, v2 = b - a, c - a, p - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    den = d00 * d11 - d01 * d01
    ok = np.abs(den) > 1e-30
    safe = np.where(ok, den, 1.0)
    v = np.where(ok, (d11 * d20 - d01 * d21) / safe, 0.0)
    w = np.where(ok, (d00 * d21 - d01 * d20) / safe, 0.0)
    return np.stack([1.0 - v - w, v, w], axis=1)


def interpolate_uv(points: np.ndarray, tri_corners: np.ndarray, tri_uvs: np.ndarray) -> np.ndarray:
    """UVs (N, 2) of points (N, 3) lying on triangles with corners (N, 3, 3) and corner UVs (N, 3, 2)."""
    w = barycentric(points, tri_corners[:, 0], tri_corners[:, 1], tri_corners[:, 2])
    w = np.clip(w, 0.0, None)
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-30)
    return np.einsum("nk,nkj->nj", w, tri_uvs)


def fit_sphere(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares sphere (centre, radius) through points (N, 3), N >= 4 not coplanar."""
    p = np.asarray(points, dtype=np.float64)
    A = np.concatenate([2.0 * p, np.ones((len(p), 1))], axis=1)
    b = (p * p).sum(axis=1)
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    centre = x[:3]
    r2 = x[3] + centre @ centre
    return centre, float(np.sqrt(max(r2, 0.0)))


def azimuthal_uv(points: np.ndarray, centre: np.ndarray, pole: np.ndarray, return_theta: bool = False):
    """A seamless UV map of a scalp-like cap: the azimuthal equidistant projection of each point's
    direction from ``centre`` about ``pole`` (unit vector through the top of the cap). The pole maps
    to (0.5, 0.5); a direction at angle theta from the pole lies at radius theta / (2 pi), so the whole
    sphere fits in [0, 1]^2 and a cap smaller than a hemisphere sits within radius 0.25."""
    pole = np.asarray(pole, dtype=np.float64)
    pole = pole / np.linalg.norm(pole)
    ref = np.array([1.0, 0.0, 0.0]) if abs(pole[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = ref - pole * (ref @ pole)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(pole, e1)
    d = np.asarray(points, dtype=np.float64) - centre
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    theta = np.arccos(np.clip(d @ pole, -1.0, 1.0))
    phi = np.arctan2(d @ e2, d @ e1)
    r = theta / (2.0 * np.pi)
    uv = np.stack([0.5 + r * np.cos(phi), 0.5 + r * np.sin(phi)], axis=1).astype(np.float32)
    return (uv, theta) if return_theta else uv


def scalp_uv(points: np.ndarray, scalp: np.ndarray | None = None, return_theta: bool = False):
    """UVs (N, 2) for vertices without a UV map: a sphere fitted to the scalp vertices (``scalp``,
    default all points), projected about the pole through the scalp's mean. Points outside the scalp
    (the rest of a head mesh) get distinct UVs too, farther from the centre."""
    p = np.asarray(points if scalp is None else scalp, dtype=np.float64)
    if len(p) >= 4:
        centre, _ = fit_sphere(p)
    else:
        centre = p.mean(axis=0) - np.array([0.0, 0.0, 0.1])
    pole = p.mean(axis=0) - centre
    if not np.all(np.isfinite(pole)) or np.linalg.norm(pole) < 1e-9:
        pole = np.array([0.0, 0.0, 1.0])
    return azimuthal_uv(np.asarray(points, dtype=np.float64), centre, pole, return_theta)


# where faces off the scalp put their UVs: outside the disk that holds every face within
# FOLD_ANGLE of the pole, as zero-area UV triangles that contain no other UV; faces reaching
# beyond FOLD_ANGLE (around the pole's antipode, where the projection wraps) are parked too
FOLD_ANGLE = np.deg2rad(170.0)
PARKED_UV = (0.98, 0.98)


def loop_uvs(points: np.ndarray, in_scalp: np.ndarray, loop_vertex: np.ndarray, loop_face: np.ndarray) -> np.ndarray:
    """Per-loop UVs (L, 2) of a mesh (points (V, 3), loop_vertex (L,), loop_face (L,)) by
    :func:`scalp_uv` about the scalp vertices (``in_scalp``, bool (V,)).

    Blender's hair attachment finds a curve's triangle from its UV, so the map must not overlap
    itself. A radial projection overlaps wherever the surface folds back as seen from the head's
    centre (ears, eyelids, lips, the neck near the pole's antipode), so only faces touching the
    scalp keep their projected UVs; every other face, and any face reaching beyond FOLD_ANGLE from
    the pole, gets all its loops parked at PARKED_UV (zero-area UV triangles, outside the disk)."""
    uv_v, theta = scalp_uv(points, points[in_scalp], return_theta=True)
    nfaces = int(loop_face.max()) + 1 if len(loop_face) else 0
    far = np.zeros(nfaces, bool)
    np.logical_or.at(far, loop_face, theta[loop_vertex] > FOLD_ANGLE)
    touches = np.zeros(nfaces, bool)
    np.logical_or.at(touches, loop_face, in_scalp[loop_vertex])
    bad = far | ~touches
    uv = uv_v[loop_vertex].copy()
    uv[bad[loop_face]] = PARKED_UV
    return uv
