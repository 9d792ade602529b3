#!/usr/bin/env python3
"""Batch hair reconstruction of a .blend scene set up with the hairrecon extension's Hair panel.

    blender -b scene.blend -P scripts/reconstruct.py -- --out DIR [options]
    .venv/bin/python scripts/reconstruct.py scene.blend --out DIR [options]     (the bpy module)

Loads the scene, runs ``bpy.ops.hairrecon.reconstruct()`` synchronously with the settings saved in
the .blend (Hair panel) or the overrides below, and writes into DIR:

    scene.blend         the scene with the hair Curves objects added
    strands.hair        the strands (children), world space, root to tip
    guides.hair         the guide strands
    summary.json        objects, strand counts, root distances, stage times, the run's report (scores with ground truth)
                        (before DR: "init_strands"; after: "dr_strands")
    render.png          with --render: a Cycles picture of the result from a scene camera (with
                        --render-before and --render-gt, the strands before DR and the ground truth
                        the same way; --render-pair puts them side by side)
    physics.json        with --physics: Test Hair Physics's measures (the strands, and the ground truth with
                        --gt-strands), as scripts/physics_check.py prints them
    capture/, result/   the capture folder written from the scene and the library's own output
                        (result/init_strands.hair: the strands before DR; result/loss.csv, loss.png)

Progress goes to stdout; on failure it prints one ``error: ...`` line to stderr and exits 1.
The add-on comes from the installed extension (bl_ext.*.hairrecon), else from this source tree
(``addon/hairrecon``, with the ``hairrecon`` Python module installed in the running Python).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))  # under `blender -P` the script's folder is not on the path
from blender_batch import Failure, ensure_addon, script_args  # noqa: E402


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="reconstruct.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("blend", nargs="?", type=Path, help="the .blend to load (omit under `blender -b scene.blend`)")
    ap.add_argument("--out", type=Path, required=True, help="output folder (created)")
    ap.add_argument("--cameras", help="name of the collection of cameras")
    ap.add_argument("--raw-mesh", help="name of the raw mesh object")
    ap.add_argument("--scalp", help="name of the scalp mesh object")
    ap.add_argument("--head", help="name of the head mesh object: with --scalp-group its vertex group is the scalp; "
                    "with a scalp object it hides the strands behind it and keeps them out of it")
    ap.add_argument("--scalp-group", help="vertex group of --head that is the scalp")
    ap.add_argument("--photos", help="folder of photos named after the cameras")
    ap.add_argument("--masks", help="folder of hair masks named after the cameras")
    ap.add_argument("--quality", choices=["PREVIEW", "STANDARD", "HIGH"])
    ap.add_argument("--guides", type=int)
    ap.add_argument("--children", type=int)
    ap.add_argument("--no-dr", action="store_true",
                    help="keep the grown strands: no optimization by differentiable rendering (DR)")
    ap.add_argument("--dr-iters-guides", type=int, help="DR steps on the guides")
    ap.add_argument("--dr-iters-children", type=int, help="DR steps on every strand after the guides")
    ap.add_argument("--no-hull-trim", action="store_true",
                    help="keep the grown strands whole where a photo sees them outside its hair mask")
    ap.add_argument("--no-parting", action="store_true",
                    help="do not look for partings (where the photos see the scalp's skin)")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--stop-after", help="stop the pipeline after this stage")
    ap.add_argument("--render", type=Path, help="also render the result with Cycles (CPU) to this PNG")
    ap.add_argument("--render-camera", help="camera for --render (default: the scene camera)")
    ap.add_argument("--render-height", type=int, default=512, help="picture height in pixels (default 512)")
    ap.add_argument("--render-samples", type=int, default=32)
    ap.add_argument("--render-no-denoise", action="store_true",
                    help="keep the picture's Monte Carlo noise (by default it is denoised with OpenImageDenoise "
                         "where this Blender's Cycles has it)")
    ap.add_argument("--render-before", type=Path,
                    help="with --render: also render the strands before DR (result/init_strands.hair) the same way")
    ap.add_argument("--render-pair", type=Path,
                    help="with --render and --render-before: the pictures side by side, before on the left "
                         "(ground truth, before, after with --render-gt)")
    ap.add_argument("--gt-strands", type=Path,
                    help="ground-truth strands (.hair, .data, .ply or .obj; e.g. a synthetic capture's gt/strands.hair) "
                         "for --render-gt")
    ap.add_argument("--render-gt", type=Path,
                    help="with --render: also render --gt-strands the same way (the result's material, strand radii, "
                         "camera and settings) to this PNG")
    ap.add_argument("--render-fit", type=float, default=0.0,
                    help="frame the head and hair: a picture camera from the chosen camera's side, at a distance "
                         "where they fill this share of the picture height (e.g. 0.8; 0 = the camera as it is)")
    ap.add_argument("--physics", type=Path,
                    help="then run Test Hair Physics on the strands (and on --gt-strands, the same way) and write its "
                         "measures to this JSON (scripts/physics_check.py does it for a saved scene)")
    ap.add_argument("--physics-strands", type=int, default=400, help="strands simulated by --physics (default 400)")
    return ap.parse_args(argv)


def apply_overrides(bpy, a):
    s = bpy.context.scene.hairrecon

    def obj(name, what):
        o = bpy.data.objects.get(name)
        if o is None:
            raise Failure(f"--{what}: the scene has no object named {name!r}")
        return o

    if a.cameras:
        c = bpy.data.collections.get(a.cameras)
        if c is None:
            raise Failure(f"--cameras: the scene has no collection named {a.cameras!r}")
        s.camera_collection = c
    if a.raw_mesh:
        s.raw_mesh = obj(a.raw_mesh, "raw-mesh")
    if a.scalp:
        s.scalp_source, s.scalp_object = "OBJECT", obj(a.scalp, "scalp")
    if a.scalp_group:
        if not a.head:
            raise Failure("--scalp-group needs --head, the mesh whose vertex group it is")
        if a.scalp:
            raise Failure("give the scalp either as an object (--scalp) or as a vertex group (--head, --scalp-group)")
        s.scalp_source, s.scalp_vertex_group = "VERTEX_GROUP", a.scalp_group
    if a.head:
        s.head_object = obj(a.head, "head")
    if a.photos:
        s.photo_folder = str(Path(a.photos).resolve())
    if a.masks:
        s.mask_folder = str(Path(a.masks).resolve())
    if a.quality:
        s.quality = a.quality
    for k in ("guides", "children", "dr_iters_guides", "dr_iters_children"):
        if getattr(a, k) is not None:
            s.quality = "CUSTOM"
            setattr(s, k, getattr(a, k))
    if a.no_dr:
        s.dr = False
    if a.no_hull_trim:
        s.hull_trim = False
    if a.no_parting:
        s.parting = False
    if a.seed is not None:
        s.seed = a.seed
    if a.stop_after is not None:
        s.stop_after = a.stop_after


def write_strands(hr, path: Path, obj):
    import numpy as np

    cv = obj.data
    p = np.empty(len(cv.points) * 3, np.float32)
    cv.attributes["position"].data.foreach_get("vector", p)
    off = np.empty(len(cv.curves) + 1, np.int32)
    cv.curve_offset_data.foreach_get("value", off)
    m = np.array(obj.matrix_world, np.float64)
    world = (p.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    hr.write_strands(str(path), np.ascontiguousarray(world), np.diff(off).astype(np.uint32))


def framing_camera(bpy, cam, hair, meshes, fill):
    """A new camera on the line from the centre of the hair and meshes to ``cam``, aimed at it, at the
    distance where the hair and the given meshes fill ``fill`` of the picture height."""
    import numpy as np
    from mathutils import Vector

    pts = []
    for o in hair:
        p = np.empty(len(o.data.points) * 3, np.float32)
        o.data.attributes["position"].data.foreach_get("vector", p)
        m = np.array(o.matrix_world)
        pts.append(p.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3])
    for o in meshes:
        p = np.empty(len(o.data.vertices) * 3, np.float32)
        o.data.vertices.foreach_get("co", p)
        m = np.array(o.matrix_world)
        pts.append(p.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3])
    pts = np.concatenate(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = Vector(((lo + hi) / 2).tolist())
    radius = float(np.linalg.norm(pts - np.array(centre), axis=1).max())
    data = cam.data.copy()
    data.shift_x = data.shift_y = 0.0
    pic = bpy.data.objects.new("hairrecon picture", data)
    bpy.context.scene.collection.objects.link(pic)
    direction = (cam.matrix_world.translation - centre).normalized()
    r = bpy.context.scene.render
    # vertical field of view of the camera under the scene's render settings
    import math

    half = math.atan(0.5 * data.sensor_width / data.lens) * (r.resolution_y / r.resolution_x if data.sensor_fit != "VERTICAL" else 1.0)
    dist = radius / math.tan(half) / fill
    pic.location = centre + direction * dist
    pic.rotation_euler = (centre - pic.location).to_track_quat("-Z", "Y").to_euler()
    data.clip_start, data.clip_end = dist * 0.01, dist * 10
    return pic


def render_picture(bpy, a, hair):
    """A Cycles picture of the head and the new hair; the raw mesh is hidden. Runs after the
    result was saved, so the saved scene keeps its own render settings."""
    scene = bpy.context.scene
    s = scene.hairrecon
    cam = bpy.data.objects.get(a.render_camera) if a.render_camera else scene.camera
    if cam is None or cam.type != "CAMERA":
        raise Failure(f"--render-camera: no camera named {a.render_camera!r}" if a.render_camera else
                      "--render: the scene has no camera; pass --render-camera")
    if a.render_fit > 0:
        cam = framing_camera(bpy, cam, hair, [o for o in (s.head_object, s.scalp_object) if o is not None], a.render_fit)
    scene.camera = cam
    # show the hair, the head and the scalp: hide the raw mesh, the guides and everything else
    keep = {o.name for o in hair if not o.name.endswith("Guides")}
    keep |= {o.name for o in (s.head_object, s.scalp_object) if o is not None}
    keep |= {o.data.surface.name for o in hair if o.data.surface is not None}
    for o in scene.objects:
        if o.type in {"MESH", "CURVES", "CURVE", "SURFACE", "META", "FONT", "VOLUME", "POINTCLOUD"}:
            o.hide_render = o.name not in keep
    r = scene.render
    r.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = a.render_samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = not a.render_no_denoise and oidn_available()
    if scene.cycles.use_denoising:
        scene.cycles.denoiser = "OPENIMAGEDENOISE"
    r.resolution_percentage = max(1, round(100 * a.render_height / r.resolution_y))
    r.film_transparent = False
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    import warnings

    with warnings.catch_warnings():  # World.use_nodes: needed up to 4.x, deprecated in 5.0
        warnings.simplefilter("ignore", DeprecationWarning)
        scene.world.use_nodes = True
    bg = scene.world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (0.45, 0.46, 0.5, 1.0)
        bg.inputs["Strength"].default_value = 1.0
    r.image_settings.file_format = "PNG"
    return render_to(bpy, a.render, cam)


def oidn_available() -> bool:
    """Whether this Blender's Cycles was built with OpenImageDenoise (the CPU denoiser)."""
    try:
        import _cycles
    except ImportError:
        return False
    return bool(getattr(_cycles, "with_openimagedenoise", False))


