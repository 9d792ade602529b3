"""The add-on worker's tasks for photogrammetry projects (runs inside Blender): File > Import > COLMAP,
Fit Head, and the whole flow from a COLMAP model to hair."""

from __future__ import annotations

import json
import time
from pathlib import Path

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES was set by the harness)
import numpy as np

from worker_common import DATA_KINDS, camera_roundtrip, clear_scene, configure, curves_report, extension_package, install, run_op, snapshot


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
    out["camera_roundtrip"] = camera_roundtrip(Path(p["capture"]), scene)
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

    # landmarks as empties, on the good capture again: the viewer's left taken for the subject's is one
    # error naming the empties, nothing changed; two empties for one landmark too; placed right (one
    # named as a user might, "Nose Tip"), the fit starts from them and its scalp lies on the true one
    run_op(bpy.ops.hairrecon.import_capture, directory=p["good"])
    swap = {"eye_outer_left": "eye_outer_right", "eye_outer_right": "eye_outer_left",
            "ear_left": "ear_right", "ear_right": "ear_left"}

    def place(names):
        made = []
        for name, xyz in p["landmarks"].items():
            e = bpy.data.objects.new(names.get(name, name), None)
            e.location = xyz
            bpy.context.scene.collection.objects.link(e)
            made.append(e)
        return made

    def remove(made):
        for e in made:
            bpy.data.objects.remove(e)

    made = place(swap)
    before = snapshot()
    out["swapped_result"], out["swapped_error"] = run_op(bpy.ops.hairrecon.fit_head)
    out["swapped_unchanged"] = snapshot() == before
    extra = bpy.data.objects.new("Chin", None)
    bpy.context.scene.collection.objects.link(extra)
    before = snapshot()
    out["twice_result"], out["twice_error"] = run_op(bpy.ops.hairrecon.fit_head)
    out["twice_unchanged"] = snapshot() == before
    bpy.data.objects.remove(extra)
    remove(made)
    made = place({"nose_tip": "Nose Tip"})
    out["landmarks_result"], out["landmarks_error"] = run_op(bpy.ops.hairrecon.fit_head)
    fitted = [o for o in bpy.data.objects if o.get("hairrecon_fitted") == "scalp" and o is not scalp]
    if len(fitted) == 1:
        me, m = fitted[0].data, np.array(fitted[0].matrix_world)
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        truth = hairrecon.read_mesh(p["truth_scalp"])["vertices"].astype(np.float64)
        out["landmarks_scalp_err_mm"] = float((np.linalg.norm(world - truth, axis=1) / float(p["scale"]) * 1e3).max())
    out["landmarks_fitted"] = len(fitted)
    remove(made)
    # Add Landmarks: an empty for each, where the panel's fitted head has it; a second click adds none;
    # the panel's line counts them
    from importlib import import_module

    line = import_module(extension_package().__name__ + ".ui")._landmarks_line
    out["landmarks_line_before"] = line(bpy.context.scene)
    res, err = run_op(bpy.ops.hairrecon.add_landmarks)
    out["landmarks_line_after"] = line(bpy.context.scene)
    coll = bpy.data.collections.get("Landmarks")
    added = {o.name: list(o.matrix_world.translation) for o in coll.objects} if coll else {}
    out["add_landmarks"] = {"result": res, "error": err, "added": added}
    out["add_landmarks_again"] = run_op(bpy.ops.hairrecon.add_landmarks)
    out["landmarks_after_again"] = len(coll.objects) if coll else 0
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
