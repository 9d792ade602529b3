"""A rendered synthetic capture as a photogrammetry user holds it ("wild", issue 53): ``render_synthetic.py --wild``.

Input: a capture folder that ``render_synthetic.py`` wrote (canonical frame, metres; photos at 3× the working
height, ``--background clutter``) with its raw mesh. Output: a project folder

    images/<view>.jpg         the photos as JPEG (quality 92)
    sparse/0/cameras.txt      a COLMAP text model (PINHOLE) in a random similarity frame, the photogrammetry
    sparse/0/images.txt         tool's: rotation uniform on SO(3), 10 to 40 units a metre, the head's centre
    sparse/0/points3D.txt       anywhere within ±5 units of the origin; points3D: a sample of the mesh's vertices
    mesh.ply                  the raw mesh in that frame, photogrammetry-like: Gaussian noise on the vertices
                              (0.5 mm standard deviation, in metres before scaling) and holes (about 5% of the
                              triangles, removed in a few blobs); the torso is kept
    gt/                       for scoring only: strands.hair, head.ply, scalp.ply (in the project's frame),
                              masks/<view>.png (the photos' size), render_info.json (how the project was made
                              under "wild") and frame.json, the similarity from the project's frame to canonical
                              metres ({"scale", "rotation" by rows, "translation"}, capture.json's ``to_canonical``)

No masks, scalp or head outside ``gt/``. ``hairrecon import colmap WILD/sparse/0 --images WILD/images --mesh
WILD/mesh.ply --out CAPTURE`` makes it a capture. Seeded: the same seed writes the same files. No bpy here: the
JPEG writer is passed in (Blender's, ``render_synthetic.py``).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Callable

import hairrecon
import numpy as np

JPEG_QUALITY = 92
NOISE_M = 0.5e-3  # vertex noise, standard deviation in metres (canonical frame, before the frame's scale)
HOLE_FRACTION = 0.05  # share of the raw mesh's triangles removed
HOLES = 6  # in this many blobs
UNITS_PER_METRE = (10.0, 40.0)  # the frame's scale is drawn in this range: a head 2.5 to 10 units across
OFFSET_UNITS = 5.0  # the head's centre in the project's frame, each coordinate within ±this
POINTS3D = 2000  # vertices of the noisy mesh written as points3D.txt


def random_frame(rng: np.random.Generator, centre: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """A similarity (scale s, rotation R, translation T) from a random project frame to canonical metres,
    X = s R x + T: R uniform on SO(3) (a normalized Gaussian quaternion), 1/s in UNITS_PER_METRE, and the
    canonical point `centre` at a random project point within ±OFFSET_UNITS."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    r = rotation_from_quaternion(q)
    s = 1.0 / rng.uniform(*UNITS_PER_METRE)
    o = rng.uniform(-OFFSET_UNITS, OFFSET_UNITS, size=3)
    return s, r, centre - s * r @ o


