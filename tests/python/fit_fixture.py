"""A capture as an import leaves it, for the head-fit tests (as rust/cli/tests/fit_head_cli.rs makes it):
the bundled head moved into another frame by a similarity (scale 40, turned, offset) as the raw mesh,
four cameras 0.6 m (canonical) around it looking at it, no head and no scalp. ``raw="sphere"`` puts a
sphere of a head's size there instead: nothing to fit. ``raw="shell"`` adds a hair shell to the head (the
scalp pushed 8 mm outward, as rust/cli/tests/masks_cli.rs makes it): a raw mesh of a head with its hair;
with ``photos="render"`` and more views, photos of it that a reconstruction can use (the add-on's
COLMAP flow test: colmap_fixture.colmap_from_capture makes a COLMAP project of the capture).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
SCALE = 40.0


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


ROTATION = _rx(1.1) @ _rz(2.3)
OFFSET = np.array([3.0, -7.0, 11.0])


def to_capture(points: np.ndarray) -> np.ndarray:
    """Canonical metres -> the capture's frame."""
    return (SCALE * (np.asarray(points, np.float64) @ ROTATION.T) + OFFSET).astype(np.float32)


def sphere(radius: float, rings: int = 24, segments: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """A UV sphere about the origin: vertices (N, 3), triangles (M, 3)."""
    th = np.linspace(0, np.pi, rings + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    v = np.vstack([[0, 0, 1], v, [0, 0, -1]]) * radius
    tris = []
    idx = lambda r, s: 1 + r * segments + s % segments  # noqa: E731
    for s in range(segments):
        tris.append([0, idx(0, s), idx(0, s + 1)])
        last = len(v) - 1
        tris.append([last, idx(rings - 2, s + 1), idx(rings - 2, s)])
        for r in range(rings - 2):
            tris.append([idx(r, s), idx(r + 1, s), idx(r + 1, s + 1)])
            tris.append([idx(r, s), idx(r + 1, s + 1), idx(r, s + 1)])
    return v, np.array(tris, np.uint32)


def vertex_normals(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh (the triangles' winding decides the side)."""
    v = np.asarray(v, np.float64)
    t = np.asarray(t, np.int64)
    fn = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, t[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def hair_shell(head: dict, scalp: dict, offset: float = 0.008) -> tuple[np.ndarray, np.ndarray]:
    """The head and its hair shell (the scalp pushed ``offset`` metres outward) in one mesh, canonical metres."""
    sv = np.asarray(scalp["vertices"], np.float64)
    n = vertex_normals(sv, scalp["triangles"])
    # outward: away from the head's centre, whatever the scalp's winding
    if np.mean(np.sum(n * (sv - np.asarray(head["vertices"], np.float64).mean(axis=0)), axis=1)) < 0:
        n = -n
    v = np.vstack([np.asarray(head["vertices"], np.float64), sv + offset * n])
    t = np.vstack([np.asarray(head["triangles"], np.int64), np.asarray(scalp["triangles"], np.int64) + len(head["vertices"])])
    return v, t.astype(np.uint32)


def _hash(i: np.ndarray, k: int) -> np.ndarray:
    """A value in [0, 1) per integer (the texture's noise)."""
    h = (np.asarray(i, np.int64) * 0x9E3779B1 + k * 0x85EBCA77) & 0xFFFFFFFF
    h ^= h >> 15
    h = (h * 0x2C1B3C6D) & 0xFFFFFFFF
    h ^= h >> 12
    return (h & 0xFFFF) / 65536.0


def surface_samples(v: np.ndarray, t: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points on every triangle, at most ``spacing`` apart along its edges: (points (N, 3), triangle (N,))."""
    v = np.asarray(v, np.float64)
    t = np.asarray(t, np.int64)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)], axis=0)
    levels = np.maximum(np.ceil(longest / spacing), 1).astype(int)
    pts, tri = [], []
    for n in np.unique(levels):
        sel = np.flatnonzero(levels == n)
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        u, w = i[keep] / n, j[keep] / n  # barycentric weights of b and c
        p = a[sel, None] + u[None, :, None] * (b[sel] - a[sel])[:, None] + w[None, :, None] * (c[sel] - a[sel])[:, None]
        pts.append(p.reshape(-1, 3))
        tri.append(np.repeat(sel, len(u)))
    return np.concatenate(pts), np.concatenate(tri)


def render_photo(view: dict, points: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """A photo of coloured surface points (the capture's frame) through an OpenCV view: each pixel takes
    the nearest point that lands in it, the backdrop (a grey and green checker) where none does."""
    w, h = view["width"], view["height"]
    K, R, t = (np.asarray(view[k], np.float64) for k in ("K", "R", "t"))
    cam = points @ R.T + t
    z = cam[:, 2]
    uv = cam[:, :2] / np.maximum(z, 1e-9)[:, None] @ K[:2, :2].T + K[:2, 2]
    px = np.floor(uv + 0.5).astype(np.int64)  # pixel centres at integers (hairrecon's convention)
    ok = (z > 0) & (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
    idx = (px[ok, 1] * w + px[ok, 0])
    order = np.lexsort((z[ok], idx))
    first = order[np.r_[True, idx[order][1:] != idx[order][:-1]]]
    y, x = np.mgrid[0:h, 0:w]
    check = ((x // 8 + y // 8) % 2 == 0)[..., None]
    noise = _hash(y * w + x, 7)[..., None]
    img = np.where(check, [0.2, 0.45, 0.2], [0.55, 0.55, 0.5]) + 0.1 * (noise - 0.5)
    img = img.reshape(-1, 3)
    img[idx[first]] = colours[ok][first]
    return (np.clip(img, 0, 1).reshape(h, w, 3) * 255 + 0.5).astype(np.uint8)


def hair_photos(v: np.ndarray, t: np.ndarray, hair: np.ndarray, spacing: float):
    """Colours of the raw mesh (canonical metres) for photos: the triangles ``hair`` marks are brown hair
    combed straight down from the crown (strands of random lightness along the meridians about the
    vertical axis, so every view sees the same strands), the others skin. Returns the points in the
    capture's frame and their colours, for :func:`render_photo`; ``spacing`` (metres) must be below
    the pixel's size on the surface."""
    p, tri = surface_samples(v, t, spacing)
    vv = np.asarray(v, np.float64)
    tt = np.asarray(t, np.int64)
    fn = np.cross(vv[tt[:, 1]] - vv[tt[:, 0]], vv[tt[:, 2]] - vv[tt[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-30)
    # a light from above and in front, on both sides of a face
    shade = 0.55 + 0.45 * np.abs(fn[tri] @ (np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])))
    azimuth = np.arctan2(p[:, 1], p[:, 0])
    strand = np.floor((azimuth + np.pi) / 0.012).astype(np.int64)  # about 1.2 mm apart at the temples
    lightness = 0.35 + 1.0 * _hash(strand, 1) * (0.8 + 0.2 * _hash(np.floor(p[:, 2] / 0.01).astype(np.int64) * 7919 + strand, 2))
    brown = np.array([0.32, 0.2, 0.11])[None] * lightness[:, None]
    skin = np.array([0.85, 0.66, 0.58])[None] * np.ones((len(p), 1))
    colours = np.where(hair[tri][:, None], brown, skin) * shade[:, None]
    return to_capture(p).astype(np.float64), colours


def write_capture(hairrecon, d: Path, raw: str = "head", photos: bool | str = False, views: int = 4,
                  lift: float = 0.0, height: int = 600) -> dict:
    """Writes the capture into ``d``; returns the true scalp in the capture's frame
    ``{"scalp": (vertices, triangles)}``. ``photos=True`` writes a black photo per view (for Blender's
    import), ``photos="render"`` a picture of the raw mesh (:func:`hair_photos`: with ``raw="shell"`` the
    shell is hair). ``views`` cameras on the ring, every other one ``lift`` metres higher, with photos
    ``height`` pixels high (2:3); the defaults are the four views of rust/cli/tests/fit_head_cli.rs."""
    d.mkdir(parents=True, exist_ok=True)
    head = hairrecon.read_mesh(str(REPO / "blend_fixtures" / "head.ply"))
    scalp = hairrecon.read_mesh(str(REPO / "blend_fixtures" / "scalp.ply"))
    if raw == "head":
        v, t = head["vertices"], head["triangles"]
    elif raw == "shell":
        v, t = hair_shell(head, scalp)
    else:
        # a sphere of the head's size about the head's centre
        c = head["vertices"].mean(axis=0)
        v, t = sphere(0.1)
        v = v + c
    hairrecon.write_mesh(str(d / "raw.ply"), to_capture(v), t)
    if photos == "render":
        hair = np.arange(len(t)) >= (len(head["triangles"]) if raw == "shell" else len(t))
    h = int(height)
    w = h * 2 // 3
    f = 700.0 * h / 600
    if photos == "render":
        hair = np.arange(len(t)) >= (len(head["triangles"]) if raw == "shell" else len(t))
        # half a pixel at the cameras' distance (0.6 m)
        points, colours = hair_photos(v, t, hair, spacing=0.5 * 0.6 / f)
    specs = []
    for i in range(views):
        a = 2 * np.pi / views * i + 0.3
        # canonical camera on a ring, looking at the head; OpenCV axes (y down)
        c = np.array([0.6 * np.cos(a), 0.6 * np.sin(a), 0.05 + lift * (i % 2)])
        z = -c / np.linalg.norm(c)
        x = np.cross(z, [0, 0, 1.0])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        r_cam = np.stack([x, y, z]) @ ROTATION.T
        centre = SCALE * (ROTATION @ c) + OFFSET
        view = {
            "name": f"v{i}",
            "image": f"images/v{i}.png",
            "width": w,
            "height": h,
            "K": [[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]],
            "R": r_cam.tolist(),
            "t": (-(r_cam @ centre)).tolist(),
        }
        specs.append(view)
        if photos:
            (d / "images").mkdir(exist_ok=True)
            if photos == "render":
                img = render_photo(view, points, colours)
            else:
                img = np.zeros((h, w, 3), np.uint8)
            hairrecon.write_image(str(d / view["image"]), img)
    spec = {"version": 1, "units": "unknown", "frame": "imported", "convention": "opencv", "views": specs,
            "raw_mesh": "raw.ply"}
    hairrecon.write_capture(str(d), spec)
    return {"scalp": (to_capture(scalp["vertices"]), scalp["triangles"])}
