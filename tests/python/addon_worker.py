"""The Blender side of the add-on tests: ``python addon_worker.py TASK PARAMS_JSON``.

Run by addon_harness.run_worker in a fresh process with BLENDER_USER_RESOURCES set. Each task
prints ``RESULT {json}`` as its last line; the pytest side makes the assertions.
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
import time
import traceback
from pathlib import Path

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES was set by the harness)
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import addon_core  # noqa: E402  (the extension's bpy-free core as hairrecon_addon_core)


def load_core_camera():
    """addon/hairrecon/core/camera.py (it is bpy-free), from the repository."""
    return addon_core.load("camera")


# --- camera conversion ----------------------------------------------------------------------------


def task_camera(p):
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Euler, Vector

    cam_mod = load_core_camera()
    rng = np.random.default_rng(p.get("seed", 7))
    scene = bpy.context.scene
    data = bpy.data.cameras.new("cam")
    obj = bpy.data.objects.new("cam", data)
    scene.collection.objects.link(obj)
    cases = []
    for i in range(p.get("cameras", 40)):
        r = scene.render
        # sizes whose percentage is exact: world_to_camera_view scales by the unrounded size, while
        # Blender renders (and our K uses) the integer size res * pct // 100
        r.resolution_x = 4 * int(rng.integers(16, 500))
        r.resolution_y = 4 * int(rng.integers(16, 500))
        r.resolution_percentage = int(rng.choice([25, 50, 75, 100, 150, 200]))
        r.pixel_aspect_x = float(rng.choice([1.0, 1.0, 1.3, 2.0]))
        r.pixel_aspect_y = float(rng.choice([1.0, 1.0, 1.7]))
        data.lens = float(rng.uniform(12, 200))
        data.sensor_width = float(rng.uniform(10, 50))
        data.sensor_height = float(rng.uniform(8, 40))
        data.sensor_fit = str(rng.choice(["AUTO", "HORIZONTAL", "VERTICAL"]))
        data.shift_x = float(rng.uniform(-0.4, 0.4))
        data.shift_y = float(rng.uniform(-0.4, 0.4))
        obj.location = Vector(rng.uniform(-3, 3, 3).tolist())
        obj.rotation_euler = Euler(rng.uniform(-math.pi, math.pi, 3).tolist())
        obj.scale = Vector(rng.uniform(0.5, 2.0, 3).tolist())  # non-uniform scale must not matter
        bpy.context.view_layer.update()

        bc = cam_mod.BlenderCamera(
            name=obj.name, matrix_world=np.array(obj.matrix_world), lens=data.lens, sensor_width=data.sensor_width,
            sensor_height=data.sensor_height, sensor_fit=data.sensor_fit, shift_x=data.shift_x, shift_y=data.shift_y,
            resolution_x=r.resolution_x, resolution_y=r.resolution_y, resolution_percentage=r.resolution_percentage,
            pixel_aspect_x=r.pixel_aspect_x, pixel_aspect_y=r.pixel_aspect_y, type=data.type,
        )
        pin = cam_mod.opencv_from_blender(bc)
        # random points in front of the camera, within and around its view
        M = np.array(obj.matrix_world.normalized())
        n = 4000
        local = np.stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), -rng.uniform(0.5, 5, n)], axis=1)
        world = local @ M[:3, :3].T + M[:3, 3]
        uv, z = pin.project(world)
        W, H = pin.width, pin.height
        # keep points that land in the image or near it (up to half an image outside)
        inside = (uv[:, 0] > -0.5 * W) & (uv[:, 0] < 1.5 * W) & (uv[:, 1] > -0.5 * H) & (uv[:, 1] < 1.5 * H)
        world, uv, z = world[inside], uv[inside], z[inside]
        ref = []
        for q in world:
            v = world_to_camera_view(scene, obj, Vector(q.tolist()))
            ref.append((v.x * W - 0.5, (1.0 - v.y) * H - 0.5, v.z))
        ref = np.array(ref)
        err = np.abs(uv - ref[:, :2]).max()
        derr = np.abs(z - ref[:, 2]).max()
        # round trip: OpenCV -> Blender settings -> OpenCV
        s = cam_mod.blender_from_opencv(pin)
        back = cam_mod.BlenderCamera(
            name="rt", matrix_world=s.matrix_world, lens=s.lens, sensor_width=s.sensor_width, sensor_height=24.0,
            sensor_fit=s.sensor_fit, shift_x=s.shift_x, shift_y=s.shift_y, resolution_x=s.resolution_x,
            resolution_y=s.resolution_y, resolution_percentage=100, pixel_aspect_x=s.pixel_aspect_x,
            pixel_aspect_y=s.pixel_aspect_y,
        )
        pin2 = cam_mod.opencv_from_blender(back)
        uv2, _ = pin2.project(world)
        cases.append({
            "i": i, "points": int(len(world)), "max_px": float(err), "max_depth": float(derr), "roundtrip_px": float(np.abs(uv2 - uv).max()),
            "W": W, "H": H, "fit": data.sensor_fit, "pa": [r.pixel_aspect_x, r.pixel_aspect_y],
            "shift": [data.shift_x, data.shift_y], "lens": data.lens, "pct": r.resolution_percentage, "scale": list(obj.scale),
        })
    # a zero focal length (angle set to pi makes lens ~ 0) and an orthographic camera are refused
    errors = {}
    for label, setup in (("zero_focal", lambda d: setattr(d, "angle", math.pi)), ("ortho", lambda d: setattr(d, "type", "ORTHO"))):
        d = bpy.data.cameras.new(label)
        setup(d)
        bc = cam_mod.BlenderCamera(name=label, matrix_world=np.eye(4), lens=d.lens, sensor_width=d.sensor_width,
                                   sensor_height=d.sensor_height, sensor_fit=d.sensor_fit, type=d.type)
        try:
            cam_mod.opencv_from_blender(bc)
            errors[label] = None
        except cam_mod.CameraInputError as e:
            errors[label] = str(e)
    return {"cases": cases, "errors": errors}


# --- helpers for the extension tasks ---------------------------------------------------------------

DATA_KINDS = ("objects", "meshes", "hair_curves", "cameras", "images", "materials", "collections")


def snapshot() -> dict:
    """Names of the datablocks the add-on may touch, and each mesh's UV maps."""
    snap = {k: sorted(db.name for db in getattr(bpy.data, k)) for k in DATA_KINDS}
    snap["uv_maps"] = {m.name: [l.name for l in m.uv_layers] for m in bpy.data.meshes}
    return snap