def render_to(bpy, path: Path, cam) -> str:
    r = bpy.context.scene.render
    r.filepath = str(path.resolve())
    path.parent.mkdir(parents=True, exist_ok=True)
    print(f"hairrecon: rendering {r.filepath} from {cam.name!r}", flush=True)
    bpy.ops.render.render(write_still=True)
    return r.filepath


def render_before(bpy, hr, a, hair, init_strands: Path) -> str:
    """Renders the strands before DR in place of the result's (same camera and settings): the
    positions of the strands object are swapped for ``init_strands`` (DR keeps every strand's point
    count), rendered to --render-before, and swapped back."""
    import numpy as np

    obj = next(o for o in hair if not o.name.endswith("Guides"))
    cv = obj.data
    pts, counts = hr.read_strands(str(init_strands))
    off = np.empty(len(cv.curves) + 1, np.int32)
    cv.curve_offset_data.foreach_get("value", off)
    if not np.array_equal(np.diff(off), np.asarray(counts, np.int64)):
        raise Failure(f"{init_strands} does not have the result's strands and point counts")
    after = np.empty(len(cv.points) * 3, np.float32)
    cv.attributes["position"].data.foreach_get("vector", after)
    inv = np.linalg.inv(np.array(obj.matrix_world, np.float64))
    local = (np.asarray(pts, np.float64).reshape(-1, 3) @ inv[:3, :3].T + inv[:3, 3]).astype(np.float32)
    cv.attributes["position"].data.foreach_set("vector", local.ravel())
    cv.update_tag()
    try:
        return render_to(bpy, a.render_before, bpy.context.scene.camera)
    finally:
        cv.attributes["position"].data.foreach_set("vector", after)
        cv.update_tag()


