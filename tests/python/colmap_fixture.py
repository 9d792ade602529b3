"""A tiny COLMAP text model written by hand, for the import tests (test_module.py, test_addon.py).

Two PINHOLE cameras (one per image) look at an octahedron at the origin from 2 units away; the
photos are gradients written with ``hairrecon.write_image``, the raw mesh with ``hairrecon.write_mesh``.
``expected_k`` gives the K the importer must write for a working height: COLMAP puts the first pixel's
centre at (0.5, 0.5), hairrecon at (0, 0), so cx = cx_colmap - 0.5, then scaling by s = height / H gives
cx' = s (cx + 0.5) - 0.5 (the same for cy; fx and fy scale by s).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

# per image: name, camera (fx, fy, cx, cy in COLMAP's pixel convention), yaw about +y in degrees
VIEWS = (
    ("view_a.png", (500.0, 500.0, 330.0, 235.0), 0.0),
    ("view_b.png", (520.0, 520.0, 315.0, 245.0), 30.0),
)
# at the tests' 640x480 photos; other sizes scale these (the camera stays the same)
BASE_SIZE = (640, 480)


def rotation_y(deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def write_colmap_model(root: Path, width: int = 640, height: int = 480, missing_photo: str | None = None) -> dict:
    """Writes ``root/sparse`` (cameras.txt, images.txt, points3D.txt), ``root/photos`` and
    ``root/mesh.ply``; leaves out the photo named ``missing_photo``. Returns the paths and, per view
    (named without extension), its COLMAP intrinsics (fx, fy, cx, cy) and OpenCV R, t."""
    import hairrecon

    root = Path(root)
    sparse, photos = root / "sparse", root / "photos"
    sparse.mkdir(parents=True, exist_ok=True)
    photos.mkdir(parents=True, exist_ok=True)
    scale = width / BASE_SIZE[0]
    cams = ["# CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]"]
    imgs = ["# IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", "# POINTS2D[] as (X Y POINT3D_ID)"]
    views = {}
    for i, (name, k, yaw) in enumerate(VIEWS, start=1):
        fx, fy, cx, cy = (scale * x for x in k)
        cams.append(f"{i} PINHOLE {width} {height} {fx!r} {fy!r} {cx!r} {cy!r}")
        r = rotation_y(yaw)
        centre = -2.0 * r[2]  # the camera looks along its +z (row 2 of R) at the origin
        t = -r @ centre
        h = math.radians(yaw) / 2  # quaternion of a rotation about +y: (cos, 0, sin, 0)
        q = (math.cos(h), 0.0, math.sin(h), 0.0)
        imgs.append(f"{i} {q[0]!r} {q[1]!r} {q[2]!r} {q[3]!r} {t[0]!r} {t[1]!r} {t[2]!r} {i} {name}")
        imgs.append("")
        views[Path(name).stem] = {"colmap_k": [fx, fy, cx, cy], "R": r.tolist(), "t": t.tolist(), "size": [width, height]}
        if name != missing_photo:
            y, x = np.mgrid[0:height, 0:width]
            px = np.stack([x * 255 // max(width - 1, 1), y * 255 // max(height - 1, 1), np.full_like(x, 60 * i)], axis=2)
            hairrecon.write_image(str(photos / name), np.ascontiguousarray(px.astype(np.uint8)))
    (sparse / "cameras.txt").write_text("\n".join(cams) + "\n")
    (sparse / "images.txt").write_text("\n".join(imgs) + "\n")
    (sparse / "points3D.txt").write_text("# POINT3D_ID X Y Z R G B ERROR TRACK[]\n1 0.0 0.0 0.0 128 128 128 0.5 1 0 2 0\n")
    r = 0.3
    verts = np.array([[r, 0, 0], [-r, 0, 0], [0, r, 0], [0, -r, 0], [0, 0, r], [0, 0, -r]], np.float32)
    tris = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], np.uint32)
    hairrecon.write_mesh(str(root / "mesh.ply"), verts, tris)
    return {"sparse": str(sparse), "images": str(photos), "mesh": str(root / "mesh.ply"), "views": views}


def expected_k(view: dict, height: int) -> np.ndarray:
    """The working copy's K for a view of ``write_colmap_model`` at a working ``height``."""
    fx, fy, cx, cy = view["colmap_k"]
    s = height / view["size"][1]
    cx, cy = cx - 0.5, cy - 0.5  # COLMAP's pixel centres -> hairrecon's
    return np.array([[s * fx, 0.0, s * (cx + 0.5) - 0.5], [0.0, s * fy, s * (cy + 0.5) - 0.5], [0.0, 0.0, 1.0]])