_PACKAGE = {"name": "bl_ext.user_default.hairrecon"}


def install(zip_path: str) -> dict:
    """Installs the extension zip into the user folder (BLENDER_USER_RESOURCES) and enables it.
    Without a zip (development only), registers addon/hairrecon from the source tree instead."""
    import addon_utils

    if not zip_path:
        pkg = ROOT / "addon" / "hairrecon"
        spec = importlib.util.spec_from_file_location("hairrecon_addon", pkg / "__init__.py", submodule_search_locations=[str(pkg)])
        mod = importlib.util.module_from_spec(spec)
        sys.modules["hairrecon_addon"] = mod
        spec.loader.exec_module(mod)
        mod.register()
        _PACKAGE["name"] = "hairrecon_addon"
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
    roots_local = pos[off[:-1]]
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


def task_install(p):
    out = install(p["zip"])
    out["panels"] = [n for n in ("HAIRRECON_PT_reconstruct", "HAIRRECON_PT_advanced") if hasattr(bpy.types, n)]
    out["panel_category"] = getattr(getattr(bpy.types, "HAIRRECON_PT_reconstruct", None), "bl_category", None)
    out["operators"] = [n for n in ("reconstruct", "import_capture", "export_hair", "test_physics") if hasattr(bpy.ops.hairrecon, n)
                        and bpy.ops.hairrecon.__getattribute__(n).idname() == f"HAIRRECON_OT_{n}"]
    # quality presets fill in the counts; editing a count switches to Custom
    s = bpy.context.scene.hairrecon
    s.quality = "PREVIEW"
    preview = [s.guides, s.children, s.dr_iters_guides, s.dr_iters_children, s.dr, s.quality]
    s.guides = 123
    out["presets"] = {"preview": preview, "after_edit": [s.guides, s.quality]}
    return out