def check_gt_args(a):
    """Refuses --render-gt without what it needs, before anything runs."""
    if a.render_gt is None:
        return
    if a.render is None:
        raise Failure("--render-gt needs --render (it renders the ground truth from the same camera)")
    if a.gt_strands is None:
        raise Failure("--render-gt needs --gt-strands, the ground-truth strand file to render")
    if not a.gt_strands.is_file():
        raise Failure(f"--gt-strands: {a.gt_strands} does not exist")


def read_gt(a):
    """The --gt-strands file as (points, counts), read before the reconstruction so that a bad file
    fails at once; None without --render-gt."""
    if a.render_gt is None:
        return None
    import hairrecon as hr

    try:
        return hr.read_strands(str(a.gt_strands))
    except Exception as e:  # the library's reader says what is wrong with the file
        raise Failure(f"--gt-strands: {a.gt_strands}: {e}") from None


def render_gt(bpy, package: str, a, hair, gt) -> str:
    """Renders the ground-truth strands ``gt`` in place of the result's: a temporary Curves object with
    the result's material and root/tip radii, from the same camera with the same settings; the
    object is removed afterwards and the result shown again."""
    import importlib

    import numpy as np

    build = importlib.import_module(f"{package}.scene_build")
    obj = next(o for o in hair if not o.name.endswith("Guides"))
    radius = np.empty(len(obj.data.points), np.float32)
    obj.data.attributes["radius"].data.foreach_get("value", radius)
    first = obj.data.curves[0].points_length
    pts, counts = gt
    cv = build.new_hair_curves("hairrecon ground truth", np.asarray(pts, np.float32).reshape(-1, 3),
                               np.asarray(counts), float(radius[0]), float(radius[first - 1]))
    ref = None
    hidden = obj.hide_render
    try:
        for m in obj.data.materials:
            cv.materials.append(m)
        ref = bpy.data.objects.new("hairrecon ground truth", cv)
        bpy.context.scene.collection.objects.link(ref)
        obj.hide_render = True
        return render_to(bpy, a.render_gt, bpy.context.scene.camera)
    finally:
        obj.hide_render = hidden
        if ref is not None:
            bpy.data.objects.remove(ref)
        bpy.data.hair_curves.remove(cv)