def rotation_from_quaternion(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_from_rotation(r: np.ndarray) -> np.ndarray:
    """(w, x, y, z) with w >= 0 (Shepperd's method: the largest of the four squares first)."""
    t = np.trace(r)
    cands = [1 + t, 1 + 2 * r[0, 0] - t, 1 + 2 * r[1, 1] - t, 1 + 2 * r[2, 2] - t]
    k = int(np.argmax(cands))
    v = 0.5 * np.sqrt(cands[k])
    if k == 0:
        q = [v, (r[2, 1] - r[1, 2]) / (4 * v), (r[0, 2] - r[2, 0]) / (4 * v), (r[1, 0] - r[0, 1]) / (4 * v)]
    elif k == 1:
        q = [(r[2, 1] - r[1, 2]) / (4 * v), v, (r[0, 1] + r[1, 0]) / (4 * v), (r[0, 2] + r[2, 0]) / (4 * v)]
    elif k == 2:
        q = [(r[0, 2] - r[2, 0]) / (4 * v), (r[0, 1] + r[1, 0]) / (4 * v), v, (r[1, 2] + r[2, 1]) / (4 * v)]
    else:
        q = [(r[1, 0] - r[0, 1]) / (4 * v), (r[0, 2] + r[2, 0]) / (4 * v), (r[1, 2] + r[2, 1]) / (4 * v), v]
    q = np.array(q)
    return q if q[0] >= 0 else -q


def to_project(points: np.ndarray, s: float, r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Canonical metres to the project's frame: x = Rᵀ (X − T) / s (rows of points)."""
    return (np.asarray(points, np.float64) - t) @ r / s


def camera_to_project(rc: np.ndarray, tc: np.ndarray, s: float, r: np.ndarray, t: np.ndarray):
    """The world-to-camera pose that sees project points x as (rc, tc) sees X = s R x + T:
    rc (s R x + T) + tc = s (rc R x + (rc T + tc) / s), and the factor s drops out of the projection."""
    return rc @ r, (rc @ t + tc) / s


def punch_holes(vertices: np.ndarray, triangles: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The triangles kept after removing about HOLE_FRACTION of them in HOLES blobs: around a random
    triangle each, the triangles whose centroids are nearest to it (a ball cut out of the surface)."""
    cent = vertices[triangles].mean(axis=1)
    keep = np.ones(len(triangles), bool)
    per_hole = int(round(HOLE_FRACTION * len(triangles) / HOLES))
    for _ in range(HOLES):
        alive = np.flatnonzero(keep)
        if per_hole == 0 or len(alive) <= per_hole:
            break
        c = cent[rng.choice(alive)]
        d = np.linalg.norm(cent[alive] - c, axis=1)
        keep[alive[np.argpartition(d, per_hole - 1)[:per_hole]]] = False
    return triangles[keep]


def drop_unused(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used = np.unique(triangles)
    remap = np.full(len(vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[triangles]


def write_colmap_text(dir_: Path, views: list[dict], names: list[str], poses: list, points: np.ndarray):
    """cameras.txt (PINHOLE; one camera per distinct intrinsics), images.txt, points3D.txt (no tracks).
    COLMAP puts the first pixel's centre at (0.5, 0.5), hairrecon at (0, 0): cx, cy + 0.5."""
    dir_.mkdir(parents=True, exist_ok=True)
    cams: dict[tuple, int] = {}
    cam_of = []
    for v in views:
        k = np.asarray(v["K"], np.float64)
        key = (int(v["width"]), int(v["height"]), k[0, 0], k[1, 1], k[0, 2] + 0.5, k[1, 2] + 0.5)
        cam_of.append(cams.setdefault(key, len(cams) + 1))
    lines = ["# Camera list with one line of data per camera:", "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]"]
    lines.append(f"# Number of cameras: {len(cams)}")
    for (w, h, fx, fy, cx, cy), cid in cams.items():
        lines.append(f"{cid} PINHOLE {w} {h} {fx!r} {fy!r} {cx!r} {cy!r}")
    (dir_ / "cameras.txt").write_text("\n".join(lines) + "\n")
    lines = ["# Image list with two lines of data per image:"]
    lines += ["#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME", "#   POINTS2D[] as (X, Y, POINT3D_ID)"]
    lines.append(f"# Number of images: {len(views)}, mean observations per image: 0")
    for i, (name, (rp, tp), cid) in enumerate(zip(names, poses, cam_of)):
        q = quaternion_from_rotation(rp)
        nums = " ".join(repr(float(x)) for x in (*q, *tp))
        lines += [f"{i + 1} {nums} {cid} {name}", ""]
    (dir_ / "images.txt").write_text("\n".join(lines) + "\n")
    lines = ["# 3D point list with one line of data per point:"]
    lines += ["#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)"]
    lines.append(f"# Number of points: {len(points)}, mean track length: 0")
    lines += [f"{i + 1} {p[0]!r} {p[1]!r} {p[2]!r} 128 128 128 0" for i, p in enumerate(points.tolist())]
    (dir_ / "points3D.txt").write_text("\n".join(lines) + "\n")


def make_project(capture: Path, out: Path, seed: int, write_jpeg: Callable[[Path, np.ndarray], None]) -> dict:
    """Writes the wild project of `capture` into `out` (module doc). Returns frame.json's content."""
    capture, out = Path(capture), Path(out)
    spec = json.loads((capture / "capture.json").read_text())
    rng = np.random.default_rng([seed, 53])
    pts, counts = hairrecon.read_strands(str(capture / spec["gt_strands"]))
    head = hairrecon.read_mesh(str(capture / spec["head_mesh"]))
    allp = np.concatenate([pts, head["vertices"]]).astype(np.float64)
    centre = 0.5 * (allp.min(0) + allp.max(0))
    s, r, t = random_frame(rng, centre)
    frame = {"scale": s, "rotation": r.tolist(), "translation": t.tolist()}

    for sub in ("images", "sparse/0", "gt/masks"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    names, poses = [], []
    for v in spec["views"]:
        name = f"{v['name']}.jpg"
        write_jpeg(out / "images" / name, hairrecon.read_image(str(capture / v["image"]))[:, :, :3])
        shutil.copyfile(capture / v["mask"], out / "gt" / "masks" / f"{v['name']}.png")
        names.append(name)
        poses.append(camera_to_project(np.asarray(v["R"]), np.asarray(v["t"]), s, r, t))

    raw = hairrecon.read_mesh(str(capture / spec["raw_mesh"]))
    v = raw["vertices"].astype(np.float64)
    v = v + rng.normal(scale=NOISE_M, size=v.shape)
    n_tris = len(raw["triangles"])
    tris = punch_holes(v, raw["triangles"].astype(np.int64), rng)
    v, tris = drop_unused(v, tris)
    v = to_project(v, s, r, t)
    hairrecon.write_mesh(str(out / "mesh.ply"), v.astype(np.float32), tris.astype(np.uint32))
    sample = v[np.sort(rng.choice(len(v), size=min(POINTS3D, len(v)), replace=False))]
    write_colmap_text(out / "sparse" / "0", spec["views"], names, poses, sample)

    hairrecon.write_strands(str(out / "gt" / "strands.hair"), to_project(pts, s, r, t).astype(np.float32), counts)
    for key, name in (("head_mesh", "head.ply"), ("scalp_mesh", "scalp.ply")):
        if spec.get(key):
            m = hairrecon.read_mesh(str(capture / spec[key]))
            hairrecon.write_mesh(
                str(out / "gt" / name), to_project(m["vertices"], s, r, t).astype(np.float32), m["triangles"], m["uvs"]
            )
    info_path = capture / "render_info.json"
    info = json.loads(info_path.read_text()) if info_path.is_file() else {}
    info["wild"] = {
        "jpeg_quality": JPEG_QUALITY,
        "photo_height": int(spec["views"][0]["height"]),
        "noise_mm": NOISE_M * 1e3,
        "holes": HOLES,
        "triangles_removed": int(n_tris - len(tris)),
        "triangles_kept": int(len(tris)),
        "units_per_metre": 1.0 / s,
    }
    (out / "gt" / "render_info.json").write_text(json.dumps(info, indent=2) + "\n")
    (out / "gt" / "frame.json").write_text(json.dumps(frame, indent=2) + "\n")
    return frame