def task_pipeline(p):
    out = {"install": install(p.get("zip"))}
    interchange = None
    import hairrecon

    clear_scene()
    res, err = run_op(bpy.ops.hairrecon.import_capture, directory=p["capture"])
    out["import"] = {"result": res, "error": err, "snapshot": snapshot()}
    scene = bpy.context.scene
    s = scene.hairrecon
    out["panel_after_import"] = {
        "cameras": len([o for o in s.camera_collection.all_objects if o.type == "CAMERA"]) if s.camera_collection else 0,
        "raw_mesh": s.raw_mesh.name if s.raw_mesh else None,
        "scalp": s.scalp_object.name if s.scalp_object else None,
        "mask_folder": s.mask_folder,
        "resolution": [scene.render.resolution_x, scene.render.resolution_y],
        "scalp_uv_maps": [l.name for l in s.scalp_object.data.uv_layers] if s.scalp_object else [],
    }
    # the imported cameras give back the capture's K, R, t
    import json as _json

    spec = _json.loads((Path(p["capture"]) / "capture.json").read_text())
    pkg = extension_package()
    from importlib import import_module

    sr = import_module(pkg.__name__ + ".scene_read")
    cam_mod = import_module(pkg.__name__ + ".core.camera")
    worst_k = worst_rt = 0.0
    for v in spec["views"]:
        pin = cam_mod.opencv_from_blender(sr.blender_camera(bpy.data.objects[v["name"]], scene))
        worst_k = max(worst_k, float(np.abs(pin.K - np.array(v["K"])).max()))
        worst_rt = max(worst_rt, float(np.abs(pin.R - np.array(v["R"])).max()), float(np.abs(pin.t - np.array(v["t"])).max()))
    out["camera_roundtrip"] = {"K_max_abs": worst_k, "Rt_max_abs": worst_rt}

    configure(p)
    bpy.ops.ed.undo_push(message="scene ready")  # background mode starts without an undo system
    runs = []
    for run in range(2):
        before = snapshot()
        t0 = time.monotonic()
        # as from the UI: 'EXEC_DEFAULT' with undo=True pushes the operator's undo step
        res, err = run_op(bpy.ops.hairrecon.reconstruct, "EXEC_DEFAULT", True)
        objs = new_result_objects(before)
        runs.append({
            "before": before, "result": res, "error": err, "seconds": time.monotonic() - t0,
            "new": {k: sorted(set(snapshot()[k]) - set(before[k])) for k in DATA_KINDS},
            "gone": {k: sorted(set(before[k]) - set(snapshot()[k])) for k in DATA_KINDS},
            "curves": [curves_report(o) for o in objs if o.type == "CURVES"],
        })
        if err:
            break
    out["runs"] = runs
    session_mod = import_module(pkg.__name__ + ".session")

    def switch(name, keep):
        """The panel's default of the switch `name`, what the module's report shows with the keyword on
        and off (`keep` picks them), and the keyword the add-on passes for each panel setting."""
        report = {"panel_default": bool(getattr(s, name))}
        for flag in (True, False):
            r = hairrecon.reconstruct(p["capture"], str(Path(p["workdir"]) / f"{name}_{flag}"), guides=64,
                                      children=400, stop_after="init", **{name: flag})
            report[str(flag)] = keep({st["stage"]: st.get("stats") for st in r["report"]["stages"]})
        for flag in (False, True):
            setattr(s, name, flag)
            sess = session_mod.Session.prepare(bpy.context)
            try:
                report[f"session_{flag}"] = sess.options.get(name)
            finally:
                sess.cleanup()
        return report

    # the visual-hull switch, from the panel's setting to the module's keyword (the test capture's
    # masks are see-through, so the hull is built and skipped: hull_views 0; off: no hull at all)
    out["hull_switch"] = switch("hull_trim", lambda m: {k: v for k, v in m["init"].items() if k.startswith("hull")})
    # the partings switch, likewise (see-through masks: the partings are looked for in no view)
    out["parting_switch"] = switch("parting", lambda m: m["partings"])
    # the panel's Curls settings reach the keyword the add-on passes
    out["curl_switch"] = {"panel_default": s.curl}
    for mode, left in (("AUTO", False), ("OFF", False), ("CUSTOM", True)):
        s.curl, s.curl_radius_mm, s.curl_period_mm, s.curl_left = mode, 5.5, 18.0, left
        sess = session_mod.Session.prepare(bpy.context)
        try:
            out["curl_switch"][mode] = sess.options.get("curl")
        finally:
            sess.cleanup()
    s.curl = "AUTO"
    # Import Capture sets the head mesh beside the scalp object; the capture the add-on writes must
    # carry it (the visual hull and DR hide what lies behind the head, the output stays out of it)
    hd = Path(p["workdir"]) / "session_head"
    sess = session_mod.Session.prepare(bpy.context, str(hd))
    try:
        written = _json.loads((hd / "capture" / "capture.json").read_text())
        out["head_passed"] = {
            "scalp_source": s.scalp_source,
            "head_object": s.head_object.name if s.head_object else None,
            "head_mesh": written.get("head_mesh"),
            "head_ply": (hd / "capture" / str(written.get("head_mesh"))).is_file(),
        }
    finally:
        sess.cleanup()
    if runs and not runs[-1]["error"]:
        hair = [o for o in new_result_objects(out["import"]["snapshot"]) if o.type == "CURVES"]
        children = [o for o in hair if not o.name.endswith("Guides")]
        if children:
            out["attach_node"] = attach_node_check(children[0])
        # export the selected hair and read it back
        for o in bpy.context.view_layer.objects:
            o.select_set(False)
        target = children[0] if children else hair[0]
        target.select_set(True)
        bpy.context.view_layer.objects.active = target
        exp = {}
        for ext in (".hair", ".data", ".ply"):
            f = Path(p["workdir"]) / f"export{ext}"
            res, err = run_op(bpy.ops.hairrecon.export_hair, filepath=str(f))
            e = {"result": res, "error": err}
            if not err:
                pts, counts = hairrecon.read_strands(str(f))
                cv = target.data
                pos = np.empty(len(cv.points) * 3, np.float32)
                cv.attributes["position"].data.foreach_get("vector", pos)
                m = np.array(target.matrix_world)
                world = pos.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
                e.update(curves=int(len(counts)), points=int(len(pts)),
                         max_diff_m=float(np.abs(np.asarray(pts).reshape(-1, 3) - world).max()))
            exp[ext] = e
        res, err = run_op(bpy.ops.hairrecon.export_hair, filepath=str(Path(p["workdir"]) / "export.abc"))
        exp[".abc"] = {"result": res, "error": err}
        # Blender's own Alembic and USD exporters on the same object; read back at the end of the task
        interchange = {"strands": curves_world(target), "radius": point_radius(target)}
        for ext, op, kw in ((".abc", bpy.ops.wm.alembic_export, {"selected": True}),
                            (".usdc", bpy.ops.wm.usd_export, {"selected_objects_only": True})):
            f = Path(p["workdir"]) / f"interchange{ext}"
            res, err = run_op(op, filepath=str(f), **kw)
            interchange[ext] = {"file": str(f), "result": res, "error": err}
        out["export"] = exp
    if len(runs) == 2 and not runs[-1]["error"]:
        # undo (the operator has bl_options UNDO) takes the second result away again
        before_second = runs[-1]["before"]
        bpy.ops.ed.undo()
        after = snapshot()
        out["undo"] = {"restored": after == before_second,
                       "objects_left": sorted(set(after["objects"]) - set(out["import"]["snapshot"]["objects"]))}
    if runs and not runs[0]["error"]:
        # Test Hair Physics on a reconstruction that is left, and on the ground truth (worker_physics.py)
        import worker_physics

        hair = [o for o in bpy.context.scene.objects if o.type == "CURVES" and not o.name.endswith("Guides") and o.data.surface]
        if hair:
            out["physics"] = worker_physics.physics_checks(pkg.__name__, Path(p["capture"]), hair[0], run_op)
    if p.get("save_blend"):
        # a scene for the batch-script test: the capture imported, settings made, no results, and
        # a "scalp" vertex group on the head (the batch test reconstructs with it)
        for o in new_result_objects(out["import"]["snapshot"]):
            bpy.data.objects.remove(o)
        out["scalp_group_vertices"] = make_scalp_group()
        bpy.ops.wm.save_as_mainfile(filepath=p["save_blend"])
        out["saved"] = p["save_blend"]
    for r in runs:
        r.pop("before", None)
    if interchange is not None:
        out["interchange"] = read_back_interchange(interchange)
    return out


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


