"""What the add-on worker's tasks share (runs inside Blender): installing the extension, snapshots of the
datablocks, running operators, the test scenes, and reading hair back from Blender."""

from __future__ import annotations

import math
import sys
import json
from pathlib import Path

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES was set by the harness)
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import addon_core  # noqa: E402  (the extension's bpy-free core as hairrecon_addon_core)

DATA_KINDS = ("objects", "meshes", "hair_curves", "cameras", "images", "materials", "collections")
_PACKAGE = {"name": "bl_ext.user_default.hairrecon"}


def load_core_camera():
    """addon/hairrecon/core/camera.py (it is bpy-free), from the repository."""
    return addon_core.load("camera")


def snapshot() -> dict:
    """Names of the datablocks the add-on may touch, and each mesh's UV maps."""
    snap = {k: sorted(db.name for db in getattr(bpy.data, k)) for k in DATA_KINDS}
    snap["uv_maps"] = {m.name: [l.name for l in m.uv_layers] for m in bpy.data.meshes}
    return snap


def install(zip_path: str) -> dict:
    """Installs the extension zip into the user folder (BLENDER_USER_RESOURCES) and enables it.
    Without a zip (development only), registers addon/hairrecon from the source tree instead."""
    import addon_utils

    if not zip_path:
        from blender_batch import register_source_addon

        _PACKAGE["name"] = register_source_addon()
        import hairrecon

        return {"result": ["SOURCE"], "enabled": [], "module_file": hairrecon.__file__, "version": hairrecon.__version__,
                "has_operator": hasattr(bpy.types, "HAIRRECON_OT_reconstruct"), "addon_module": []}
    res = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    enabled = sorted(m for m in bpy.context.preferences.addons.keys())
    # Blender appends the extensions' wheel folder to sys.path; in this venv a developer's
    # `maturin develop` copy of hairrecon would come first and hide the bundled wheel, which is the
    # one under test (a real Blender has no such copy). Put the wheel folder first.
    wheel_dir = str(Path(bpy.utils.user_resource("EXTENSIONS")) / ".local" / "lib"
                    / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages")
    if wheel_dir in sys.path:
        sys.path.remove(wheel_dir)
        sys.path.insert(0, wheel_dir)
    sys.modules.pop("hairrecon", None)
    import hairrecon  # the Rust module, from the extension's wheel

    return {
        "result": sorted(res),
        "enabled": enabled,
        "module_file": hairrecon.__file__,
        "version": hairrecon.__version__,
        "has_operator": hasattr(bpy.types, "HAIRRECON_OT_reconstruct"),
        "addon_module": [m.__name__ for m in addon_utils.modules() if m.__name__.endswith(".hairrecon")],
    }


def extension_package():
    import importlib

    return importlib.import_module(_PACKAGE["name"])


def run_op(op, *args, **kw):
    """Calls an operator; returns (result set or None, error message or None)."""
    try:
        return sorted(op(*args, **kw)), None
    except RuntimeError as e:
        return None, str(e)


def configure(p):
    s = bpy.context.scene.hairrecon
    s.quality = "CUSTOM"
    s.guides = int(p.get("guides", 100))
    s.children = int(p.get("children", 1000))
    s.dr = bool(p.get("dr", True))
    s.dr_iters_guides = int(p.get("dr_iters_guides", 5))
    s.dr_iters_children = int(p.get("dr_iters_children", 3))
    s.stop_after = p.get("stop_after", "") or ""


def curves_report(obj) -> dict:
    """Checks one hair Curves object against its scalp surface (world space)."""
    from mathutils.bvhtree import BVHTree

    cv = obj.data
    n_pts, n_cur = len(cv.points), len(cv.curves)
    pos = np.empty(n_pts * 3, np.float32)
    cv.attributes["position"].data.foreach_get("vector", pos)
    pos = pos.reshape(-1, 3).astype(np.float64)
    off = np.empty(n_cur + 1, np.int32)
    cv.curve_offset_data.foreach_get("value", off)
    m = np.array(obj.matrix_world)
    world = pos @ m[:3, :3].T + m[:3, 3]
    roots = world[off[:-1]]
    out = {"name": obj.name, "curves": n_cur, "points": n_pts, "surface": cv.surface.name if cv.surface else None,
           "uv_map": cv.surface_uv_map, "has_radius": "radius" in cv.attributes}
    if "radius" in cv.attributes:
        r = np.empty(n_pts, np.float32)
        cv.attributes["radius"].data.foreach_get("value", r)
        out["radius_range"] = [float(r.min()), float(r.max())]
    mats = [mt.name for mt in cv.materials if mt]
    out["materials"] = mats
    out["material_nodes"] = sorted({n.bl_idname for mt in cv.materials if mt and mt.node_tree for n in mt.node_tree.nodes})
    hair_nodes = [n for mt in cv.materials if mt and mt.node_tree for n in mt.node_tree.nodes
                  if n.bl_idname == "ShaderNodeBsdfHairPrincipled"]
    if hair_nodes:
        out["hair_parametrization"] = hair_nodes[0].parametrization
        out["hair_color"] = [float(x) for x in next(i for i in hair_nodes[0].inputs if i.name == "Color").default_value[:3]]
    surf = cv.surface
    if surf is None:
        return out
    me = surf.data
    me.calc_loop_triangles()
    sm = np.array(surf.matrix_world)
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co_l = co.reshape(-1, 3).astype(np.float64)
    co_w = co_l @ sm[:3, :3].T + sm[:3, 3]
    tri_v = np.empty(len(me.loop_triangles) * 3, np.int32)
    me.loop_triangles.foreach_get("vertices", tri_v)
    tri_v = tri_v.reshape(-1, 3)
    tri_l = np.empty(len(me.loop_triangles) * 3, np.int32)
    me.loop_triangles.foreach_get("loops", tri_l)
    tri_l = tri_l.reshape(-1, 3)
    layer = me.uv_layers.get(cv.surface_uv_map)
    out["uv_map_exists"] = layer is not None
    # distance of every root to the scalp surface, world space
    bvh = BVHTree.FromPolygons(co_w.tolist(), tri_v.tolist(), all_triangles=True)
    hits = [bvh.find_nearest(r.tolist()) for r in roots]
    d = np.array([h[3] if h[0] is not None else np.inf for h in hits], dtype=float)
    out["root_dist_max_mm"] = float(1000 * d.max())
    out["root_dist_median_mm"] = float(1000 * np.median(d))
    if "surface_uv_coordinate" not in cv.attributes or layer is None:
        return out
    a = cv.attributes["surface_uv_coordinate"]
    out["uv_attr"] = [a.domain, a.data_type]
    uv = np.empty(n_cur * 2, np.float32)
    a.data.foreach_get("vector", uv)
    uv = uv.reshape(-1, 2).astype(np.float64)
    out["uv_min"], out["uv_max"] = uv.min(axis=0).tolist(), uv.max(axis=0).tolist()
    # map each UV back to the surface: find its triangle in UV space, interpolate the 3D corners
    luv = np.empty(len(me.loops) * 2, np.float32)
    layer.uv.foreach_get("vector", luv)
    luv = luv.reshape(-1, 2).astype(np.float64)
    # zero-area triangles (a UV sphere's poles) carry no position: leave them out of the lookup
    c3 = co_w[tri_v]
    area2 = np.linalg.norm(np.cross(c3[:, 1] - c3[:, 0], c3[:, 2] - c3[:, 0]), axis=1)
    good = area2 > 1e-7 * area2.max()
    tri_v, tri_l = tri_v[good], tri_l[good]
    tuv = luv[tri_l]  # (T, 3, 2)
    flat = [[(float(x), float(y), 0.0) for x, y in t] for t in tuv]
    verts2 = [v for t in flat for v in t]
    uv_bvh = BVHTree.FromPolygons(verts2, [(3 * i, 3 * i + 1, 3 * i + 2) for i in range(len(flat))], all_triangles=True)
    back = np.zeros((n_cur, 3))
    uv_miss = np.zeros(n_cur)
    for i, (u, v) in enumerate(uv):
        loc, _, ti, dist = uv_bvh.find_nearest((float(u), float(v), 0.0))
        uv_miss[i] = dist
        a2, b2, c2 = tuv[ti]
        T = np.array([[b2[0] - a2[0], c2[0] - a2[0]], [b2[1] - a2[1], c2[1] - a2[1]]])
        try:
            l1, l2 = np.linalg.solve(T, np.array([loc[0] - a2[0], loc[1] - a2[1]]))
        except np.linalg.LinAlgError:
            l1 = l2 = 0.0
        w = np.array([1 - l1 - l2, l1, l2])
        back[i] = w @ co_w[tri_v[ti]]
    # the closest surface point of each root, to compare the UV's surface point with
    closest = np.array([bvh.find_nearest(r.tolist())[0] for r in roots])
    out["uv_outside_map_max"] = float(uv_miss.max())
    out["uv_back_to_closest_max_mm"] = float(1000 * np.linalg.norm(back - closest, axis=1).max())
    out["uv_back_to_root_max_mm"] = float(1000 * np.linalg.norm(back - roots, axis=1).max())
    return out


def attach_node_check(obj, scale=0.05) -> dict:
    """Blender's own use of the attachment:
    (1) the "Attach Hair Curves to Surface" node group (from Blender's hair assets), told to sample
        the UV at each root itself, must find the UVs the add-on stored in surface_uv_coordinate;
    (2) the result's "Surface Deform" modifier (Deform Curves on Surface, driven by the stored UVs)
        must carry the hair along when the scalp deforms: here it grows by `scale`."""
    cv = obj.data
    surf = cv.surface
    assets = Path(bpy.utils.system_resource("DATAFILES")) / "assets"
    # Blender 5.0 keeps the hair node assets in assets/nodes, 4.2-4.5 in assets/geometry_nodes
    path = next((p for p in (assets / d / "procedural_hair_node_assets.blend" for d in ("nodes", "geometry_nodes"))
                 if p.is_file()), assets / "nodes" / "procedural_hair_node_assets.blend")
    with bpy.data.libraries.load(str(path), link=False) as (src, dst):
        dst.node_groups = [n for n in src.node_groups if n == "Attach Hair Curves to Surface"]
    ng = dst.node_groups[0]
    items = [it for it in ng.interface.items_tree if it.item_type == "SOCKET"]
    inputs = {(it.name, it.socket_type): it.identifier for it in items if it.in_out == "INPUT"}
    ids = {name: ident for (name, _), ident in inputs.items()}
    uv_out = next(it.identifier for it in items if it.in_out == "OUTPUT" and it.name == "Surface UV Coordinate")
    mod = obj.modifiers.new("attach", "NODES")
    mod.node_group = ng
    mod[inputs[("Surface", "NodeSocketObject")]] = surf
    mod[ids["Surface UV Map"] + "_use_attribute"] = True
    mod[ids["Surface UV Map"] + "_attribute_name"] = cv.surface_uv_map
    mod[ids["Sample Attachment UV"]] = True
    mod[ids["Snap to Surface"]] = False
    mod[ids["Align to Surface Normal"]] = False
    mod[uv_out + "_attribute_name"] = "blender_uv"
    bpy.context.view_layer.update()
    ecv = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    out = {"attach_inputs": sorted(ids)}
    n = len(cv.curves)
    ours = np.empty(n * 2, np.float32)
    cv.attributes["surface_uv_coordinate"].data.foreach_get("vector", ours)
    a = ecv.attributes.get("blender_uv")
    out["blender_uv_domain"] = a.domain if a else None
    if a is not None:
        vals = np.empty(len(a.data) * 3, np.float32)
        a.data.foreach_get("vector", vals)
        vals = vals.reshape(len(a.data), 3)
        if a.domain == "POINT":  # one value per point: take the roots
            off = np.empty(n + 1, np.int32)
            cv.curve_offset_data.foreach_get("value", off)
            vals = vals[off[:-1]]
        diff = np.abs(vals[:, :2] - ours.reshape(-1, 2)).max(axis=1)
        out["uv_vs_blender_median"] = float(np.median(diff))
        out["uv_vs_blender_p99"] = float(np.quantile(diff, 0.99))
    obj.modifiers.remove(mod)
    bpy.data.node_groups.remove(ng)

    deform = [m.name for m in obj.modifiers if m.type == "NODES" and m.node_group and any(
        nd.bl_idname == "GeometryNodeDeformCurvesOnSurface" for nd in m.node_group.nodes)]
    out["deform_modifiers"] = deform
    out["rest_position"] = bool(surf.add_rest_position_attribute)
    p0 = np.empty(len(cv.points) * 3, np.float32)
    cv.attributes["position"].data.foreach_get("vector", p0)

    def evaluated():
        bpy.context.view_layer.update()
        e = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
        p = np.empty(len(e.points) * 3, np.float32)
        e.attributes["position"].data.foreach_get("vector", p)
        return (p - p0).reshape(-1, 3)

    out["still_max_mm"] = float(1000 * np.abs(evaluated()).max())
    # scale the scalp by (1 + scale) about its origin with a Geometry Nodes modifier: each root's
    # surface point s moves by scale * s, a different vector per curve, so a curve attached through
    # a wrong UV (a wrong triangle) would move wrongly; the frames do not rotate, so every point of
    # a curve moves like its root
    gn = bpy.data.node_groups.new("scale scalp", "GeometryNodeTree")
    gn.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    gn.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi, go, tr = gn.nodes.new("NodeGroupInput"), gn.nodes.new("NodeGroupOutput"), gn.nodes.new("GeometryNodeTransform")
    tr.inputs["Scale"].default_value = (1.0 + scale,) * 3
    gn.links.new(gi.outputs[0], tr.inputs[0])
    gn.links.new(tr.outputs[0], go.inputs[0])
    smod = surf.modifiers.new("scale", "NODES")
    smod.node_group = gn
    d = evaluated()
    surf.modifiers.remove(smod)
    bpy.data.node_groups.remove(gn)
    off = np.empty(n + 1, np.int32)
    cv.curve_offset_data.foreach_get("value", off)
    roots = p0.reshape(-1, 3)[off[:-1]].astype(np.float64)  # curves-local = surface-local
    want = np.repeat(scale * roots, np.diff(off), axis=0)
    err = np.linalg.norm(d - want, axis=1)
    out["moved_err_max_mm"] = float(1000 * err.max())
    out["moved_mean_mm"] = float(1000 * np.linalg.norm(d, axis=1).mean())
    return out


def clear_scene():
    """Removes the startup scene's objects (its 2 m cube would enclose the test cameras)."""
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    for coll in (bpy.data.meshes, bpy.data.cameras, bpy.data.lights, bpy.data.materials):
        for db in list(coll):
            coll.remove(db)


def new_result_objects(before: dict) -> list:
    return [bpy.data.objects[n] for n in sorted(set(snapshot()["objects"]) - set(before["objects"]))]


def curves_world(ob) -> tuple[np.ndarray, np.ndarray]:
    """A Curves object's points in world space and its strands' point counts."""
    cv = ob.data
    pos = np.empty(len(cv.points) * 3, np.float32)
    cv.attributes["position"].data.foreach_get("vector", pos)
    m = np.array(ob.matrix_world, np.float64)
    counts = np.array([c.points_length for c in cv.curves], np.int64)
    return pos.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3], counts


