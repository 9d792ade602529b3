"""The Blender side of the add-on tests: ``python addon_worker.py TASK PARAMS_JSON``.

Run by addon_harness.run_worker in a fresh process with BLENDER_USER_RESOURCES set. Each task
prints ``RESULT {json}`` as its last line; the pytest side makes the assertions. The shared helpers
are in worker_common.py, the photogrammetry tasks in worker_capture.py, Test Hair Physics in
worker_physics.py.
"""

from __future__ import annotations

import json
import math
import sys
import time
import traceback
from pathlib import Path

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES was set by the harness)
import numpy as np

from worker_capture import task_colmap_flow, task_fit_head, task_import_colmap  # noqa: E402
from worker_common import (  # noqa: E402
    DATA_KINDS,
    attach_node_check,
    base_scene,
    camera_roundtrip,
    clear_scene,
    configure,
    curves_report,
    curves_world,
    extension_package,
    install,
    load_core_camera,
    make_scalp_group,
    new_result_objects,
    point_radius,
    read_back_interchange,
    run_op,
    snapshot,
)


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
    out["camera_roundtrip"] = camera_roundtrip(Path(p["capture"]), scene)
    import json as _json

    pkg = extension_package()
    from importlib import import_module

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

    def switch(name):
        """The panel's default of the switch `name` and the keyword the add-on passes for each panel
        setting (what the keyword does in the library: test_switches.py)."""
        report = {"panel_default": bool(getattr(s, name))}
        for flag in (False, True):
            setattr(s, name, flag)
            sess = session_mod.Session.prepare(bpy.context)
            try:
                report[f"session_{flag}"] = sess.options.get(name)
            finally:
                sess.cleanup()
        return report

    out["hull_switch"] = switch("hull_trim")
    out["parting_switch"] = switch("parting")
    # the panel's Curls settings reach the keyword the add-on passes
    out["curl_switch"] = {"panel_default": s.curl}
    for mode, left in (("AUTO", False), ("OFF", False), ("CUSTOM", True), ("COILS", False)):
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