def task_inspect(p):
    """Opens a .blend and reports its hair Curves objects (for the batch-script test)."""
    bpy.ops.wm.open_mainfile(filepath=p["blend"])
    hair = [o for o in bpy.data.objects if o.type == "CURVES"]
    out = {"curves": [curves_report(o) for o in hair]}
    head = bpy.data.objects.get(p.get("head", "head"))
    out["head_uv_maps"] = [l.name for l in head.data.uv_layers] if head else None
    children = [o for o in hair if not o.name.endswith("Guides")]
    if children:
        out["attach_node"] = attach_node_check(children[0])
    return out


def task_cancel(p):
    out = {"install": install(p.get("zip"))}
    clear_scene()
    run_op(bpy.ops.hairrecon.import_capture, directory=p["capture"])
    configure(p)
    import hairrecon

    pkg = extension_package()
    from importlib import import_module

    Session = import_module(pkg.__name__ + ".session").Session
    before = snapshot()
    sess = Session.prepare(bpy.context)
    root = sess.root
    sess.start()
    time.sleep(float(p.get("cancel_after", 0.2)))
    sess.cancel()
    t0 = time.monotonic()
    sess.wait()
    out["stop_seconds"] = time.monotonic() - t0
    try:
        sess.finish(bpy.context)
        out["raised"] = None
    except hairrecon.Cancelled as e:
        out["raised"] = "Cancelled: " + str(e)
    except Exception as e:  # noqa: BLE001
        out["raised"] = f"{type(e).__name__}: {e}"
    out["unchanged"] = snapshot() == before
    out["temp_removed"] = not Path(root).exists()
    return out


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


