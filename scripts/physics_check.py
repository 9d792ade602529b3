#!/usr/bin/env python3
"""Test Hair Physics on a saved reconstruction, and on its ground truth the same way.

    .venv/bin/python scripts/physics_check.py out/demo/result/scene.blend [--gt out/demo/gt.hair]
        [--strands 400] [--frames 48] [--json physics.json] [--gif physics.gif --gif-height 240]
    blender -b scene.blend -P scripts/physics_check.py -- [same options]

Runs the extension's Test Hair Physics (Blender's hair dynamics while the head turns ±45° and nods) on the
.blend's reconstructed strands (the hair Curves object that is not the guides) with the Hair panel's Head
as collider, then, with --gt, on the ground-truth strands bound to the same scalp, with the same seed,
sample size and motion. Prints the measures side by side (and writes them with --json); --gif renders
both simulations with Cycles into one animated GIF (ours left, ground truth right; needs Pillow).
Exits 1 with one ``error: ...`` line when the scene lacks what the check needs.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from blender_batch import Failure, ensure_addon, script_args  # noqa: E402

ROWS = (
    ("exploded", "exploded", "{}"),
    ("root_max_mm", "roots off their binding, max (mm)", "{:.4f}"),
    ("stretch_median_pct", "segment stretch, median (%)", "{:.2f}"),
    ("stretch_p95_pct", "each strand's largest stretch, 95th percentile (%)", "{:.1f}"),
    ("stretch_max_pct", "largest stretch of any segment (%)", "{:.1f}"),
    ("inside_max_pct", "points inside the head, worst frame (%)", "{:.2f}"),
    ("inside_depth_max_mm", "deepest point inside the head (mm)", "{:.1f}"),
    ("tip_motion_median_mm", "tips moved from rest, median (mm)", "{:.0f}"),
)


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="physics_check.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("blend", nargs="?", type=Path, help="the .blend with a reconstruction (omit under blender -b)")
    ap.add_argument("--hair", help="name of the hair Curves object (default: the one not named '... Guides')")
    ap.add_argument("--gt", type=Path, help="ground-truth strands (.hair/.data/.ply) to simulate the same way")
    ap.add_argument("--strands", type=int, default=400)
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--points", type=int, default=17, choices=(9, 17, 33))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, help="write the measures here")
    ap.add_argument("--gif", type=Path, help="render both simulations into this animated GIF (Cycles, CPU)")
    ap.add_argument("--gif-height", type=int, default=240)
    ap.add_argument("--gif-samples", type=int, default=8)
    return ap.parse_args(argv)


def table(results: dict, package: str) -> str:
    names = list(results)
    lines = ["| measure | " + " | ".join(names) + " | bound |", "|---|" + "---:|" * len(names) + "---:|"]
    bounds = importlib.import_module(f"{package}.core.physics_measures").BOUNDS
    for key, label, fmt in ROWS:
        cells = [fmt.format(results[n].get(key, "-")) for n in names]
        bound = f"≤ {bounds[key]}" if key in bounds else ""
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {bound} |")
    return "\n".join(lines)


def render_gif(bpy, checks: list, names: list, out: Path, height: int, samples: int) -> None:
    """Each check's scene rendered frame by frame from the same camera (3/4 front, framing the head and
    hair), side by side and labelled with ``names``, as an animated GIF."""
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        raise Failure("--gif needs Pillow in this Python (pip install pillow)") from None
    import math
    import tempfile

    import numpy as np
    from mathutils import Vector

    frames_png = []
    tmp = Path(tempfile.mkdtemp(prefix="hairrecon_physics_"))
    for ci, check in enumerate(checks):
        scene = check.scene
        cam_data = check.created.add(bpy.data.cameras.new("Physics Camera"))
        cam = check.created.add(bpy.data.objects.new("Physics Camera", cam_data))
        scene.collection.objects.link(cam)
        # the head's pivot (the motion empty) is at the bottom of the head: look at 12 cm above it
        pivot = check.head.parent.location
        target = np.array([pivot[0], pivot[1], pivot[2] + 0.12])
        az = math.radians(-60.0)
        eye = target + 0.85 * np.array([math.cos(az), math.sin(az), 0.25])
        d = Vector(target - eye)
        cam.location = Vector(eye)
        cam.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
        cam_data.lens = 50
        light_data = check.created.add(bpy.data.lights.new("Physics Light", "SUN"))
        light = check.created.add(bpy.data.objects.new("Physics Light", light_data))
        light.rotation_euler = (math.radians(40), 0.0, math.radians(-30))
        light_data.energy = 3.0
        scene.collection.objects.link(light)
        world = check.created.add(bpy.data.worlds.new("Physics World"))
        world.color = (0.35, 0.35, 0.38)
        scene.world = world
        scene.camera = cam
        r = scene.render
        r.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = samples
        scene.cycles.use_denoising = False
        r.resolution_x, r.resolution_y, r.resolution_percentage = int(height * 4 / 3), height, 100
        r.image_settings.file_format = "PNG"
        # render_step: the render uses the same path points as the check
        for f in range(1, check.settings.frames + 1):
            scene.frame_set(f)
            r.filepath = str(tmp / f"{ci}_{f:04d}.png")
            with bpy.context.temp_override(scene=scene):
                bpy.ops.render.render(write_still=True, scene=scene.name)
        frames_png.append([tmp / f"{ci}_{f:04d}.png" for f in range(1, check.settings.frames + 1)])
    images = []
    for row in zip(*frames_png):
        parts = [Image.open(p).convert("RGB") for p in row]
        w = sum(p.width for p in parts) + 4 * (len(parts) - 1)
        im = Image.new("RGB", (w, parts[0].height), (255, 255, 255))
        x = 0
        draw = ImageDraw.Draw(im)
        for p, name in zip(parts, names):
            im.paste(p, (x, 0))
            draw.text((x + 6, 4), name, fill=(255, 255, 255))
            x += p.width + 4
        images.append(im.quantize(colors=128))
    out.parent.mkdir(parents=True, exist_ok=True)
    fps = checks[0].settings.fps
    images[0].save(out, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0, optimize=True)
    print(f"hairrecon: wrote {out}", flush=True)


def simulate(bpy, package: str, hair, gt, settings) -> tuple[dict, list]:
    """Test Hair Physics on ``hair`` and, when ``gt`` (points, counts) is given, on those strands bound to
    the same scalp; the Hair panel's Head collides. Returns the measures by name and the checks (their
    scenes stay, for --gif)."""
    import numpy as np

    physics = importlib.import_module(f"{package}.physics")
    measures = importlib.import_module(f"{package}.core.physics_measures")
    context = bpy.context
    head = physics.head_for(context, hair)
    subjects = [("ours", hair)]
    if gt is not None:
        build = importlib.import_module(f"{package}.scene_build")
        pts, counts = gt
        cv = build.new_hair_curves("ground truth", np.asarray(pts, np.float32).reshape(-1, 3), np.asarray(counts), 4e-5, 1e-5)
        obj = bpy.data.objects.new("ground truth", cv)
        context.scene.collection.objects.link(obj)
        cv.surface = hair.data.surface
        subjects.append(("ground truth", obj))
    results, checks = {}, []
    try:
        for name, obj in subjects:
            print(f"hairrecon: simulating {name} ({obj.name!r}, {settings.strands} strands, {settings.frames} frames)",
                  flush=True)
            try:
                check = physics.PhysicsCheck(context, obj, head, settings)
            except physics.UserError as e:
                raise Failure(str(e)) from None
            results[name] = check.run()
            checks.append(check)
            print(f"hairrecon: {name}: {measures.describe(results[name])}", flush=True)
    finally:
        if gt is not None:
            cv = subjects[1][1].data
            bpy.data.objects.remove(subjects[1][1])
            bpy.data.hair_curves.remove(cv)
    return results, checks


def run(a) -> dict:
    import bpy

    if a.blend is not None:
        if not a.blend.is_file():
            raise Failure(f"{a.blend} does not exist")
        bpy.ops.wm.open_mainfile(filepath=str(a.blend.resolve()))
    elif not bpy.data.filepath:
        raise Failure("no .blend given: pass the scene file (or run `blender -b scene.blend -P physics_check.py -- ...`)")
    package = ensure_addon(bpy)
    physics = importlib.import_module(f"{package}.physics")
    curves = [o for o in bpy.data.objects if o.type == "CURVES"]
    if a.hair:
        hair = bpy.data.objects.get(a.hair)
        if hair is None or hair.type != "CURVES":
            raise Failure(f"--hair: no hair Curves object named {a.hair!r} (there are {[o.name for o in curves]})")
    else:
        mine = [o for o in curves if not o.name.endswith("Guides") and o.data.surface is not None]
        if not mine:
            raise Failure(f"{bpy.data.filepath} holds no hair Curves object with a scalp surface")
        hair = mine[0]
    settings = physics.PhysicsSettings(strands=a.strands, frames=a.frames, points=a.points, seed=a.seed)
    gt = None
    if a.gt is not None:
        import hairrecon as hr

        if not a.gt.is_file():
            raise Failure(f"--gt: {a.gt} does not exist")
        gt = hr.read_strands(str(a.gt))
    results, checks = simulate(bpy, package, hair, gt, settings)
    print(table(results, package), flush=True)
    if a.json is not None:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"blend": bpy.data.filepath, "settings": vars(settings), "results": results}, indent=1))
    if a.gif is not None:
        render_gif(bpy, checks, list(results), a.gif, a.gif_height, a.gif_samples)
    return results


def main() -> int:
    a = parse_args(script_args())
    try:
        run(a)
    except Failure as e:
        print(f"error: {e}", file=sys.stderr, flush=True)
        return 1
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.exit(code)
