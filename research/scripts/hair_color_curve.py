#!/usr/bin/env python3
"""How bright hair with the Principled Hair BSDF's direct colouring C looks in a capture's photos.

    .venv/bin/python scripts/hair_color_curve.py CAPTURE [--views view_000,view_005,view_010]

CAPTURE is a folder written by scripts/render_synthetic.py (it holds the scene.blend it was rendered
from: a uniform white environment of strength 1, the Standard view transform). The hair's material is
switched to direct colouring with a grey C, the views are rendered again with Cycles, and the median
linear value of the pixels the masks cover fully (mask >= 230/255) is printed for each C. The add-on
inverts this table (``core.capture.DIRECT_COLOR_RESPONSE``) to give the reconstructed hair the colour
whose render looks like the photos.

With ``--check`` it tests that inversion instead: the add-on's colour from all the capture's photos and
masks, set as the hair's direct colour, rendered again; it prints the median linear colour of the
fully covered pixels in the photos and in the new renders, and their ratio per channel.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

import addon_core  # noqa: E402
import hairrecon  # noqa: E402

GREYS = [0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.9]


def load_pixels(bpy, path: Path) -> np.ndarray:
    """An image file's pixels as floats (H, W, channels), top row first."""
    im = bpy.data.images.load(str(path), check_existing=False)
    w, h = im.size
    px = np.empty(w * h * im.channels, np.float32)
    im.pixels.foreach_get(px)
    c = im.channels
    bpy.data.images.remove(im)
    return px.reshape(h, w, c)[::-1]


def load_gray(bpy, path: Path) -> np.ndarray:
    return load_pixels(bpy, path)[..., 0]


def render_rgb(bpy, sc, camera: str, out: Path) -> np.ndarray:
    """Linear RGB of the scene rendered from ``camera`` (through an EXR, removed after)."""
    sc.camera = bpy.data.objects[camera]
    sc.render.filepath = str(out)
    bpy.ops.render.render(write_still=True)
    ex = hairrecon.read_exr(str(out))
    out.unlink()
    return np.stack([ex[f"ViewLayer.Combined.{c}"] for c in "RGB"], axis=2)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", type=Path)
    ap.add_argument("--views", default="view_000,view_005,view_010")
    ap.add_argument("--check", action="store_true", help="re-render with the colour the add-on gives these photos")
    a = ap.parse_args(argv)
    import bpy

    core = addon_core.load("capture")
    photos = {}
    if a.check:  # read before the scene replaces bpy.data
        views = []
        for f in sorted((a.capture / "images").glob("*.png")):
            photo = (np.clip(load_pixels(bpy, f)[..., :3], 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
            mask = (np.clip(load_gray(bpy, a.capture / "masks" / f.name), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
            views.append(core.ViewInput(name=f.stem, camera=None, photo=photo, mask=mask[..., None]))
            photos[f.stem] = photo
        seen = core.hair_color(views)
        if seen is None:
            print(f"error: the masks of {a.capture} cover no hair fully", file=sys.stderr)
            return 1
        direct = core.direct_color(seen)
        print(f"hair colour in the photos (linear) {np.round(seen, 4).tolist()} -> direct colour {np.round(direct, 4).tolist()}")

    blend = a.capture / "scene.blend"
    if not blend.is_file():
        print(f"error: {blend} does not exist (a capture of scripts/render_synthetic.py has it)", file=sys.stderr)
        return 1
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    sc = bpy.context.scene
    nodes = [n for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes
             if n.bl_idname == "ShaderNodeBsdfHairPrincipled"]
    if len(nodes) != 1:
        print(f"error: {blend} has {len(nodes)} Principled Hair BSDF nodes, not one", file=sys.stderr)
        return 1
    hb = nodes[0]
    color = next(i for i in hb.inputs if i.name == "Color")
    hb.parametrization = "COLOR"
    names = a.views.split(",")
    # fully covered as the add-on reads it: the mask at 8 bits, at least 230
    masks = {n: np.round(np.clip(load_gray(bpy, a.capture / "masks" / f"{n}.png"), 0.0, 1.0) * 255.0) >= 230
             for n in names}
    (a.capture / "_tmp").mkdir(exist_ok=True)
    if a.check:
        color.default_value = (*direct, 1.0)
        got, want = [], []
        for n in names:
            rgb = render_rgb(bpy, sc, n, a.capture / "_tmp" / f"check_{n}.exr")
            got.append(rgb[masks[n]])
            want.append(core.srgb_to_linear(photos[n][masks[n]].astype(np.float64) / 255.0))
        g, w = np.median(np.concatenate(got), axis=0), np.median(np.concatenate(want), axis=0)
        print(f"photos {np.round(w, 4).tolist()}  rendered {np.round(g.astype(np.float64), 4).tolist()}  ratio {np.round(g / w, 3).tolist()}")
        return 0
    rows = []
    for c in GREYS:
        color.default_value = (c, c, c, 1.0)
        vals = [render_rgb(bpy, sc, n, a.capture / "_tmp" / f"curve_{n}.exr")[..., 1][masks[n]] for n in names]
        rows.append((c, float(np.median(np.concatenate(vals)))))
        print(f"C {c:.3f}: median hair value {rows[-1][1]:.4f}", flush=True)
    print("DIRECT_COLOR_RESPONSE = (" + ", ".join(f"({c:g}, {v:.4f})" for c, v in rows) + ")")
    return 0


if __name__ == "__main__":
    sys.exit(main())