def quaternion_from_rotation(r: np.ndarray) -> tuple[float, float, float, float]:
    """COLMAP's (QW, QX, QY, QZ) of a rotation matrix (Hamilton, QW >= 0)."""
    r = np.asarray(r, np.float64)
    tr = np.trace(r)
    if tr > 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = (0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s)
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        v = [0.0, 0.0, 0.0]
        v[i] = 0.25 * s
        v[j] = (r[j, i] + r[i, j]) / s
        v[k] = (r[k, i] + r[i, k]) / s
        q = ((r[k, j] - r[j, k]) / s, *v)
    q = np.array(q) / np.linalg.norm(q)
    return tuple(float(x) for x in (q if q[0] >= 0 else -q))


def rotation_from_quaternion(q) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def colmap_from_capture(capture: Path, root: Path) -> dict:
    """The capture folder ``capture`` (pinhole views with photos, e.g. fit_fixture.write_capture) as a
    COLMAP text model, as a photogrammetry project holds it: ``root/sparse`` (one PINHOLE camera per
    image, world-to-camera poses), ``root/photos`` and ``root/mesh.ply`` (the raw mesh), nothing else
    (no masks, head or scalp). Returns what :func:`write_colmap_model` returns."""
    import json
    import shutil

    capture, root = Path(capture), Path(root)
    spec = json.loads((capture / "capture.json").read_text())
    sparse, photos = root / "sparse", root / "photos"
    sparse.mkdir(parents=True, exist_ok=True)
    photos.mkdir(parents=True, exist_ok=True)
    cams = ["# CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]"]
    imgs = ["# IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", "# POINTS2D[] as (X Y POINT3D_ID)"]
    views = {}
    for i, v in enumerate(spec["views"], start=1):
        k = np.asarray(v["K"], np.float64)
        assert abs(k[0, 1]) < 1e-12, "COLMAP's PINHOLE has no skew"
        # hairrecon puts the first pixel's centre at (0, 0), COLMAP at (0.5, 0.5)
        fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2] + 0.5, k[1, 2] + 0.5
        cams.append(f"{i} PINHOLE {v['width']} {v['height']} {fx!r} {fy!r} {cx!r} {cy!r}")
        r, t = np.asarray(v["R"], np.float64), np.asarray(v["t"], np.float64)
        q = quaternion_from_rotation(r)
        name = Path(v["image"]).name
        imgs.append(f"{i} {q[0]!r} {q[1]!r} {q[2]!r} {q[3]!r} {t[0]!r} {t[1]!r} {t[2]!r} {i} {name}")
        imgs.append("")
        shutil.copyfile(capture / v["image"], photos / name)
        views[v["name"]] = {"colmap_k": [fx, fy, cx, cy], "R": r.tolist(), "t": t.tolist(),
                            "size": [v["width"], v["height"]]}
    (sparse / "cameras.txt").write_text("\n".join(cams) + "\n")
    (sparse / "images.txt").write_text("\n".join(imgs) + "\n")
    # one point seen by the first two images (a sparse model's points are not used by the import)
    centre = np.mean([-np.asarray(v["R"]).T @ np.asarray(v["t"]) for v in spec["views"]], axis=0)
    (sparse / "points3D.txt").write_text(
        "# POINT3D_ID X Y Z R G B ERROR TRACK[]\n"
        f"1 {centre[0]!r} {centre[1]!r} {centre[2]!r} 128 128 128 0.5 1 0 2 0\n"
    )
    shutil.copyfile(capture / spec["raw_mesh"], root / "mesh.ply")
    return {"sparse": str(sparse), "images": str(photos), "mesh": str(root / "mesh.ply"), "views": views}