def task_bad_inputs(p):
    out = {"install": install(p.get("zip"))}
    tmp = Path(p["workdir"])
    cases = {}

    def case(name, breaker):
        objs = base_scene(tmp)
        breaker(objs)
        bpy.context.view_layer.update()
        before = snapshot()
        res, err = run_op(bpy.ops.hairrecon.reconstruct)
        cases[name] = {"result": res, "error": err, "unchanged": snapshot() == before}

    def no_cameras(o):
        bpy.data.objects.remove(o["cam"])

    def no_photo(o):
        o["cam"].data.background_images.clear()

    def no_faces(o):
        me = bpy.data.meshes.new("points")
        me.from_pydata([(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)], [], [])
        pts = bpy.data.objects.new("points", me)
        bpy.context.scene.collection.objects.link(pts)
        bpy.context.scene.hairrecon.raw_mesh = pts

    def zero_focal(o):
        o["cam"].data.angle = math.pi  # Blender's own clamp lets this through: lens ~ 0 mm

    def ortho(o):
        o["cam"].data.type = "ORTHO"

    def no_scalp(o):
        bpy.context.scene.hairrecon.scalp_object = None

    for name, fn in (("no_cameras", no_cameras), ("no_photo", no_photo), ("no_faces", no_faces),
                     ("zero_focal", zero_focal), ("ortho", ortho), ("no_scalp", no_scalp)):
        case(name, fn)
    out["cases"] = cases

    # scenes that are fine: Session.prepare writes a capture the library accepts, changing nothing
    from importlib import import_module

    pkg = extension_package()
    Session = import_module(pkg.__name__ + ".session").Session
    import hairrecon

    def prepared(label, fn):
        objs = base_scene(tmp)
        extra = fn(objs) or {}
        before = snapshot()
        sess = Session.prepare(bpy.context)
        spec = json.loads((sess.capture_dir / "capture.json").read_text())
        info = {"views": [v["name"] for v in spec["views"]], **extra}
        info.update(check(sess, spec, extra) if "check" in extra else {})
        info.pop("check", None)
        sess.cleanup()
        info["unchanged"] = snapshot() == before
        prep[label] = info

    prep = {}
    prepared("baseline", lambda o: None)

    photo = (np.arange(96 * 64 * 3) % 251).astype(np.uint8).reshape(96, 64, 3)
    # A soft mask in a 16-bit PNG (as render_synthetic.py writes them): Blender reads it into a float
    # buffer, and the capture must keep its coverage, not encode it to sRGB (0.22 became 0.51).
    mask16 = np.zeros((96, 64), np.uint16)
    mask16[20:60, 10:50] = 65535
    mask16[60:70, 10:50] = round(0.22 * 65535)
    mask = (mask16 / 65535.0 * 255.0 + 0.5).astype(np.uint8)

    def folders(o):
        (tmp / "photos").mkdir(exist_ok=True)
        (tmp / "masks").mkdir(exist_ok=True)
        hairrecon.write_image(str(tmp / "photos" / "cam0.png"), photo)
        hairrecon.write_image(str(tmp / "masks" / "cam0.png"), mask16)
        o["cam"].data.background_images.clear()
        s = bpy.context.scene.hairrecon
        s.photo_folder, s.mask_folder = str(tmp / "photos"), str(tmp / "masks")
        return {"check": True}

    def check(sess, spec, extra):
        v = spec["views"][0]
        out = {}
        if "mask" in v:
            img = bpy.data.images.load(str(sess.capture_dir / v["image"]))
            px = np.empty(64 * 96 * 4, np.float32)
            img.pixels.foreach_get(px)
            got = (px.reshape(96, 64, 4)[::-1, :, :3] * 255 + 0.5).astype(np.uint8)
            bpy.data.images.remove(img)
            out["image_equal"] = bool(np.array_equal(got, photo))
            m = bpy.data.images.load(str(sess.capture_dir / v["mask"]))
            m.colorspace_settings.is_data = True
            px = np.empty(64 * 96 * 4, np.float32)
            m.pixels.foreach_get(px)
            gotm = (px.reshape(96, 64, 4)[::-1, :, 0] * 255 + 0.5).astype(np.uint8)
            bpy.data.images.remove(m)
            out["mask_equal"] = bool(np.array_equal(gotm, mask))
        if extra.get("group_triangles"):
            sc = hairrecon.read_mesh(str(sess.capture_dir / spec["scalp_mesh"]))
            out["scalp_triangles"] = int(len(sc["triangles"]))
            out["scalp_has_uv"] = sc.get("uvs") is not None
            out["head_mesh"] = bool(spec.get("head_mesh"))
        return out

    prepared("folders", folders)

    def vertex_group(o):
        bpy.ops.mesh.primitive_ico_sphere_add(radius=0.09, subdivisions=3)
        head = bpy.context.active_object
        head.name = "head"
        me = head.data
        while me.uv_layers:
            me.uv_layers.remove(me.uv_layers[0])
        vg = head.vertex_groups.new(name="scalp")
        top = [v.index for v in me.vertices if v.co.z > 0.03]
        vg.add(top, 1.0, "REPLACE")
        s = bpy.context.scene.hairrecon
        s.scalp_source, s.head_object, s.scalp_vertex_group = "VERTEX_GROUP", head, "scalp"
        topset = set(top)
        me.calc_loop_triangles()
        n = sum(all(i in topset for i in t.vertices) for t in me.loop_triangles)
        return {"group_triangles": n, "check": True}

    prepared("vertex_group", vertex_group)
    out["prepare"] = prep
    return out


