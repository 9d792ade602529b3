"""A capture as an import leaves it, for the head-fit tests (as rust/cli/tests/fit_head_cli.rs makes it):
the bundled head moved into another frame by a similarity (scale 40, turned, offset) as the raw mesh,
four cameras 0.6 m (canonical) around it looking at it, no head and no scalp. ``raw="sphere"`` puts a
sphere of a head's size there instead: nothing to fit.
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


def write_capture(hairrecon, d: Path, raw: str = "head", photos: bool = False) -> dict:
    """Writes the capture into ``d``; returns the true scalp in the capture's frame
    ``{"scalp": (vertices, triangles)}``. ``photos`` writes a black photo per view (for Blender's import)."""
    d.mkdir(parents=True, exist_ok=True)
    head = hairrecon.read_mesh(str(REPO / "blend_fixtures" / "head.ply"))
    scalp = hairrecon.read_mesh(str(REPO / "blend_fixtures" / "scalp.ply"))
    if raw == "head":
        v, t = head["vertices"], head["triangles"]
    else:
        # a sphere of the head's size about the head's centre
        c = head["vertices"].mean(axis=0)
        v, t = sphere(0.1)
        v = v + c
    hairrecon.write_mesh(str(d / "raw.ply"), to_capture(v), t)
    w, h = 400, 600
    views = []
    for i in range(4):
        a = np.pi / 2 * i + 0.3
        # canonical camera on a ring, looking at the head; OpenCV axes (y down)
        c = np.array([0.6 * np.cos(a), 0.6 * np.sin(a), 0.05])
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
            "K": [[700.0, 0, (w - 1) / 2], [0, 700.0, (h - 1) / 2], [0, 0, 1]],
            "R": r_cam.tolist(),
            "t": (-(r_cam @ centre)).tolist(),
        }
        views.append(view)
        if photos:
            (d / "images").mkdir(exist_ok=True)
            hairrecon.write_image(str(d / view["image"]), np.zeros((h, w, 3), np.uint8))
    spec = {"version": 1, "units": "unknown", "frame": "imported", "convention": "opencv", "views": views,
            "raw_mesh": "raw.ply"}
    hairrecon.write_capture(str(d), spec)
    return {"scalp": (to_capture(scalp["vertices"]), scalp["triangles"])}
