"""Fusion depth maps that see a porous hair layer as its envelope, as a patch-based MVS would.

The synthetic renderer fuses the raw mesh from each photo's sample-0 depth: one ray per pixel, which on hair
that stands off the head (the generator's `volume` style) passes between the strands to the scalp about half
the time, so the fused surface lies on the scalp under the hair (research/notes/volume-study.md). Here each
hair pixel takes instead the q-quantile of the sample-0 depths of the hair pixels in a (2r+1)² window: the
strands in front give a patch its texture. Background pixels keep their depth, hair pixels with no depth in
the window are unknown (-1). It reads the capture's `fusion/depth/` maps where they exist (the renderer crops
the backdrop out of them), else each view's `gt_depth`.

    python research/scripts/envelope_depth.py CAPTURE OUT_DEPTH_DIR [--quantile 0.15] [--radius 3]
    hairrecon fuse-depth CAPTURE --depth-dir OUT_DEPTH_DIR --voxel-mm 1 --truncation-voxels 5 --quantile 0.3 --out MESH.ply
"""

import argparse
import json
import warnings
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

import hairrecon


def envelope_depth(depth: np.ndarray, mask: np.ndarray, q: float, r: int) -> np.ndarray:
    d = np.where(depth > 0, depth, np.nan).astype(np.float32)
    w = sliding_window_view(np.pad(d, r, constant_values=np.nan), (2 * r + 1, 2 * r + 1)).reshape(*d.shape, -1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows: no hair depth near the pixel
        f = np.nanquantile(w, q, axis=-1)
    out = depth.astype(np.float32).copy()
    out[mask & np.isfinite(f)] = f[mask & np.isfinite(f)]
    out[mask & ~np.isfinite(f)] = -1.0
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--quantile", type=float, default=0.15)
    p.add_argument("--radius", type=int, default=3)
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    spec = json.loads((a.capture / "capture.json").read_text())
    for v in spec["views"]:
        # The renderer's own fusion depth maps where they exist (the backdrop cropped away), else the
        # photo's depth.
        own = a.capture / "fusion" / "depth" / f"{v['name']}.exr"
        depth = hairrecon.read_exr(str(own if own.is_file() else a.capture / v["gt_depth"]))["R"]
        m = hairrecon.read_image(str(a.capture / v["mask"]))
        mask = (m if m.ndim == 2 else m[..., 0]) > 0
        e = envelope_depth(depth, mask, a.quantile, a.radius)
        hairrecon.write_image(str(a.out / f"{v['name']}.exr"), np.ascontiguousarray(np.stack([e] * 3, -1)))
    print(f"{len(spec['views'])} depth maps -> {a.out}")


if __name__ == "__main__":
    main()