def point_radius(ob) -> np.ndarray | None:
    """A Curves object's per-point radius (m), or None without one."""
    a = ob.data.attributes.get("radius")
    if a is None:
        return None
    r = np.empty(len(a.data), np.float32)
    a.data.foreach_get("value", r)
    return r


def read_back_interchange(interchange: dict) -> dict:
    """Imports each exported Alembic/USD file into an empty scene and compares its hair with what was
    exported: strand and point counts, the largest point deviation in world space (m)."""
    world, counts = interchange["strands"]
    radius = interchange["radius"]
    out = {}
    for ext, op in ((".abc", "alembic_import"), (".usdc", "usd_import")):
        e = dict(interchange[ext])
        if not e["error"]:
            bpy.ops.wm.read_factory_settings(use_empty=True)
            res, err = run_op(getattr(bpy.ops.wm, op), filepath=e["file"])
            e.update(import_result=res, import_error=err)
            got = [o for o in bpy.context.scene.objects if o.type == "CURVES"]
            e["objects"] = [(o.name, o.type) for o in bpy.context.scene.objects]
            if len(got) == 1:
                w, c = curves_world(got[0])
                r = point_radius(got[0])
                e.update(curves=int(len(c)), points=int(len(w)), counts_equal=bool(np.array_equal(c, counts)),
                         max_diff_m=float(np.abs(w - world).max()) if w.shape == world.shape else None,
                         radius_max_diff_m=float(np.abs(r - radius).max()) if r is not None and r.shape == radius.shape
                         else None)
        out[ext] = e
    out["curves"], out["points"] = int(len(counts)), int(len(world))
    return out


