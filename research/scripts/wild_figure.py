#!/usr/bin/env python3
"""A view of a capture beside the strands reconstructed from it, drawn from the same camera over the
fitted head (the README's picture of a photogrammetry project).

    .venv/bin/python research/scripts/wild_figure.py CAPTURE OUT VIEW PICTURE.png [--strands N]

CAPTURE is the imported capture (its capture.json gives the view's camera and photo); OUT the
`hairrecon reconstruct` output folder (`strands.hair` and `fitted_head.ply`, both in the capture's frame).
The head is drawn flat-shaded with a z-buffer, and each strand segment only where it lies in front of
the head; the strands run dark at the root to light at the tip. A picture, not a measurement.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import hairrecon
import numpy as np
from PIL import Image, ImageDraw

SCALE = 3  # the drawing's pixels per photo pixel


def camera(capture: Path, view: str):
    spec = json.loads((capture / "capture.json").read_text())
    v = next((x for x in spec["views"] if x["name"] == view), None)
    if v is None:
        raise SystemExit(f"{capture}: no view named {view}")
    return v, np.array(v["K"]), np.array(v["R"]), np.array(v["t"])


def project(points, K, R, t):
    cam = points @ R.T + t
    uv = cam @ K.T
    return uv[:, :2] / uv[:, 2:3] * SCALE, cam[:, 2]


def head_depth(mesh, K, R, t, w, h):
    """The head's depth per pixel (inf where it is absent) and its flat shading."""
    v = np.asarray(mesh["vertices"], dtype=float)
    tri = np.asarray(mesh["triangles"], dtype=np.int64)
    uv, z = project(v, K, R, t)
    cam = v @ R.T + t
    depth = np.full((h, w), np.inf)
    shade = np.zeros((h, w))
    for a, b, c in tri:
        p = uv[[a, b, c]]
        n = np.cross(cam[b] - cam[a], cam[c] - cam[a])
        n /= np.linalg.norm(n) + 1e-12
        x0, y0 = np.floor(p.min(0)).astype(int)
        x1, y1 = np.ceil(p.max(0)).astype(int)
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w - 1), min(y1, h - 1)
        if x0 > x1 or y0 > y1:
            continue
        xs, ys = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
        d = (p[1, 1] - p[2, 1]) * (p[0, 0] - p[2, 0]) + (p[2, 0] - p[1, 0]) * (p[0, 1] - p[2, 1])
        if abs(d) < 1e-12:
            continue
        l0 = ((p[1, 1] - p[2, 1]) * (xs - p[2, 0]) + (p[2, 0] - p[1, 0]) * (ys - p[2, 1])) / d
        l1 = ((p[2, 1] - p[0, 1]) * (xs - p[2, 0]) + (p[0, 0] - p[2, 0]) * (ys - p[2, 1])) / d
        l2 = 1 - l0 - l1
        inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0)
        zz = l0 * z[a] + l1 * z[b] + l2 * z[c]
        region = depth[y0 : y1 + 1, x0 : x1 + 1]
        nearer = inside & (zz < region)
        region[nearer] = zz[nearer]
        shade[y0 : y1 + 1, x0 : x1 + 1][nearer] = abs(n[2])
    return depth, shade


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("view")
    ap.add_argument("picture", type=Path)
    ap.add_argument("--strands", type=int, default=15000, help="strands drawn (a seeded sample)")
    a = ap.parse_args()
    v, K, R, t = camera(a.capture, a.view)
    w, h = v["width"] * SCALE, v["height"] * SCALE
    depth, shade = head_depth(hairrecon.read_mesh(str(a.out / "fitted_head.ply")), K, R, t, w, h)
    img = np.full((h, w, 3), 236.0)
    skin = np.array([232.0, 200.0, 180.0])
    on = np.isfinite(depth)
    img[on] = skin * (0.45 + 0.55 * shade[on, None])
    canvas = Image.fromarray(img.astype(np.uint8))
    draw = ImageDraw.Draw(canvas)
    pts, counts = hairrecon.read_strands(str(a.out / "strands.hair"))
    pts = np.asarray(pts, dtype=float)
    counts = np.asarray(counts).astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    uv, z = project(pts, K, R, t)
    order = np.random.default_rng(0).permutation(len(counts))[: a.strands]
    far_first = order[np.argsort([-z[starts[i] : starts[i] + counts[i]].mean() for i in order])]
    root, tip = np.array([60.0, 35.0, 18.0]), np.array([185.0, 135.0, 85.0])
    for i in far_first:
        s, n = starts[i], counts[i]
        for j in range(n - 1):
            m = (uv[s + j] + uv[s + j + 1]) / 2
            x, y = int(m[0]), int(m[1])
            if 0 <= x < w and 0 <= y < h and (z[s + j] + z[s + j + 1]) / 2 > depth[y, x]:
                continue  # behind the head
            k = j / max(n - 2, 1)
            c = tuple(int(q) for q in root * (1 - k) + tip * k)
            draw.line([tuple(uv[s + j]), tuple(uv[s + j + 1])], fill=c, width=1)
    photo = Image.open(a.capture / v["image"]).convert("RGB").resize((w, h), Image.LANCZOS)
    fig = Image.new("RGB", (2 * w + 12, h), (255, 255, 255))
    fig.paste(photo, (0, 0))
    fig.paste(canvas, (w + 12, 0))
    fig.resize((fig.width // 2, fig.height // 2), Image.LANCZOS).save(a.picture, quality=90)
    print(f"{a.picture}: view {a.view}, {len(order)} of {len(counts)} strands")


if __name__ == "__main__":
    main()
