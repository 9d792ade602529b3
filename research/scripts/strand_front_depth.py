"""Fusion depth maps of the hair's front layer: the nearest ground-truth strand through each hair pixel.

The renderer fuses the raw mesh from each photo's sample-0 depth: one ray per pixel, which through a porous
layer of hair (the `volume` and `spiky` styles) reaches the scalp about half the time, so the fused surface lies
on the scalp (research/notes/volume-study.md). A photogrammetry mesh follows the strands that give the photos
their texture. Here each hair pixel (mask > 0) takes the depth of the nearest strand point that projects into
it and that the head does not hide (no deeper than the pixel's sample-0 depth plus `--margin`), then the median
of those over a (2r+1)² window (no outward bias on a sloped surface, unlike a low quantile); hair pixels with
no strand point in the window are unknown (-1). Dense hair, whose sample-0 depth is already the front strand's,
keeps nearly the same maps. The ground-truth strands are the renderer's knowledge, as the sample-0 depth is.

    python research/scripts/strand_front_depth.py CAPTURE OUT_DEPTH_DIR [--radius 1] [--step-mm 0.5]
    hairrecon fuse-depth CAPTURE --depth-dir OUT_DEPTH_DIR --voxel-mm 1 --quantile 0.3 --out MESH.ply
"""

import argparse
import json
import warnings
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

import hairrecon


def resample(points: np.ndarray, counts: np.ndarray, step: float) -> np.ndarray:
    """Points along every segment, at most `step` apart (the vertices included)."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    last = np.zeros(len(points), bool)
    last[starts + counts - 1] = True
    a, b = points[:-1][~last[:-1]], points[1:][~last[:-1]]
    n = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / step).astype(int))
    seg = np.repeat(np.arange(len(a)), n)
    t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return np.concatenate([a[seg] + (b[seg] - a[seg]) * t[:, None], points[last]]).astype(np.float32)


def front_depth(pts, K, R, t, depth, mask, margin, r):
    h, w = depth.shape
    cam = pts @ R.T + t
    z = cam[:, 2]
    ok = z > 1e-3
    u = np.floor(K[0, 0] * cam[ok, 0] / z[ok] + K[0, 2] + 0.5).astype(np.int64)
    v = np.floor(K[1, 1] * cam[ok, 1] / z[ok] + K[1, 2] + 0.5).astype(np.int64)
    z = z[ok]
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    u, v, z = u[inside], v[inside], z[inside]
    idx = v * w + u
    d0 = depth.reshape(-1)[idx]
    seen = ~(d0 > 0) | (z <= d0 + margin)  # no surface in the pixel, or not behind what it shows
    zb = np.full(h * w, np.inf, np.float32)
    np.minimum.at(zb, idx[seen], z[seen])
    zb = zb.reshape(h, w)
    zb[~np.isfinite(zb)] = np.nan
    win = sliding_window_view(np.pad(zb, r, constant_values=np.nan), (2 * r + 1, 2 * r + 1)).reshape(h, w, -1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows
        f = np.nanmedian(win, axis=-1)
    out = depth.astype(np.float32).copy()
    out[mask & np.isfinite(f)] = f[mask & np.isfinite(f)]
    out[mask & ~np.isfinite(f)] = -1.0
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--radius", type=int, default=1, help="window half-size in pixels")
    p.add_argument("--step-mm", type=float, default=0.5, help="points along the strands this far apart")
    p.add_argument("--margin-mm", type=float, default=1.0, help="a strand point this far behind the pixel's depth counts")
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    spec = json.loads((a.capture / "capture.json").read_text())
    gt = a.capture / spec.get("gt_strands", "gt/strands.hair")
    points, counts = hairrecon.read_strands(str(gt))
    pts = resample(np.asarray(points, np.float32), np.asarray(counts, np.int64), a.step_mm * 1e-3)
    for v in spec["views"]:
        own = a.capture / "fusion" / "depth" / f"{v['name']}.exr"
        depth = hairrecon.read_exr(str(own if own.is_file() else a.capture / v["gt_depth"]))["R"]
        depth = np.where(depth > 0, depth, 0.0).astype(np.float32)  # the renderer's -1 (unknown) as no depth
        m = hairrecon.read_image(str(a.capture / v["mask"]))
        mask = (m if m.ndim == 2 else m[..., 0]) > 0
        K, R, t = (np.asarray(v[k], np.float32) for k in ("K", "R", "t"))
        e = front_depth(pts, K, R, t, depth, mask, a.margin_mm * 1e-3, a.radius)
        hairrecon.write_image(str(a.out / f"{v['name']}.exr"), np.ascontiguousarray(np.stack([e] * 3, -1)))
    print(f"{len(spec['views'])} depth maps from {len(pts)} strand points -> {a.out}")


if __name__ == "__main__":
    main()