# a 3x5 pixel font for the labels of the side-by-side pictures
_GLYPHS = {
    "A": "010 101 111 101 101", "B": "110 101 110 101 110", "D": "110 101 101 101 110",
    "E": "111 100 110 100 111", "F": "111 100 110 100 100", "I": "111 010 010 010 111",
    "N": "110 101 101 101 101", "O": "111 101 101 101 111", "R": "110 101 110 101 101",
    "T": "111 010 010 010 010", " ": "000 000 000 000 000", "(": "001 010 010 010 001",
    ")": "100 010 010 010 100", "G": "111 100 101 101 111", "H": "101 101 111 101 101",
    "U": "101 101 101 101 111",
}


def _label(img, text: str, scale: int):
    """Draws white-on-black ``text`` into the top-left corner of ``img`` (H, W, 4 floats, top row first)."""
    x0 = y0 = 2 * scale
    img[: 9 * scale, : (4 * len(text) + 3) * scale, :3] = 0.0
    for i, ch in enumerate(text.upper()):
        rows = _GLYPHS.get(ch, _GLYPHS[" "]).split()
        for r, bits in enumerate(rows):
            for c, bit in enumerate(bits):
                if bit == "1":
                    y, x = y0 + r * scale, x0 + (4 * i + c) * scale
                    img[y:y + scale, x:x + scale, :3] = 1.0


