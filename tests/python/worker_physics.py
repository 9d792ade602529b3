"""The add-on worker's part for Test Hair Physics (imported by addon_worker.py, runs inside Blender).

On the pipeline task's reconstruction and on the capture's ground truth bound to the same scalp: the
operator without a head (one error, nothing changed), the operator on each (its measures, the scene it
adds, the user's scene untouched), and a check removed after a few frames (what Esc and a failure do).
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import bpy
import numpy as np

KINDS = ("objects", "meshes", "hair_curves", "materials", "particles", "actions", "scenes", "collections")


def datablocks() -> dict:
    return {k: sorted(db.name for db in getattr(bpy.data, k)) for k in KINDS}


def scene_state(scene) -> dict:
    """What the user's scene holds: its objects with their transforms, frame range and current frame."""
    return {
        "objects": sorted((o.name, [round(x, 9) for row in o.matrix_world for x in row]) for o in scene.objects),
        "frame": scene.frame_current,
        "range": [scene.frame_start, scene.frame_end],
        "window_scene": bpy.context.window.scene.name if bpy.context.window else None,
    }


def remove_new(before: dict):
    """Deletes the datablocks made since ``before`` (a finished check's scene and what it holds)."""
    after = datablocks()
    for k in ("scenes", "objects", "particles", "actions", "hair_curves", "meshes", "materials"):
        coll = getattr(bpy.data, k)
        for name in set(after[k]) - set(before[k]):
            if name in coll:
                coll.remove(coll[name])


def physics_checks(package: str, capture: Path, hair, run_op, frames: int = 24, strands: int = 200) -> dict:
    physics = importlib.import_module(f"{package}.physics")
    import hairrecon

    import time

    t0 = time.monotonic()
    out = {}
    scene = bpy.context.scene
    s = scene.hairrecon
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    hair.select_set(True)
    bpy.context.view_layer.objects.active = hair

    # no head to collide with: one clear error, nothing made
    head = s.head_object
    s.head_object = None
    before, state = datablocks(), scene_state(scene)
    res, err = run_op(bpy.ops.hairrecon.test_physics, strands=strands, frames=frames)
    out["no_head"] = {"result": res, "error": err, "unchanged": datablocks() == before and scene_state(scene) == state}
    s.head_object = head

    # a check stopped after a few frames (Esc, or a failure) removes everything it made
    before, state = datablocks(), scene_state(scene)
    check = physics.PhysicsCheck(bpy.context, hair, head, physics.PhysicsSettings(strands=strands, frames=frames))
    made = {k: sorted(set(v) - set(before[k])) for k, v in datablocks().items()}
    for _ in range(3):
        check.step()
    check.remove()
    out["removed"] = {"made": made, "unchanged": datablocks() == before and scene_state(scene) == state}

    # the reconstruction, then the ground truth bound to the same scalp, the same way
    spec = json.loads((capture / "capture.json").read_text())
    pts, counts = hairrecon.read_strands(str(capture / spec["gt_strands"]))
    build = importlib.import_module(f"{package}.scene_build")
    cv = build.new_hair_curves("ground truth", np.asarray(pts, np.float32).reshape(-1, 3), np.asarray(counts), 4e-5, 1e-5)
    cv.surface = hair.data.surface
    gt = bpy.data.objects.new("ground truth", cv)
    scene.collection.objects.link(gt)
    for name, obj in (("ours", hair), ("ground_truth", gt)):
        for o in bpy.context.view_layer.objects:
            o.select_set(False)
        obj.select_set(True)
        bpy.context.view_layer.objects.active = obj
        before, state = datablocks(), scene_state(scene)
        res, err = run_op(bpy.ops.hairrecon.test_physics, strands=strands, frames=frames)
        new = {k: sorted(set(v) - set(before[k])) for k, v in datablocks().items()}
        out[name] = {
            "result": res, "error": err, "summary": dict(physics.LAST_SUMMARY), "new": new,
            "scene_unchanged": scene_state(scene) == state,
        }
        if not err:
            ps = bpy.data.scenes[physics.SCENE_NAME]
            emitter = next(o for o in ps.objects if o.particle_systems)
            out[name]["particles"] = len(emitter.particle_systems[0].particles)
            out[name]["dynamics"] = bool(emitter.particle_systems[0].use_hair_dynamics)
            out[name]["collider"] = [o.name for o in ps.objects if any(m.type == "COLLISION" for m in o.modifiers)]
        remove_new(before)
    bpy.data.objects.remove(gt)
    bpy.data.hair_curves.remove(cv)
    out["seconds"] = time.monotonic() - t0
    return out
