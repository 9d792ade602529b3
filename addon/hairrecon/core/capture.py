"""Writing a capture folder (rust/core/src/capture.rs) from data taken out of a Blender scene.

The Blender layer gathers, per camera, a :class:`~.camera.PinholeCamera` and the photo's pixels, and
per mesh its world-space vertices and triangles; this module checks them and phrases every problem as
one :class:`CaptureInputError` that names the camera, object or file and says how to fix it. The files
(PNGs, meshes, ``capture.json``) are written by the hairrecon library, passed in as ``lib`` (the
``hairrecon`` module), so that this module imports neither bpy nor the library.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Optional, Sequence

import numpy as np

from .camera import PinholeCamera, rescale

CAPTURE_VERSION = 1
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".bmp", ".webp")


class CaptureInputError(ValueError):
    """The scene cannot be turned into a capture; the message says what and how to fix it."""


# --- images -------------------------------------------------------------------------------------


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))


def hair_color(views: Sequence["ViewInput"], min_coverage: int = 230, max_samples: int = 200_000) -> Optional[tuple]:
    """The hair's colour in the photos: the per-channel median, in linear RGB, of the photo pixels
    that the masks cover fully (mask value at least ``min_coverage`` of 255), pooled over the views,
    at most ``max_samples`` pixels per view (evenly strided). None without masks or with fewer than
    100 such pixels: the photos alone do not tell hair from the rest."""
    samples = []
    for v in views:
        if v.photo is None or v.mask is None:
            continue
        photo = v.photo[..., :3]
        mask = v.mask.reshape(v.mask.shape[0], v.mask.shape[1], -1)[..., 0]
        if mask.shape != photo.shape[:2]:
            continue  # a photo at another size than its mask: the pixels do not correspond
        px = photo[mask >= min_coverage]
        if len(px) > max_samples:
            px = px[:: -(-len(px) // max_samples)]
        samples.append(px)
    if not samples or sum(len(s) for s in samples) < 100:
        return None
    lin = srgb_to_linear(np.concatenate(samples).astype(np.float64) / 255.0)
    return tuple(float(c) for c in np.median(lin, axis=0))


# The Principled Hair BSDF's direct colouring C (grey) against the median linear value of the fully
# covered hair pixels it renders to, under a uniform white environment of strength 1 (the synthetic
# captures' light), measured at commit ff68f35 by `.venv/bin/python scripts/hair_color_curve.py
# out/demo/capture` (now research/scripts/) on the demo's capture of then (20,000 wavy strands, 16 views
# of 171x256 px). The response is far from the identity: C = 0.1 renders to 0.25, and the specular lobe keeps dark hair above 0.04.
DIRECT_COLOR_RESPONSE = ((0.005, 0.0429), (0.01, 0.0584), (0.02, 0.0847), (0.05, 0.1539), (0.1, 0.2490),
                         (0.2, 0.4059), (0.35, 0.5651), (0.5, 0.6594), (0.7, 0.7264), (0.9, 0.7465))


def direct_color(observed: Sequence[float]) -> tuple:
    """The direct colouring C per channel whose render (by DIRECT_COLOR_RESPONSE) has the observed
    linear value: log-log interpolation in the table, extended below its first row along its first
    segment, C within [0.001, 0.9]."""
    cs = np.log([c for c, _ in DIRECT_COLOR_RESPONSE])
    vs = np.log([v for _, v in DIRECT_COLOR_RESPONSE])
    out = []
    for o in observed:
        lo = np.log(max(float(o), 1e-6))
        if lo <= vs[0]:
            c = cs[0] + (lo - vs[0]) * (cs[1] - cs[0]) / (vs[1] - vs[0])
        else:
            c = float(np.interp(lo, vs, cs))
        out.append(float(np.clip(np.exp(c), 0.001, 0.9)))
    return tuple(out)


def pixels_to_uint8(flat_rgba: np.ndarray, width: int, height: int, linear: bool, channels: int = 4) -> np.ndarray:
    """Blender ``Image.pixels`` (float RGBA, bottom row first) -> uint8 (H, W, C) top row first.
    ``linear`` images (float buffers) are encoded to sRGB; byte images are stored as they are."""
    a = np.asarray(flat_rgba, dtype=np.float32).reshape(height, width, 4)[::-1, :, :channels]
    if linear:
        a = a.copy()
        a[..., :3] = linear_to_srgb(a[..., :3])
    return (np.clip(a, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def find_file_by_name(folder: os.PathLike | str, names: Iterable[str], extensions=IMAGE_EXTENSIONS) -> Optional[Path]:
    """The file in ``folder`` whose name without extension equals one of ``names`` (case-insensitive),
    trying the names in order; None when none matches."""
    folder = Path(folder)
    if not folder.is_dir():
        return None
    by_stem: dict[str, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix.lower() in extensions:
            by_stem.setdefault(p.stem.lower(), p)
    for n in names:
        if n and n.lower() in by_stem:
            return by_stem[n.lower()]
    return None


def safe_file_stem(name: str) -> str:
    """A file name for a view name (camera names may hold '/', ':' ...)."""
    s = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return s or "view"


# --- meshes -------------------------------------------------------------------------------------


@dataclass
class MeshData:
    """A triangle mesh in world space; ``uvs`` per vertex (seams already split) or None."""

    name: str
    vertices: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) uint32
    uvs: Optional[np.ndarray] = None  # (V, 2) float32


def check_mesh(mesh: MeshData, role: str) -> None:
    """Raises CaptureInputError when a mesh cannot serve as ``role`` (e.g. 'raw mesh')."""
    if len(mesh.vertices) == 0 or len(mesh.triangles) == 0:
        raise CaptureInputError(
            f"the {role} object {mesh.name!r} has no faces ({len(mesh.vertices)} vertices, "
            f"{len(mesh.triangles)} triangles); pick a mesh with a surface"
        )
    if not np.all(np.isfinite(mesh.vertices)):
        raise CaptureInputError(f"the {role} object {mesh.name!r} has vertices that are not finite numbers")


def split_uv_seams(
    positions: np.ndarray, tri_loops: np.ndarray, loop_vertex: np.ndarray, loop_uv: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-loop UVs -> per-vertex UVs by duplicating vertices on UV seams.

    positions (V, 3); tri_loops (T, 3) loop indices of each triangle; loop_vertex (L,) vertex of each
    loop; loop_uv (L, 2). Returns (vertices (V', 3), triangles (T, 3), uvs (V', 2)).
    """
    key = np.concatenate([loop_vertex[:, None].astype(np.float64), np.round(loop_uv.astype(np.float64), 7)], axis=1)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    verts = positions[uniq[:, 0].astype(np.int64)].astype(np.float32)
    uvs = uniq[:, 1:].astype(np.float32)
    tris = inverse[tri_loops].astype(np.uint32)
    return verts, tris, uvs