def task_import_colmap(p):
    """File > Import > COLMAP Model on a hand-written model (colmap_fixture.py, written by the test):
    first with a photo missing (one error, nothing changed or written), then the whole model, then
    again into the now non-empty capture folder."""
    out = {"install": install(p.get("zip"))}
    clear_scene()
    scene = bpy.context.scene

    def run(model, **kw):
        before = snapshot()
        res, err = run_op(bpy.ops.hairrecon.import_colmap, filepath=str(Path(model["sparse"]) / "cameras.txt"),
                          photos_folder=model["images"], mesh_file=model["mesh"], height=p["height"], **kw)
        return {"result": res, "error": err, "unchanged": snapshot() == before}

    bad = p["bad"]
    out["missing_photo"] = run(bad)
    out["missing_photo"]["written"] = sorted(q.name for q in Path(bad["sparse"]).iterdir())
    out["missing_photo"]["resolution"] = [scene.render.resolution_x, scene.render.resolution_y]
    out["good"] = run(p["good"], capture_folder=p["capture"])
    s = scene.hairrecon
    out["cameras"] = sorted(o.name for o in s.camera_collection.all_objects if o.type == "CAMERA") if s.camera_collection else []
    out["resolution"] = [scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage]
    out["raw_mesh"] = s.raw_mesh.name if s.raw_mesh else None
    out["raw_mesh_faces"] = len(s.raw_mesh.data.polygons) if s.raw_mesh else 0
    out["photos"] = sorted(
        Path(o.data.background_images[0].image.filepath).name for o in s.camera_collection.all_objects
        if o.type == "CAMERA" and o.data.background_images
    ) if s.camera_collection else []
    # the imported cameras give back capture.json's K, R, t
    spec = json.loads((Path(p["capture"]) / "capture.json").read_text())
    pkg = extension_package()
    from importlib import import_module

    sr = import_module(pkg.__name__ + ".scene_read")
    cam_mod = import_module(pkg.__name__ + ".core.camera")
    worst_k = worst_rt = 0.0
    for v in spec["views"]:
        pin = cam_mod.opencv_from_blender(sr.blender_camera(bpy.data.objects[v["name"]], scene))
        worst_k = max(worst_k, float(np.abs(pin.K - np.array(v["K"])).max()))
        worst_rt = max(worst_rt, float(np.abs(pin.R - np.array(v["R"])).max()), float(np.abs(pin.t - np.array(v["t"])).max()))
    out["camera_roundtrip"] = {"K_max_abs": worst_k, "Rt_max_abs": worst_rt}
    out["again"] = run(p["good"], capture_folder=p["capture"])
    return out


