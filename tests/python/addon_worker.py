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


def load_core_camera():
    """addon/hairrecon/core/camera.py as a plain module (it is bpy-free)."""
    path = ROOT / "addon" / "hairrecon" / "core" / "camera.py"
    spec = importlib.util.spec_from_file_location("hairrecon_core_camera", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


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

        from hairrecon_core_camera import BlenderCamera  # noqa: F401  (module registered above)

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


TASKS = {"camera": task_camera}


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
