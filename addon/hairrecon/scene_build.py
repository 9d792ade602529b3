"""Building Blender data from results: hair Curves attached to a scalp, and scenes from captures.

Everything here creates new datablocks; callers remove them again (``remove_created``) when a
later step fails, so the scene is left as it was.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Optional

import bpy
import numpy as np
from mathutils import Matrix
from mathutils.bvhtree import BVHTree

from .core.camera import PinholeCamera, blender_from_opencv
from .core.surface import interpolate_uv, loop_uvs

HAIR_UV_MAP = "hairrecon_uv"


class Created:
    """Datablocks made by one step, removed again by :meth:`remove` if the step fails."""

    def __init__(self):
        self.items: list = []

    def add(self, datablock):
        self.items.append(datablock)
        return datablock

    def remove(self):
        for db in reversed(self.items):
            for kind, coll in (
                (bpy.types.Object, bpy.data.objects),
                (bpy.types.Curves, bpy.data.hair_curves),
                (bpy.types.Mesh, bpy.data.meshes),
                (bpy.types.Material, bpy.data.materials),
                (bpy.types.Camera, bpy.data.cameras),
                (bpy.types.Image, bpy.data.images),
                (bpy.types.Collection, bpy.data.collections),
                (bpy.types.NodeTree, bpy.data.node_groups),
                (bpy.types.ParticleSettings, bpy.data.particles),
                (bpy.types.Action, bpy.data.actions),
                (bpy.types.Scene, bpy.data.scenes),
            ):
                try:
                    if isinstance(db, kind):
                        coll.remove(db)
                        break
                except (ReferenceError, RuntimeError):
                    break
        self.items.clear()


# --- surfaces -----------------------------------------------------------------------------------


def surface_triangles(obj: bpy.types.Object):
    """Surface-local corner positions (T, 3, 3) and corner UVs (T, 3, 2) of the original mesh's loop
    triangles in its active UV map (the map Blender's hair attachment uses)."""
    me = obj.data
    me.calc_loop_triangles()
    nt = len(me.loop_triangles)
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    tri_v = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("vertices", tri_v)
    tri_l = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", tri_l)
    uv = np.empty(len(me.loops) * 2, np.float32)
    me.uv_layers.active.uv.foreach_get("vector", uv)
    return co.reshape(-1, 3), tri_v.reshape(-1, 3), uv.reshape(-1, 2)[tri_l.reshape(-1, 3)]


def ensure_uv_map(obj: bpy.types.Object, group_name: Optional[str] = None) -> str:
    """The name of the surface's active UV map; adds ``hairrecon_uv`` (a seamless projection of the
    scalp, :func:`core.surface.scalp_uv`) when the mesh has none. Returns the map's name."""
    me = obj.data
    if me.uv_layers.active is not None:
        return me.uv_layers.active.name
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    keep = np.ones(len(co), bool)
    if group_name:
        from .scene_read import vertex_group_mask

        keep = vertex_group_mask(obj, group_name)
    loop_v = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", loop_v)
    starts = np.empty(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_start", starts)
    totals = np.empty(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_total", totals)
    loop_face = np.empty(len(me.loops), np.int64)
    loop_face[np.repeat(starts, totals) + _ranks(totals)] = np.repeat(np.arange(len(starts)), totals)
    layer = me.uv_layers.new(name=HAIR_UV_MAP)
    layer.uv.foreach_set("vector", loop_uvs(co, keep, loop_v, loop_face).ravel())
    me.uv_layers.active = layer
    return layer.name


def _ranks(totals: np.ndarray) -> np.ndarray:
    """0, 1, ..., n-1 within each polygon: loop index = loop_start + rank."""
    starts = np.concatenate([[0], np.cumsum(totals)[:-1]])
    return np.arange(int(totals.sum())) - np.repeat(starts, totals)


def attach(points_local: np.ndarray, counts: np.ndarray, surface: bpy.types.Object):
    """For each strand root (surface-local): (uv (S,2), distance to the surface (S,), closest point
    (S,3)). The UV is that of the closest point on the surface mesh, in its active UV map."""
    co, tri_v, tri_uv = surface_triangles(surface)
    # degenerate triangles (e.g. at a UV sphere's poles) have no meaningful barycentric UV: skip them
    area2 = np.linalg.norm(np.cross(co[tri_v[:, 1]] - co[tri_v[:, 0]], co[tri_v[:, 2]] - co[tri_v[:, 0]]), axis=1)
    good = area2 > 1e-7 * max(float(area2.max(initial=0.0)), 1e-30)
    # ...and neither have triangles without UV area (faces parked outside the scalp's UV map)
    e1, e2 = tri_uv[:, 1] - tri_uv[:, 0], tri_uv[:, 2] - tri_uv[:, 0]
    good &= np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) > 1e-12
    tri_v, tri_uv = tri_v[good], tri_uv[good]
    if len(tri_v) == 0:
        raise ValueError(f"the scalp {surface.name!r} has no faces with an area in its UV map")
    bvh = BVHTree.FromPolygons([tuple(p) for p in co], [tuple(t) for t in tri_v], all_triangles=True)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    roots = points_local[starts]
    n = len(roots)
    loc = np.zeros((n, 3))
    tri = np.zeros(n, np.int64)
    dist = np.full(n, np.inf)
    find = bvh.find_nearest
    for i, r in enumerate(roots.tolist()):
        hit = find(r)
        if hit[0] is not None:
            loc[i] = hit[0]
            tri[i] = hit[2]
            dist[i] = hit[3]
    uv = interpolate_uv(loc, co[tri_v[tri]].astype(np.float64), tri_uv[tri].astype(np.float64))
    return uv.astype(np.float32), dist, loc


# --- hair curves --------------------------------------------------------------------------------


def hair_material(name: str = "Hair", color=None) -> bpy.types.Material:
    """A Principled Hair BSDF material: with ``color`` (linear RGB; the add-on passes
    ``core.capture.direct_color`` of the hair's colour in the photos) in the direct colouring
    parametrization, without it a mid brown (melanin 0.6)."""
    mat = bpy.data.materials.new(name)
    with warnings.catch_warnings():  # Material.use_nodes: needed up to 4.x, deprecated in 5.0
        warnings.simplefilter("ignore", DeprecationWarning)
        mat.use_nodes = True
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = nt.nodes.new("ShaderNodeBsdfHairPrincipled")
    bsdf.location = (-300, 0)
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    # sockets by name over all inputs: Blender 5.0's inputs[name] skips those of other parametrizations
    if color is not None:
        bsdf.parametrization = "COLOR"
        socket = next(i for i in bsdf.inputs if i.name == "Color")
        socket.default_value = (*(min(max(float(c), 0.0), 1.0) for c in color[:3]), 1.0)
    else:
        bsdf.parametrization = "MELANIN"
        next(i for i in bsdf.inputs if i.name == "Melanin").default_value = 0.6
    return mat


def new_hair_curves(
    name: str,
    points_local: np.ndarray,
    counts: np.ndarray,
    root_radius: float,
    tip_radius: float,
) -> bpy.types.Curves:
    """A Curves datablock with the strands (surface-local positions) and a tapering radius."""
    cv = bpy.data.hair_curves.new(name)
    try:
        _fill_curves(cv, points_local, counts, root_radius, tip_radius)
    except BaseException:
        bpy.data.hair_curves.remove(cv)
        raise
    return cv


def _fill_curves(cv, points_local, counts, root_radius, tip_radius):
    counts = np.asarray(counts, dtype=np.int64)
    if len(points_local) != int(counts.sum()):
        raise ValueError(f"{len(points_local)} points but the strand counts add up to {int(counts.sum())}")
    cv.add_curves([int(c) for c in counts])
    cv.attributes["position"].data.foreach_set("vector", np.ascontiguousarray(points_local, np.float32).ravel())
    # radius tapers linearly from root to tip along each strand's point index
    starts = np.repeat(np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
    idx = np.arange(len(points_local)) - starts
    denom = np.repeat(np.maximum(counts - 1, 1), counts)
    s = idx / denom
    radius = (root_radius + (tip_radius - root_radius) * s).astype(np.float32)
    attr = cv.attributes.get("radius") or cv.attributes.new("radius", "FLOAT", "POINT")
    attr.data.foreach_set("value", radius)


DEFORM_GROUP = "hairrecon Surface Deform"


def surface_deform_group(created: Created) -> bpy.types.NodeTree:
    """A geometry node group with Blender's "Deform Curves on Surface" node: hair follows the
    scalp's deformation through ``surface_uv_coordinate`` (as Blender's own new hair objects do)."""
    ng = bpy.data.node_groups.get(DEFORM_GROUP)
    if ng is not None and any(n.bl_idname == "GeometryNodeDeformCurvesOnSurface" for n in ng.nodes):
        return ng
    ng = created.add(bpy.data.node_groups.new(DEFORM_GROUP, "GeometryNodeTree"))
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi = ng.nodes.new("NodeGroupInput")
    go = ng.nodes.new("NodeGroupOutput")
    de = ng.nodes.new("GeometryNodeDeformCurvesOnSurface")
    gi.location, de.location, go.location = (-300, 0), (0, 0), (300, 0)
    ng.links.new(gi.outputs[0], de.inputs[0])
    ng.links.new(de.outputs[0], go.inputs[0])
    return ng


def add_hair_object(
    context,
    created: Created,
    name: str,
    points_world: np.ndarray,
    counts: np.ndarray,
    surface: bpy.types.Object,
    material: bpy.types.Material,
    root_radius: float = 4e-5,
    tip_radius: float = 1e-5,
) -> tuple[bpy.types.Object, np.ndarray]:
    """A hair Curves object parented to ``surface``, in its local space, with ``surface``,
    ``surface_uv_map`` and ``surface_uv_coordinate`` set. Returns the object and root distances (m)."""
    m = np.array(surface.matrix_world, dtype=np.float64)
    inv = np.linalg.inv(m)
    local = (np.asarray(points_world, np.float64) @ inv[:3, :3].T + inv[:3, 3]).astype(np.float32)
    cv = created.add(new_hair_curves(name, local, counts, root_radius, tip_radius))
    uv, dist_local, _ = attach(local, counts, surface)
    cv.surface = surface
    cv.surface_uv_map = surface.data.uv_layers.active.name
    a = cv.attributes.get("surface_uv_coordinate") or cv.attributes.new("surface_uv_coordinate", "FLOAT2", "CURVE")
    a.data.foreach_set("vector", uv.ravel())
    cv.materials.append(material)
    obj = created.add(bpy.data.objects.new(name, cv))
    collection = surface.users_collection[0] if surface.users_collection else context.scene.collection
    collection.objects.link(obj)
    obj.parent = surface
    obj.matrix_parent_inverse = Matrix.Identity(4)
    mod = obj.modifiers.new("Surface Deform", "NODES")
    mod.node_group = surface_deform_group(created)
    # distances in world units (the surface may be scaled)
    scale = float(np.cbrt(abs(np.linalg.det(m[:3, :3]))))
    return obj, dist_local * scale


# --- scenes from captures -----------------------------------------------------------------------


def mesh_object(created: Created, collection, name: str, vertices, triangles, uvs=None) -> bpy.types.Object:
    v = np.asarray(vertices, np.float32)
    t = np.asarray(triangles, np.int32)
    me = created.add(bpy.data.meshes.new(name))
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", v.ravel())
    me.loops.add(t.size)
    me.loops.foreach_set("vertex_index", t.ravel())
    me.polygons.add(len(t))
    me.polygons.foreach_set("loop_start", np.arange(0, t.size, 3, dtype=np.int32))
    me.update(calc_edges=True)
    if uvs is not None:
        layer = me.uv_layers.new(name="UVMap")
        layer.uv.foreach_set("vector", np.asarray(uvs, np.float32)[t.ravel()].ravel())
    me.validate()
    obj = created.add(bpy.data.objects.new(name, me))
    collection.objects.link(obj)
    return obj


def camera_object(created: Created, collection, name: str, cam: PinholeCamera, photo_path: Optional[Path]):
    s = blender_from_opencv(cam)
    data = created.add(bpy.data.cameras.new(name))
    data.lens = s.lens
    data.sensor_width = s.sensor_width
    data.sensor_fit = s.sensor_fit
    data.shift_x = s.shift_x
    data.shift_y = s.shift_y
    data.clip_start = 0.01
    obj = created.add(bpy.data.objects.new(name, data))
    obj.matrix_world = Matrix([list(r) for r in s.matrix_world])
    collection.objects.link(obj)
    if photo_path is not None:
        img = created.add(bpy.data.images.load(str(photo_path), check_existing=False))
        bg = data.background_images.new()
        bg.image = img
        data.show_background_images = True
    return obj, s