def render_pair(bpy, panels: list[tuple[Path, str]], out: Path) -> str:
    """The pictures ``panels`` (path, label) side by side, labelled, as one PNG."""
    import numpy as np

    imgs = []
    for p, label in panels:
        im = bpy.data.images.load(str(p), check_existing=False)
        w, h = im.size
        px = np.empty(w * h * 4, np.float32)
        im.pixels.foreach_get(px)
        bpy.data.images.remove(im)
        top_first = px.reshape(h, w, 4)[::-1].copy()
        _label(top_first, label, max(2, h // 160))
        imgs.append(top_first)
    h = max(i.shape[0] for i in imgs)
    gap = np.ones((h, max(4, h // 100), 4), np.float32)
    pair = np.concatenate([x for im in imgs for x in (gap, im)][1:], axis=1)
    out.parent.mkdir(parents=True, exist_ok=True)
    im = bpy.data.images.new("hairrecon panels", pair.shape[1], pair.shape[0], alpha=True)
    im.pixels.foreach_set(np.ascontiguousarray(pair[::-1]).ravel())
    im.filepath_raw = str(out.resolve())
    im.file_format = "PNG"
    im.save()
    bpy.data.images.remove(im)
    print(f"hairrecon: wrote {out}", flush=True)
    return str(out)


def run(a) -> dict:
    check_gt_args(a)
    import bpy

    if a.blend is not None:
        if not a.blend.is_file():
            raise Failure(f"{a.blend} does not exist")
        bpy.ops.wm.open_mainfile(filepath=str(a.blend.resolve()))
    elif not bpy.data.filepath:
        raise Failure("no .blend given: pass the scene file (or run `blender -b scene.blend -P reconstruct.py -- ...`)")
    package = ensure_addon(bpy)
    gt = read_gt(a)  # the library is importable once the add-on is
    print(f"hairrecon: add-on {package}; scene {bpy.data.filepath}", flush=True)
    apply_overrides(bpy, a)
    out = a.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    before = {o.name for o in bpy.data.objects}
    try:
        bpy.ops.hairrecon.reconstruct(output_directory=str(out))
    except RuntimeError as e:
        msg = str(e).strip()
        msg = msg[len("Error: "):] if msg.startswith("Error: ") else msg
        raise Failure(msg.splitlines()[0] if msg else "the reconstruction failed") from None
    new = [bpy.data.objects[n] for n in sorted({o.name for o in bpy.data.objects} - before)]
    hair = [o for o in new if o.type == "CURVES"]
    if not hair:
        raise Failure("the reconstruction added no hair objects")
    import hairrecon as hr

    last = getattr(sys.modules.get(f"{package}.operators"), "LAST_SUMMARY", {}) or {}
    summary = {"blend": bpy.data.filepath, "objects": [o.name for o in hair],
               "seconds": last.get("seconds"), "stage_times": last.get("stage_times", []),
               "report": last.get("report", {})}
    for o in hair:
        key = "guides" if o.name.endswith("Guides") else "strands"
        path = out / f"{key}.hair"
        write_strands(hr, path, o)
        summary[key] = {"object": o.name, "count": len(o.data.curves), "points": len(o.data.points), "file": str(path)}
        if key in last:
            summary[key]["max_root_distance_m"] = last[key].get("max_root_distance_m")
    bpy.ops.wm.save_as_mainfile(filepath=str(out / "scene.blend"), copy=True)
    summary["saved"] = str(out / "scene.blend")
    if a.render is not None:
        summary["render"] = render_picture(bpy, a, hair)
        init = out / "result" / "init_strands.hair"
        if a.render_gt is not None:
            summary["render_gt"] = render_gt(bpy, package, a, hair, gt)
        if a.render_before is not None:
            if not init.is_file():
                raise Failure(f"--render-before: {init} does not exist (did DR run?)")
            summary["render_before"] = render_before(bpy, hr, a, hair, init)
            if a.render_pair is not None:
                panels = [(a.render_before, "before DR (init)"), (a.render, "after DR")]
                if a.render_gt is not None:
                    panels.insert(0, (a.render_gt, "ground truth"))
                summary["render_pair"] = render_pair(bpy, panels, a.render_pair)
    if a.physics is not None:
        import physics_check

        physics = importlib.import_module(f"{package}.physics")
        strands = next(o for o in hair if not o.name.endswith("Guides"))
        gt_strands = hr.read_strands(str(a.gt_strands)) if a.gt_strands is not None else None
        settings = physics.PhysicsSettings(strands=a.physics_strands)
        try:
            results, checks = physics_check.simulate(bpy, package, strands, gt_strands, settings)
        except Failure as e:
            raise Failure(f"--physics: {e}") from None
        for c in checks:
            c.remove()
        print(physics_check.table(results, package), flush=True)
        a.physics.parent.mkdir(parents=True, exist_ok=True)
        a.physics.write_text(json.dumps({"blend": summary["saved"], "settings": vars(settings), "results": results}, indent=1))
        summary["physics"] = {"file": str(a.physics), **{k: v["ok"] for k, v in results.items()}}
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return summary


def main() -> int:
    a = parse_args(script_args())
    try:
        summary = run(a)
    except Failure as e:
        print(f"error: {e}", file=sys.stderr, flush=True)
        return 1
    print(f"hairrecon: wrote {summary['saved']} and " + ", ".join(
        f"{summary[k]['count']} {k} to {summary[k]['file']}" for k in ("strands", "guides") if k in summary), flush=True)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.exit(code)
