#!/usr/bin/env python3
"""A crop of one view: the photo, the ground truth's 2D orientation and the Gabor maps', side by side.

    .venv/bin/python scripts/orient_crop.py CAPTURE ORIENT2D VIEW OUT.png Y0 Y1 X0 X1

CAPTURE a synthetic capture folder (with `gt/orientation`), ORIENT2D a `hairrecon reconstruct` output's
`orient2d/`, VIEW a view's name (e.g. view_034), the crop rows Y0:Y1 and columns X0:X1 in pixels (top
row first), each panel enlarged 3 times. Orientation as hue (θ from 0 to 180°: red, yellow, green, cyan
at 90°, i.e. along the image's columns, blue, magenta), brightness the confidence. Uses the bpy module.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from orient_by_region import load_exr  # any image bpy reads, (H, W, C) top row first


def hue(a: np.ndarray) -> np.ndarray:
    """RGBA picture of a map stored as (cos 2θ, sin 2θ, confidence): hue = θ, brightness = confidence."""
    th = (0.5 * np.arctan2(a[..., 1], a[..., 0])) % np.pi / np.pi
    v = np.clip(a[..., 2], 0, 1)
    i = np.floor(th * 6).astype(int) % 6
    f = th * 6 - np.floor(th * 6)
    o, z = np.ones_like(th), np.zeros_like(th)
    r = np.choose(i, [o, 1 - f, z, z, f, o])
    g = np.choose(i, [f, o, o, 1 - f, z, z])
    b = np.choose(i, [z, z, f, o, o, 1 - f])
    return np.stack([r * v, g * v, b * v, o], -1)


def main() -> None:
    if len(sys.argv) != 9:
        sys.exit(__doc__.split("\n\n")[1])
    cap, o2d, name, out = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3], sys.argv[4]
    y0, y1, x0, x1 = (int(v) for v in sys.argv[5:9])
    import bpy

    photo = load_exr(bpy, cap / "images" / f"{name}.png")
    if photo.shape[2] == 3:
        photo = np.concatenate([photo, np.ones(photo.shape[:2] + (1,), np.float32)], -1)
    panels = [photo, hue(load_exr(bpy, cap / "gt" / "orientation" / f"{name}.exr")),
              hue(load_exr(bpy, o2d / f"{name}.exr"))]
    tiles = [np.kron(p[y0:y1, x0:x1], np.ones((3, 3, 1), np.float32)) for p in panels]
    gap = np.ones((tiles[0].shape[0], 6, 4), np.float32)
    pic = np.concatenate([tiles[0], gap, tiles[1], gap, tiles[2]], 1)
    im = bpy.data.images.new("orient crop", pic.shape[1], pic.shape[0], alpha=True)
    im.pixels.foreach_set(np.ascontiguousarray(pic[::-1]).ravel())
    im.filepath_raw = out
    im.file_format = "PNG"
    im.save()


if __name__ == "__main__":
    main()