def submesh(mesh: MeshData, keep_vertex: np.ndarray, name: str) -> MeshData:
    """The triangles whose three vertices are kept, with unused vertices dropped."""
    keep_tri = keep_vertex[mesh.triangles].all(axis=1)
    tris = mesh.triangles[keep_tri]
    used = np.unique(tris)
    remap = np.full(len(mesh.vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    return MeshData(
        name=name,
        vertices=mesh.vertices[used],
        triangles=remap[tris].astype(np.uint32),
        uvs=None if mesh.uvs is None else mesh.uvs[used],
    )


# --- the capture --------------------------------------------------------------------------------


@dataclass
class ViewInput:
    """One camera with its photo (and optional mask) as uint8 pixels (H, W, C), top row first.
    When the photo is not at the render size, it must have the same aspect ratio; K is rescaled."""

    name: str
    camera: PinholeCamera
    photo: Optional[np.ndarray]
    mask: Optional[np.ndarray] = None
    photo_source: str = ""  # where the photo came from, for messages


def check_views(views: Sequence[ViewInput]) -> None:
    if not views:
        raise CaptureInputError("there are no cameras: put the calibrated cameras in the Cameras collection")
    seen = set()
    for v in views:
        if v.photo is None:
            raise CaptureInputError(
                f"camera {v.name!r} has no photo: give it a background image (Camera Properties > "
                "Background Images) or put a file named after the camera in the Photos folder"
            )
        key = safe_file_stem(v.name).lower()
        if key in seen:
            raise CaptureInputError(f"two cameras have the file name {key!r}; rename one of them")
        seen.add(key)


def _fit_camera(v: ViewInput, h: int, w: int, what: str) -> PinholeCamera:
    try:
        return rescale(v.camera, w, h)
    except ValueError:
        raise CaptureInputError(
            f"camera {v.name!r}: its {what} {v.photo_source or ''} is {w}x{h} pixels, which does not have the "
            f"aspect ratio of the render resolution {v.camera.width}x{v.camera.height}; set Output Properties > "
            "Format > Resolution to the photo's size"
        ) from None


def write_capture(
    directory: os.PathLike | str,
    views: Sequence[ViewInput],
    raw_mesh: MeshData,
    lib,
    head_mesh: Optional[MeshData] = None,
    scalp_mesh: Optional[MeshData] = None,
    to_canonical: Optional[dict] = None,
) -> Path:
    """Writes ``directory/capture.json`` with images/, masks/ and the meshes; returns its path.

    ``to_canonical`` (``scale``, ``rotation`` by rows, ``translation``: what Fit Head found) makes the
    capture an imported one in the scene's frame and units, which the library runs in the canonical
    frame and whose strands come back in the scene's frame.

    ``lib`` is the ``hairrecon`` module: its ``write_image``, ``write_mesh`` and ``write_capture`` (which
    checks capture.json against the schema) write the files.
    """
    check_views(views)
    check_mesh(raw_mesh, "raw mesh")
    if head_mesh is not None:
        check_mesh(head_mesh, "head mesh")
    if scalp_mesh is not None:
        check_mesh(scalp_mesh, "scalp")
    d = Path(directory)
    (d / "images").mkdir(parents=True, exist_ok=True)
    entries = []
    for v in views:
        h, w = v.photo.shape[:2]
        cam = _fit_camera(v, h, w, "photo")
        stem = safe_file_stem(v.name)
        entry = {"name": v.name, "image": f"images/{stem}.png"}
        lib.write_image(str(d / entry["image"]), np.ascontiguousarray(v.photo, dtype=np.uint8))
        if v.mask is not None:
            mh, mw = v.mask.shape[:2]
            if (mw, mh) != (w, h):
                raise CaptureInputError(
                    f"camera {v.name!r}: its mask is {mw}x{mh} pixels but its photo is {w}x{h}; "
                    "masks must have the size of their photos"
                )
            (d / "masks").mkdir(exist_ok=True)
            entry["mask"] = f"masks/{stem}.png"
            lib.write_image(str(d / entry["mask"]), np.ascontiguousarray(v.mask, dtype=np.uint8))
        entry.update(cam.to_json())
        entries.append(entry)
    spec = {"version": CAPTURE_VERSION, "units": "metres", "convention": "opencv", "views": entries}
    if to_canonical is not None:
        spec["units"], spec["frame"] = "unknown", "imported"
        spec["to_canonical"] = {k: to_canonical[k] for k in ("scale", "rotation", "translation")}
    for key, mesh, fname in (
        ("raw_mesh", raw_mesh, "raw_mesh.ply"),
        ("head_mesh", head_mesh, "head.ply"),
        ("scalp_mesh", scalp_mesh, "scalp.ply"),
    ):
        if mesh is None:
            continue
        lib.write_mesh(
            str(d / fname),
            np.ascontiguousarray(mesh.vertices, dtype=np.float32),
            np.ascontiguousarray(mesh.triangles, dtype=np.uint32),
            uvs=None if mesh.uvs is None else np.ascontiguousarray(mesh.uvs, dtype=np.float32),
        )
        spec[key] = fname
    return Path(lib.write_capture(str(d), spec))


def write_fit_capture(
    directory: os.PathLike | str,
    cameras: Sequence[tuple[str, PinholeCamera]],
    raw_mesh: MeshData,
    lib,
) -> Path:
    """Writes the capture a head fit reads (``lib.fit_head``): ``directory/capture.json`` with the
    cameras (name, OpenCV camera) and the raw mesh. The fit reads no photo, so the images the views
    name are not written; the frame is "imported" (the fit finds it). Returns capture.json's path."""
    if not cameras:
        raise CaptureInputError("there are no cameras: put the calibrated cameras in the Cameras collection")
    check_mesh(raw_mesh, "raw mesh")
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    entries, seen = [], set()
    for name, cam in cameras:
        stem = safe_file_stem(name)
        if stem.lower() in seen:
            raise CaptureInputError(f"two cameras have the file name {stem.lower()!r}; rename one of them")
        seen.add(stem.lower())
        entries.append({"name": name, "image": f"images/{stem}.png", **cam.to_json()})
    lib.write_mesh(
        str(d / "raw_mesh.ply"),
        np.ascontiguousarray(raw_mesh.vertices, dtype=np.float32),
        np.ascontiguousarray(raw_mesh.triangles, dtype=np.uint32),
    )
    spec = {"version": CAPTURE_VERSION, "units": "unknown", "frame": "imported", "convention": "opencv",
            "views": entries, "raw_mesh": "raw_mesh.ply"}
    return Path(lib.write_capture(str(d), spec))


def read_capture_json(directory: os.PathLike | str) -> dict:
    """capture.json of a capture folder as a dict, with clear errors (validation is the library's)."""
    d = Path(directory)
    path = d / "capture.json" if d.is_dir() else d
    if not path.is_file():
        raise CaptureInputError(f"{path} does not exist; choose a capture folder (one with a capture.json)")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise CaptureInputError(f"{path} is not valid JSON: {e}") from None