def task_fit_head(p):
    """Fit Head on an imported capture (the bundled head moved by a similarity, tests/python/fit_fixture.py):
    the fitted scalp object against the true scalp; then on a sphere's capture: one error, nothing changed."""
    out = {"install": install(p.get("zip"))}
    import hairrecon

    clear_scene()
    run_op(bpy.ops.hairrecon.import_capture, directory=p["good"])
    s = bpy.context.scene.hairrecon
    out["before"] = {"scalp": s.scalp_object.name if s.scalp_object else None}
    t0 = time.monotonic()
    out["result"], out["error"] = run_op(bpy.ops.hairrecon.fit_head)
    out["fit_seconds"] = time.monotonic() - t0
    scalp = bpy.data.objects.get("Fitted Scalp")
    head = bpy.data.objects.get("Fitted Head")
    coll = bpy.data.collections.get("Fitted Head")
    out["collection"] = sorted(o.name for o in coll.objects) if coll else None
    out["linked"] = coll is not None and coll.name in bpy.context.scene.collection.children
    out["panel"] = {"source": s.scalp_source, "scalp": s.scalp_object.name if s.scalp_object else None,
                    "head": s.head_object.name if s.head_object else None}
    if scalp is not None and head is not None:
        me = scalp.data
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        m = np.array(scalp.matrix_world)
        world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        truth = hairrecon.read_mesh(p["truth_scalp"])["vertices"].astype(np.float64)
        out["scalp_vertices"] = [len(world), len(truth)]
        if len(world) == len(truth):
            err = np.linalg.norm(world - truth, axis=1) / float(p["scale"]) * 1e3
            out["scalp_err_mm"] = {"mean": float(err.mean()), "max": float(err.max())}
        out["head_faces"] = len(head.data.polygons)
        # Reconstruct Hair's preparation takes the fitted scalp and head into its capture
        from importlib import import_module

        Session = import_module(extension_package().__name__ + ".session").Session
        sess = Session.prepare(bpy.context)
        try:
            spec = json.loads((sess.capture_dir / "capture.json").read_text())
            written = hairrecon.read_mesh(str(sess.capture_dir / spec["scalp_mesh"]))
            out["session"] = {"surface": sess.surface_name, "head_mesh": spec.get("head_mesh"),
                              "scalp_triangles": int(len(written["triangles"])),
                              "scalp_has_uv": written["uvs"] is not None,
                              "frame": spec.get("frame"), "to_canonical": spec.get("to_canonical")}
        finally:
            sess.cleanup()

    # a sphere does not fit: one error, the scene and the panel as they were
    run_op(bpy.ops.hairrecon.import_capture, directory=p["sphere"])
    panel = (s.scalp_source, s.scalp_object, s.head_object)
    before = snapshot()
    out["sphere_result"], out["sphere_error"] = run_op(bpy.ops.hairrecon.fit_head)
    out["sphere_unchanged"] = snapshot() == before and (s.scalp_source, s.scalp_object, s.head_object) == panel
    return out