def make_scalp_group() -> int:
    """A "scalp" vertex group on the head mesh: its vertices within 3 mm of the scalp mesh."""
    from mathutils.bvhtree import BVHTree

    s = bpy.context.scene.hairrecon
    head, scalp = s.head_object, s.scalp_object
    bvh = BVHTree.FromObject(scalp, bpy.context.evaluated_depsgraph_get())
    m_h, m_s_inv = head.matrix_world, scalp.matrix_world.inverted()
    near = []
    for v in head.data.vertices:
        hit = bvh.find_nearest(m_s_inv @ (m_h @ v.co))
        if hit[0] is not None and hit[3] < 0.003:
            near.append(v.index)
    vg = head.vertex_groups.new(name="scalp")
    vg.add(near, 1.0, "REPLACE")
    return len(near)


def base_scene(tmp: Path):
    """A tiny valid scene: a camera with a photo (a generated image) looking at a raw mesh sphere
    with a scalp cap; bad-input cases each break one thing of it."""
    scene = bpy.context.scene
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 96, 100
    cams = bpy.data.collections.new("Cams")
    scene.collection.children.link(cams)
    cd = bpy.data.cameras.new("cam0")
    co = bpy.data.objects.new("cam0", cd)
    co.location = (0.0, -1.0, 0.0)
    co.rotation_euler = (math.pi / 2, 0.0, 0.0)
    cams.objects.link(co)
    img = bpy.data.images.new("photo0", 64, 96)
    img.pixels.foreach_set(np.full(64 * 96 * 4, 0.5, np.float32))
    bg = cd.background_images.new()
    bg.image = img
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.1)
    raw = bpy.context.active_object
    raw.name = "raw"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.09)
    scalp = bpy.context.active_object
    scalp.name = "scalp"
    s = scene.hairrecon
    s.camera_collection, s.raw_mesh, s.scalp_object = cams, raw, scalp
    s.scalp_source, s.photo_folder, s.mask_folder = "OBJECT", "", ""
    configure({"guides": 10, "children": 10})
    return {"cams": cams, "cam": co, "raw": raw, "scalp": scalp, "image": img}


def camera_roundtrip(capture: Path, scene) -> dict:
    """The largest differences between capture.json's K, R, t and those of the scene's cameras of the same
    names, converted back by the add-on."""
    from importlib import import_module

    spec = json.loads((Path(capture) / "capture.json").read_text())
    pkg = extension_package()
    sr = import_module(pkg.__name__ + ".scene_read")
    cam_mod = import_module(pkg.__name__ + ".core.camera")
    worst_k = worst_rt = 0.0
    for v in spec["views"]:
        pin = cam_mod.opencv_from_blender(sr.blender_camera(bpy.data.objects[v["name"]], scene))
        worst_k = max(worst_k, float(np.abs(pin.K - np.array(v["K"])).max()))
        worst_rt = max(worst_rt, float(np.abs(pin.R - np.array(v["R"])).max()), float(np.abs(pin.t - np.array(v["t"])).max()))
    return {"K_max_abs": worst_k, "Rt_max_abs": worst_rt}
