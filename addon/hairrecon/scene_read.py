"""Reading a Blender scene into the core's plain data: cameras, photos, masks, meshes.

Bulk data moves through numpy and ``foreach_get``. Images that this module loads from folders are
removed again before it returns, so reading never changes ``bpy.data``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import bpy
import numpy as np

from .core.camera import CameraInputError, blender_camera, opencv_from_blender
from .core.capture import (
    CaptureInputError,
    MeshData,
    ViewInput,
    find_file_by_name,
    pixels_to_uint8,
    split_uv_seams,
    submesh,
)
from .core.surface import scalp_uv


def cameras_of(collection: Optional[bpy.types.Collection]) -> list:
    """Camera objects in a collection and its children, sorted by name."""
    if collection is None:
        return []
    return sorted((o for o in collection.all_objects if o.type == "CAMERA"), key=lambda o: o.name)


def landmarks(scene: bpy.types.Scene, names) -> dict:
    """The landmarks the user placed for Fit Head: the scene's empties named after the library's
    landmarks (``nose_tip``, ``eye_outer_left``, ...; case, spaces and hyphens aside: "Nose Tip"
    is ``nose_tip``), as name -> world location [x, y, z]. Two empties for one landmark are an
    error (CaptureInputError)."""
    wanted = set(names)
    found: dict = {}
    owner: dict = {}
    for obj in sorted(scene.objects, key=lambda o: o.name):
        if obj.type != "EMPTY":
            continue
        key = obj.name.strip().lower().replace(" ", "_").replace("-", "_")
        if key not in wanted:
            continue
        if key in found:
            raise CaptureInputError(
                f"the empties {owner[key]!r} and {obj.name!r} are both the landmark {key}: delete or rename one")
        found[key] = [float(c) for c in obj.matrix_world.translation]
        owner[key] = obj.name
    return found


def image_to_uint8(image: bpy.types.Image, channels: int = 3, data: bool = False) -> np.ndarray:
    """An image's pixels as uint8 (H, W, channels), top row first. Colour images with a float buffer
    (16-bit PNG, EXR) are encoded to sRGB; ``data`` images (masks: coverage, not colour) are stored as
    their values are."""
    w, h = image.size
    if w == 0 or h == 0:
        raise CaptureInputError(f"the image {image.name!r} ({image.filepath}) could not be read (size 0x0)")
    flat = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(flat)
    return pixels_to_uint8(flat, w, h, linear=image.is_float and not data, channels=channels)


def load_image_file(path: Path, channels: int) -> np.ndarray:
    """Reads an image file through Blender without leaving a datablock behind."""
    img = bpy.data.images.load(str(path), check_existing=False)
    try:
        img.colorspace_settings.is_data = channels == 1
        return image_to_uint8(img, channels, data=channels == 1)
    except RuntimeError as e:
        raise CaptureInputError(f"cannot read the image {path}: {e}") from None
    finally:
        bpy.data.images.remove(img)


def background_photo(cam_obj: bpy.types.Object) -> Optional[bpy.types.Image]:
    for bg in cam_obj.data.background_images:
        if bg.source == "IMAGE" and bg.image is not None:
            return bg.image
    return None


def read_views(scene: bpy.types.Scene, cameras: list, photo_folder: str, mask_folder: str) -> list[ViewInput]:
    """The cameras as OpenCV cameras with their photos (background image first, else a file named
    after the camera in ``photo_folder``) and masks (a file named after the camera or its photo in
    ``mask_folder``)."""
    views = []
    photo_dir = Path(bpy.path.abspath(photo_folder)) if photo_folder else None
    mask_dir = Path(bpy.path.abspath(mask_folder)) if mask_folder else None
    if mask_dir is not None and not mask_dir.is_dir():
        raise CaptureInputError(f"the mask folder {mask_dir} does not exist")
    if photo_dir is not None and not photo_dir.is_dir():
        raise CaptureInputError(f"the photo folder {photo_dir} does not exist")
    for obj in cameras:
        try:
            pinhole = opencv_from_blender(blender_camera(obj, scene))
        except CameraInputError as e:
            raise CaptureInputError(str(e)) from None
        photo, source, photo_stem = None, "", ""
        image = background_photo(obj)
        if image is not None:
            if image.size[0] == 0 or image.size[1] == 0:
                raise CaptureInputError(
                    f"camera {obj.name!r}: its background image {image.name!r} ({bpy.path.abspath(image.filepath)}) "
                    "cannot be read; fix the path or pack the image"
                )
            photo, source = image_to_uint8(image, 3), f"background image {image.name!r}"
            photo_stem = Path(bpy.path.abspath(image.filepath)).stem if image.filepath else image.name
        elif photo_dir is not None:
            f = find_file_by_name(photo_dir, [obj.name, obj.data.name])
            if f is not None:
                photo, source, photo_stem = load_image_file(f, 3), str(f), f.stem
        mask = None
        if mask_dir is not None:
            f = find_file_by_name(mask_dir, [obj.name, photo_stem])
            if f is None:
                raise CaptureInputError(
                    f"camera {obj.name!r}: no mask named {obj.name!r} or {photo_stem!r} in the mask folder {mask_dir}"
                )
            mask = load_image_file(f, 1)
        views.append(ViewInput(name=obj.name, camera=pinhole, photo=photo, mask=mask, photo_source=source))
    return views


def mesh_of(obj: bpy.types.Object, depsgraph, with_uv: bool = False):
    """World-space (vertices (V,3) f32, triangles (T,3) u32) of an object's evaluated mesh, plus
    (tri_loops (T,3), loop_vertex (L,), loop_uv (L,2) or None) when with_uv."""
    if obj is None or obj.type != "MESH":
        raise CaptureInputError(f"{obj.name if obj else 'nothing'!r} is not a mesh object")
    ev = obj.evaluated_get(depsgraph)
    me = ev.to_mesh()
    try:
        me.calc_loop_triangles()
        nv, nt, nl = len(me.vertices), len(me.loop_triangles), len(me.loops)
        co = np.empty(nv * 3, np.float32)
        me.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3).astype(np.float64)
        m = np.array(obj.matrix_world, dtype=np.float64)
        co = (co @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
        tris = np.empty(nt * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tris)
        extra = None
        if with_uv:
            tri_loops = np.empty(nt * 3, np.int32)
            me.loop_triangles.foreach_get("loops", tri_loops)
            loop_vertex = np.empty(nl, np.int32)
            me.loops.foreach_get("vertex_index", loop_vertex)
            uv = None
            layer = me.uv_layers.active
            if layer is not None and nl:
                uv = np.empty(nl * 2, np.float32)
                layer.uv.foreach_get("vector", uv)
                uv = uv.reshape(-1, 2)
            extra = (tri_loops.reshape(-1, 3), loop_vertex, uv)
        return co, tris.reshape(-1, 3).astype(np.uint32), extra
    finally:
        ev.to_mesh_clear()


def raw_mesh_data(obj, depsgraph) -> MeshData:
    if obj is None:
        raise CaptureInputError("no raw mesh: pick the photogrammetry mesh of the head and hair in Raw Mesh")
    if obj.type != "MESH":
        raise CaptureInputError(f"the raw mesh {obj.name!r} is a {obj.type.lower()}, not a mesh")
    v, t, _ = mesh_of(obj, depsgraph)
    return MeshData(obj.name, v, t)


def vertex_group_mask(obj: bpy.types.Object, group_name: str, threshold: float = 0.5) -> np.ndarray:
    """Per-vertex bool: weight in the group >= threshold (original mesh; modifiers must keep indices)."""
    vg = obj.vertex_groups.get(group_name)
    if vg is None:
        raise CaptureInputError(f"the head mesh {obj.name!r} has no vertex group {group_name!r}")
    idx = vg.index
    mask = np.zeros(len(obj.data.vertices), bool)
    for v in obj.data.vertices:  # vertex groups have no foreach access
        for g in v.groups:
            if g.group == idx and g.weight >= threshold:
                mask[v.index] = True
    return mask


def scalp_data(obj, depsgraph, group_name: Optional[str] = None) -> tuple[MeshData, bool]:
    """The scalp with per-vertex UVs (seams split), and whether the UVs came from the mesh (True) or
    were computed by :func:`scalp_uv` (False: the add-on adds that UV map on success). With
    ``group_name``, the scalp is that vertex group of the (head) mesh ``obj``."""
    v, t, (tri_loops, loop_vertex, loop_uv) = mesh_of(obj, depsgraph, with_uv=True)
    if group_name:
        if len(v) != len(obj.data.vertices):
            raise CaptureInputError(
                f"the modifiers of {obj.name!r} change its vertex count; apply or disable them to use a vertex group as the scalp"
            )
        keep = vertex_group_mask(obj, group_name)
        if not keep.any():
            raise CaptureInputError(f"the vertex group {group_name!r} of {obj.name!r} is empty")
    else:
        keep = np.ones(len(v), bool)
    has_uv = loop_uv is not None
    if not has_uv:
        uv_v = scalp_uv(v, v[keep])
        loop_uv = uv_v[loop_vertex]
    vv, tt, uu = split_uv_seams(v, tri_loops, loop_vertex, loop_uv)
    if group_name:
        # map the split vertices back to their original index to apply the group mask
        orig = np.zeros(len(vv), np.int64)
        orig[tt.reshape(-1)] = loop_vertex[tri_loops.reshape(-1)]
        full = MeshData(obj.name, vv, tt, uu)
        return submesh(full, keep[orig], f"{obj.name}[{group_name}]"), has_uv
    return MeshData(obj.name, vv, tt, uu), has_uv