def task_colmap_flow(p):
    """The flow for a photogrammetry project, as a user runs it in a fresh scene: File > Import > COLMAP
    Model (hairrecon), Fit Head, Reconstruct Hair (colmap_fixture.colmap_from_capture of a fit_fixture
    capture: the bundled head with a hair shell in another frame, photos, no masks, head or scalp).
    Between Fit Head and the reconstruction that succeeds: a run whose photo went missing (one error,
    nothing changed) and a cancelled run (nothing changed)."""
    out = {"install": install(p.get("zip"))}
    clear_scene()
    scene = bpy.context.scene
    s = scene.hairrecon
    model = p["model"]

    def step(op, *args, **kw):
        """Runs an operator; its result, error, time and what it added to or removed from bpy.data."""
        before = snapshot()
        t0 = time.monotonic()
        res, err = run_op(op, *args, **kw)
        after = snapshot()
        return {"result": res, "error": err, "seconds": time.monotonic() - t0, "unchanged": after == before,
                "new": {k: sorted(set(after[k]) - set(before[k])) for k in DATA_KINDS},
                "gone": {k: sorted(set(before[k]) - set(after[k])) for k in DATA_KINDS}}

    out["import"] = step(bpy.ops.hairrecon.import_colmap, filepath=str(Path(model["sparse"]) / "cameras.txt"),
                         photos_folder=model["images"], mesh_file=model["mesh"], height=int(p["height"]),
                         capture_folder=p["capture"])
    cams = sorted(o.name for o in s.camera_collection.all_objects if o.type == "CAMERA") if s.camera_collection else []
    out["panel_after_import"] = {
        "cameras": cams, "raw_mesh": s.raw_mesh.name if s.raw_mesh else None,
        "raw_mesh_faces": len(s.raw_mesh.data.polygons) if s.raw_mesh else 0,
        "scalp": s.scalp_object.name if s.scalp_object else None, "head": s.head_object.name if s.head_object else None,
        "mask_folder": s.mask_folder, "photo_folder": s.photo_folder,
        "resolution": [scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage],
    }
    out["fit"] = step(bpy.ops.hairrecon.fit_head)
    out["panel_after_fit"] = {"source": s.scalp_source, "scalp": s.scalp_object.name if s.scalp_object else None,
                              "head": s.head_object.name if s.head_object else None}
    configure(p)

    # a photo of the capture folder went missing (the background image of the last camera): one error
    # that names the camera and the file, nothing changed
    cam = bpy.data.objects[cams[-1]]
    photo = Path(bpy.path.abspath(cam.data.background_images[0].image.filepath))
    aside = Path(p["workdir"]) / ("aside" + photo.suffix)
    photo.rename(aside)
    out["missing_photo"] = dict(step(bpy.ops.hairrecon.reconstruct), camera=cam.name, photo=str(photo))
    aside.rename(photo)
    # the file is back; Blender tried to read it once and failed, so the image is reloaded (Image > Reload)
    image = cam.data.background_images[0].image
    out["missing_photo"]["size_before_reload"] = list(image.size)
    image.reload()
    out["missing_photo"]["size_after_reload"] = list(image.size)

    # a cancelled run, as the operator's Esc cancels it (task_cancel): the job is cancelled while the
    # library runs, then finished on the main thread
    import hairrecon
    from importlib import import_module

    prepare = import_module(extension_package().__name__ + ".session").Session.prepare
    before = snapshot()
    job = prepare(bpy.context)
    root = job.root
    job.start()
    time.sleep(float(p.get("cancel_after", 0.5)))
    job.cancel()
    t0 = time.monotonic()
    job.wait()
    out["cancel"] = {"stop_seconds": time.monotonic() - t0}
    try:
        job.finish(bpy.context)
        out["cancel"]["raised"] = None
    except hairrecon.Cancelled as e:
        out["cancel"]["raised"] = "Cancelled: " + str(e)
    except Exception as e:  # noqa: BLE001
        out["cancel"]["raised"] = f"{type(e).__name__}: {e}"
    out["cancel"]["unchanged"] = snapshot() == before
    out["cancel"]["temp_removed"] = not Path(root).exists()

    # the reconstruction
    run = out["reconstruct"] = step(bpy.ops.hairrecon.reconstruct)
    hair = [bpy.data.objects[n] for n in run["new"]["objects"] if bpy.data.objects[n].type == "CURVES"]
    out["curves"] = [curves_report(o) for o in hair]
    # the roots and the scalp's triangles in world space (the scene's frame), for the exact distance
    out["roots"], out["tips"], out["lengths"] = {}, {}, {}
    for o in hair:
        cv = o.data
        pos = np.empty(len(cv.points) * 3, np.float32)
        cv.attributes["position"].data.foreach_get("vector", pos)
        m = np.array(o.matrix_world)
        world = pos.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        off = np.empty(len(cv.curves) + 1, np.int32)
        cv.curve_offset_data.foreach_get("value", off)
        out["roots"][o.name] = world[off[:-1]].tolist()
        out["tips"][o.name] = world[off[1:] - 1].tolist()
        seg = np.linalg.norm(np.diff(world, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        out["lengths"][o.name] = (cum[off[1:] - 1] - cum[off[:-1]]).tolist()
    scalp = bpy.data.objects.get("Fitted Scalp")
    if scalp is not None:
        from mathutils.bvhtree import BVHTree

        me = scalp.data
        me.calc_loop_triangles()
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        m = np.array(scalp.matrix_world)
        world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        tri = np.empty(len(me.loop_triangles) * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tri)
        tri = tri.reshape(-1, 3)
        out["scalp_vertices"], out["scalp_triangles"] = world.tolist(), tri.tolist()
        # the tips' distances to the scalp, to check the test's exact distance on distances that are not 0
        bvh = BVHTree.FromPolygons(world.tolist(), tri.tolist(), all_triangles=True)
        out["tip_dist_bvh"] = {n: [bvh.find_nearest(q)[3] for q in tips] for n, tips in out["tips"].items()}
    return out


TASKS = {
    "camera": task_camera,
    "install": task_install,
    "pipeline": task_pipeline,
    "cancel": task_cancel,
    "bad_inputs": task_bad_inputs,
    "fit_head": task_fit_head,
    "inspect": task_inspect,
    "import_colmap": task_import_colmap,
    "colmap_flow": task_colmap_flow,
}


def main():
    task, params = sys.argv[1], json.loads(sys.argv[2]) if len(sys.argv) > 2 else {}
    t0 = time.monotonic()
    try:
        out = TASKS[task](params)
    except Exception:
        traceback.print_exc()
        sys.exit(2)
    out["seconds"] = time.monotonic() - t0
    print("RESULT " + json.dumps(out, default=str), flush=True)


if __name__ == "__main__":
    main()
