#!/usr/bin/env python3
"""The 2D orientation maps' error over one region of the hair against the capture's ground truth.

    .venv/bin/python scripts/orient_by_region.py CAPTURE ORIENT2D GT.hair [--box XMIN XMAX YMIN YMAX ZMIN ZMAX]

CAPTURE a synthetic capture folder (with `gt/orientation`), ORIENT2D a folder of maps named after its
views (a `hairrecon reconstruct` output's `orient2d/`), GT.hair the ground-truth strands. The region
is the ground-truth points inside the box (metres; by default the front of the crown: |x| < 3 cm,
y < 3 cm, z > 14 cm on the bundled head). Per view it prints the mean undirected angle between the
maps and `gt/orientation` over the pixels where the view sees those points (within 3 mm of `gt/depth`;
where both maps have confidence) and over all hair pixels, then the means over the views, and over the
views grouped by elevation; 45° is what maps of random angles would score.
Reads EXR through the bpy module.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def load_exr(bpy, path: Path) -> np.ndarray:
    """(H, W, C) float32, top row first."""
    img = bpy.data.images.load(str(path))
    try:
        w, h = img.size
        px = np.empty(w * h * img.channels, np.float32)
        img.pixels.foreach_get(px)
        return px.reshape(h, w, img.channels)[::-1]
    finally:
        bpy.data.images.remove(img)


def angle_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Undirected angle in degrees between maps stored as (cos 2θ, sin 2θ, ...) rows."""
    ta = 0.5 * np.arctan2(a[:, 1], a[:, 0])
    tb = 0.5 * np.arctan2(b[:, 1], b[:, 0])
    return np.degrees(np.abs((ta - tb + np.pi / 2) % np.pi - np.pi / 2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", type=Path)
    ap.add_argument("orient2d", type=Path)
    ap.add_argument("gt", type=Path)
    ap.add_argument("--box", type=float, nargs=6, default=[-0.03, 0.03, -1.0, 0.03, 0.14, 1.0],
                    metavar=("XMIN", "XMAX", "YMIN", "YMAX", "ZMIN", "ZMAX"))
    a = ap.parse_args()
    import bpy
    import hairrecon

    spec = json.loads((a.capture / "capture.json").read_text())
    points, _ = hairrecon.read_strands(str(a.gt))
    p = np.asarray(points, np.float64).reshape(-1, 3)
    lo, hi = np.array(a.box[0::2]), np.array(a.box[1::2])
    region = p[np.all((p >= lo) & (p <= hi), axis=1)]
    print(f"{len(region)} ground-truth points in the box")
    region_err, all_err, elevation, conf = [], [], [], []
    for v in spec["views"]:
        gt = load_exr(bpy, a.capture / v["gt_orientation"])
        depth = load_exr(bpy, a.capture / v["gt_depth"])[..., 0]
        ours = load_exr(bpy, a.orient2d / f"{v['name']}.exr")
        h, w = gt.shape[:2]
        K, R, t = (np.array(v[k], np.float64) for k in ("K", "R", "t"))
        cam = region @ R.T + t
        front = cam[:, 2] > 0
        uv = cam[front] @ K.T
        px = np.round(uv[:, :2] / uv[:, 2:]).astype(np.int64)  # pixel centres at integer coordinates
        inside = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
        at = px[inside, 1] * w + px[inside, 0]
        seen = np.abs(cam[front][inside, 2] - depth.reshape(-1)[at]) < 0.003
        idx = np.unique(at[seen])
        g, o = gt.reshape(h * w, -1), ours.reshape(h * w, -1)
        both = (g[:, 2] > 0.5) & (o[:, 2] > 0)
        sel = idx[both[idx]]
        e_region = angle_error(g[sel], o[sel]).mean() if len(sel) else float("nan")
        e_all = angle_error(g[both], o[both]).mean()
        c_region = o[sel, 2].mean() if len(sel) else float("nan")
        c_all = o[both, 2].mean()
        conf.append(c_region)
        region_err.append(e_region)
        all_err.append(e_all)
        centre = -R.T @ t
        elevation.append(np.degrees(np.arcsin(centre[2] / np.linalg.norm(centre))))
        print(f"{v['name']}: elevation {elevation[-1]:5.1f}°, region {e_region:5.1f}° over {len(sel)} px "
              f"(confidence {c_region:.2f}), all hair {e_all:5.1f}° ({c_all:.2f})")
    print(f"mean over the views: region {np.nanmean(region_err):.1f}°, all hair {np.mean(all_err):.1f}°")
    elevation, region_err, conf = np.array(elevation), np.array(region_err), np.array(conf)
    for lo, hi in ((-90, 30), (30, 60), (60, 90)):
        sel = (elevation >= lo) & (elevation < hi) & np.isfinite(region_err)
        if sel.any():
            print(f"views at elevation {lo}–{hi}°: region {region_err[sel].mean():.1f}°, confidence "
                  f"{conf[sel].mean():.2f} ({sel.sum()} views)")


if __name__ == "__main__":
    main()
