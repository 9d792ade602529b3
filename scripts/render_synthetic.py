"""Render a synthetic multi-view capture of a hairstyle on a head with Blender Cycles.

Runs as ``.venv/bin/python scripts/render_synthetic.py ARGS`` (the ``bpy`` module) and as
``blender -b -P scripts/render_synthetic.py -- ARGS`` when Blender's Python has the ``hairrecon``
module (its wheel, target/wheels-hairrecon/): the library reads and writes every file. Input: any
``.hair`` file and the head PLY (metres, Z up, face toward -Y). Output: a capture folder that
``hairrecon_core::capture::Capture::load`` accepts, laid out as ``docs/capture-format.md`` describes:

    capture.json, images/, masks/, gt/orientation/, gt/depth/, gt/strands.hair, head.ply, scalp.ply,
    fusion/depth/ (depth maps for the raw mesh), raw_mesh.ply, scene.blend

The scene follows the paper's synthetic benchmark (Dr.Hair, supplement 1.1): a white uniform
environment, cameras evenly on the upper hemisphere around the head (a Fibonacci lattice), portrait
2:3 images, hair as Blender hair Curves with a Principled Hair BSDF. ``--background clutter`` adds a
textured room around the capture and a clothed torso under the head, as real photographs have them
(``synthetic_backdrop.py``); the default, ``uniform``, writes the same files as before the option existed.
``--wild`` writes, instead of a capture, a photogrammetry project as a user holds it (``synthetic_wild.py``):
JPEG photos at 3× ``--height`` with the clutter, a COLMAP text model and a noisy raw mesh with holes in a
random similarity frame, and the ground truth apart under ``gt/``.

Per view, one Cycles render gives the image, the depth (Cycles' Z pass: planar depth along the optical
axis, checked), and an AOV that carries, for every camera sample whose first hit is hair, the
doubled image angle of the strand there: (cos 2θ, sin 2θ, 1). Its pixel average is the hair coverage
(blue channel: the mask, anti-aliased, 0 where the head hides the hair) and the coverage-weighted mean
orientation. The projected angle is computed in the shader from the curve tangent and the position
in camera space, i.e. with the camera's Jacobian, so it is exact per sample.

``hairrecon fuse-depth`` then fuses depth maps into ``raw_mesh.ply``, the stand-in for a
photogrammetry mesh (``--fusion``, docs/capture-format.md): where the photographs show the hair as a
mostly opaque surface (mean mask coverage of hair pixels >= 0.5, e.g. 50,000 strands), the
photographs' own depth maps, with the pixels that hold hair but whose depth sample saw nothing marked
unknown, fused by a per-voxel median; where they do not (sparse hair, e.g. the 2,000-strand test
preset), a second, cheap render per view that draws the hair as camera-facing ribbons of a larger
radius, so that it closes into a surface, fused by the mean and moved inward by the ribbon radius.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

try:
    # The Rust library reads and writes every file here (.hair, PLY, PNG, OpenEXR, capture.json).
    import hairrecon
except ImportError as e:
    raise ImportError(
        f"render_synthetic.py needs the hairrecon Python module ({e}): run it with .venv/bin/python after "
        "scripts/setup_env.sh, or install target/wheels-hairrecon/hairrecon-*.whl into Blender's Python"
    ) from None

sys.path.insert(0, str(Path(__file__).resolve().parent))
# The Blender extension's bpy-free core, loaded as `hairrecon_addon_core` (scripts/addon_core.py): its
# Blender-to-OpenCV camera conversion and sRGB curve are the ones the extension uses.
import addon_core  # noqa: E402
import synthetic_backdrop  # noqa: E402
import synthetic_wild  # noqa: E402

camera = addon_core.load("camera")
linear_to_srgb = addon_core.load("capture").linear_to_srgb

REPO = Path(__file__).resolve().parent.parent

PRESETS = {
    # strands only matter to make_benchmark.py (it asks synth-hair for that many); views, height, samples here.
    "test": dict(strands=2000, views=16, height=256, samples=32),
    # 128 samples (32 before commit ab0286e): at 32 the sampling noise of the sub-pixel strands buries their
    # texture and the Gabor maps of the straight capture err by 19.3° over the hair, at 128 by 12.4° (README).
    "paper": dict(strands=50000, views=58, height=512, samples=128),
    # The colour study (issue 6: wavy in six colours): the paper's hair at about 0.3 of its render cost.
    "colors": dict(strands=50000, views=30, height=384, samples=32),
    # A phone video around the head (issue 53; the paper's hand-held capture): 60 frames on a ring at eye level,
    # rising and falling by up to 15 degrees, none from above; the colours preset's image size and samples.
    "handheld": dict(strands=50000, views=60, height=384, samples=32, rig="ring"),
}
# the cameras' layout when the preset names none: a Fibonacci lattice over the upper hemisphere
DEFAULT_RIG = "hemisphere"
# the ring rig's cameras rise and fall this many degrees about the head centre's height, twice around
RING_SPREAD_DEG = 15.0

# --fusion auto fuses the photographs' own depth when the hair pixels of the masks have at least this
# mean coverage (the hair looks like a surface), else wide-ribbon depth maps. Measured: 0.86 on the
# paper preset with 50,000 strands, 0.30 on the test preset with 2,000.
PHOTO_FUSION_MIN_COVERAGE = 0.5

# --wild renders the photos at this multiple of --height (the working height the import scales them to).
WILD_PHOTO_SCALE = 3

# Principled Hair BSDF settings per colour name: melanin-based or colour-based parametrization.
COLORS = {
    "black": dict(parametrization="MELANIN", melanin=0.95, redness=0.1),
    "brown": dict(parametrization="MELANIN", melanin=0.6, redness=0.35),
    "gold": dict(parametrization="MELANIN", melanin=0.22, redness=0.3),
    "gray": dict(parametrization="COLOR", color=(0.5, 0.5, 0.52)),
    "blue": dict(parametrization="COLOR", color=(0.04, 0.12, 0.6)),
    "red": dict(parametrization="COLOR", color=(0.65, 0.06, 0.03)),
}


def parse_args(argv=None):
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], prog="render_synthetic.py")
    p.add_argument("hair", type=Path, help="strands as Cem Yuksel's .hair")
    p.add_argument("head", type=Path, help="head mesh PLY (metres, Z up, face toward -Y)")
    p.add_argument("out", type=Path, help="capture folder to write (created; existing files are replaced)")
    p.add_argument("--scalp", type=Path, help="scalp mesh PLY to copy into the capture as scalp.ply")
    p.add_argument("--preset", choices=sorted(PRESETS), default="test")

    def by_preset(key):
        return ", ".join(f"{name} {prm[key]}" for name, prm in PRESETS.items())

    p.add_argument("--views", type=int, help=f"number of cameras (preset: {by_preset('views')})")
    p.add_argument("--height", type=int, help=f"image height in pixels, width = 2/3 of it ({by_preset('height')})")
    p.add_argument("--samples", type=int, help=f"Cycles samples per pixel ({by_preset('samples')})")
    p.add_argument("--color", choices=sorted(COLORS), default="brown", help="hair colour")
    p.add_argument("--seed", type=int, default=0, help="Cycles seed and colour randomness")
    p.add_argument(
        "--background",
        choices=["uniform", "clutter"],
        default="uniform",
        help="uniform: the white environment alone; clutter: a textured room behind and a clothed torso under "
        "the head, seeded by --seed (the room is cropped out of raw_mesh.ply, the torso kept)",
    )
    p.add_argument("--hair-scale", type=float, default=1.0, help="multiply hair coordinates (e.g. 0.01 for cm)")
    p.add_argument("--hair-up", choices=["z", "y"], default="z", help="the hair file's up axis (y: x,y,z -> x,-z,y)")
    p.add_argument(
        "--hair-axes",
        help="general axis map applied before scaling, e.g. 'z,-x,-y' (overrides --hair-up)",
    )
    p.add_argument("--hair-offset", type=float, nargs=3, default=(0.0, 0.0, 0.0), help="added after scaling (metres)")
    p.add_argument("--radius-mm", type=float, default=0.04, help="strand radius in millimetres")
    p.add_argument("--curve-shape", choices=["THICK", "RIBBONS"], default="THICK")
    p.add_argument("--distance", type=float, default=1.0, help="camera distance from the head centre (metres)")
    p.add_argument(
        "--min-elevation", type=float, default=0.0, help="lowest camera elevation in degrees above the head centre"
    )
    p.add_argument(
        "--rig",
        choices=["hemisphere", "ring"],
        help="camera layout: hemisphere (a Fibonacci lattice over the upper half, --min-elevation up) or ring (around "
        f"the head at its centre's height, rising and falling by {RING_SPREAD_DEG:g} degrees, like a phone video); "
        f"default: the preset's (handheld: ring, others: {DEFAULT_RIG})",
    )
    p.add_argument(
        "--fusion-radius-mm",
        type=float,
        help="hair radius for the fusion depth maps (default: half the median distance between neighbouring "
        "roots or half a pixel at the head, whichever is larger)",
    )
    p.add_argument(
        "--voxel-mm",
        type=float,
        help="TSDF voxel size for raw_mesh.ply (default: 1 with photo fusion, 2 with ribbons)",
    )
    p.add_argument(
        "--fusion",
        choices=["auto", "photo", "ribbons"],
        default="auto",
        help="depth maps for raw_mesh.ply: the photographs' own depth (photo) or wide-ribbon renders (ribbons); "
        f"auto: photo when the mean mask coverage of hair pixels is at least {PHOTO_FUSION_MIN_COVERAGE}",
    )
    p.add_argument("--hairrecon-bin", help="the hairrecon binary (default: target/release/hairrecon, then PATH)")
    p.add_argument("--no-fuse", action="store_true", help="skip raw_mesh.ply (run hairrecon fuse-depth later)")
    p.add_argument("--no-blend", action="store_true", help="do not save scene.blend")
    p.add_argument(
        "--skip-photos",
        action="store_true",
        help="redo only the fusion depth maps and the raw mesh of an existing capture (same arguments otherwise)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the views of an interrupted run whose photo, mask, gt orientation and gt depth all exist",
    )
    p.add_argument("--only-view", type=int, help="render only this view (for pictures); implies --no-fuse")
    p.add_argument(
        "--filter-width", type=float, default=1.5, help="Cycles pixel filter width in pixels (Blackman-Harris)"
    )
    p.add_argument("--threads", type=int, default=0, help="Cycles threads (0: all cores)")
    p.add_argument(
        "--wild",
        action="store_true",
        help="write OUT as a photogrammetry project instead of a capture: JPEG photos at 3x --height with "
        "--background clutter, a COLMAP text model (sparse/0) and mesh.ply in a random similarity frame (seeded "
        "by --seed), the ground truth under gt/ (scripts/synthetic_wild.py); import it with hairrecon import colmap",
    )
    p.add_argument(
        "--photo-scale",
        type=int,
        default=WILD_PHOTO_SCALE,
        help=f"with --wild: the photos' height as a multiple of --height (default {WILD_PHOTO_SCALE}; 1 renders a "
        "cheap project whose photos are at the working height)",
    )
    p.add_argument(
        "--keep-capture",
        action="store_true",
        help="with --wild: keep the rendered capture (canonical frame, ground-truth masks, head and scalp, photos "
        "at the project's size) as OUT/_capture, the same hair as the project for a side-by-side run",
    )
    a = p.parse_args(argv)
    if a.photo_scale < 1:
        p.error("--photo-scale must be at least 1")
    for k, v in PRESETS[a.preset].items():
        if k != "strands" and getattr(a, k) is None:
            setattr(a, k, v)
    if a.rig is None:
        a.rig = DEFAULT_RIG
    if a.wild:
        if a.no_fuse or a.only_view is not None or a.skip_photos:
            p.error("--wild needs the raw mesh of every view: no --no-fuse, --only-view or --skip-photos")
        a.height *= a.photo_scale
        a.background = "clutter"
        a.no_blend = True  # the scene is in the canonical frame, which the project does not know
    return a


# ---------------------------------------------------------------------------------------------
# Geometry helpers (no bpy)
# ---------------------------------------------------------------------------------------------


def map_axes(points: np.ndarray, spec: str) -> np.ndarray:
    """Applies an axis map like 'z,-x,-y': new x = old z, new y = -old x, new z = -old y."""
    cols = []
    for tok in spec.replace(" ", "").split(","):
        sign = -1.0 if tok.startswith("-") else 1.0
        cols.append(sign * points[:, "xyz".index(tok.lstrip("+-"))])
    if len(cols) != 3:
        raise SystemExit(f"--hair-axes {spec!r}: give three axes like 'z,-x,-y'")
    return np.stack(cols, axis=1)


def fibonacci_hemisphere(n: int, min_elevation_deg: float = 0.0) -> np.ndarray:
    """n unit directions spread evenly over the cap z >= sin(min_elevation) (a Fibonacci lattice)."""
    z0 = math.sin(math.radians(min_elevation_deg))
    i = np.arange(n) + 0.5
    z = z0 + (1.0 - z0) * i / n  # the first camera is the lowest
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = (i - 0.5) * math.pi * (3.0 - math.sqrt(5.0)) - math.pi / 2  # the first camera looks at the face (from -Y)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def ring(n: int, spread_deg: float = RING_SPREAD_DEG) -> np.ndarray:
    """n unit directions evenly around the vertical axis, the first toward the face (-Y), at elevations that
    rise and fall twice around between -spread and +spread degrees (a phone carried around the head)."""
    i = np.arange(n)
    phi = 2.0 * math.pi * i / n - math.pi / 2
    elev = np.radians(spread_deg) * np.sin(2.0 * math.pi * 2.0 * i / n)
    return np.stack([np.cos(elev) * np.cos(phi), np.cos(elev) * np.sin(phi), np.sin(elev)], axis=1)


def camera_directions(a) -> np.ndarray:
    """The unit directions from the head centre to the cameras, by ``--rig``."""
    if a.rig == "ring":
        return ring(a.views)
    return fibonacci_hemisphere(a.views, a.min_elevation)


def look_at_rt(eye: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV R, t of a camera at eye looking at target with world Z up in the image."""
    f = target - eye
    f /= np.linalg.norm(f)
    x = np.cross(f, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(f, x)
    r = np.stack([x, y, f])
    return r, -r @ eye


def median_root_spacing(roots: np.ndarray, sample: int = 2000, seed: int = 0) -> float:
    """Median distance from a root to its nearest other root (on up to `sample` roots)."""
    if len(roots) < 2:
        return 0.0
    rng = np.random.default_rng(seed)
    pick = roots[rng.choice(len(roots), size=min(sample, len(roots)), replace=False)]
    best = np.full(len(pick), np.inf)
    for s in range(0, len(roots), 4096):
        d = np.linalg.norm(pick[:, None, :] - roots[None, s : s + 4096, :], axis=2)
        d[d < 1e-9] = np.inf
        best = np.minimum(best, d.min(axis=1))
    return float(np.median(best))


# ---------------------------------------------------------------------------------------------
# Scene
# ---------------------------------------------------------------------------------------------


def build_scene(bpy, a, head_path: Path, pts: np.ndarray, counts: np.ndarray):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    sc.cycles.seed = a.seed
    sc.cycles.filter_width = a.filter_width
    sc.cycles_curves.shape = a.curve_shape
    sc.render.threads_mode = "FIXED" if a.threads else "AUTO"
    if a.threads:
        sc.render.threads = a.threads
    sc.view_settings.view_transform = "Standard"
    sc.render.film_transparent = False
    # Cycles keeps the scene (its BVH over every hair segment) from one view's render to the next; only
    # the camera changes. The same pixels, in less time (the demo's 16 views: 67.9 -> 61.3 s).
    sc.render.use_persistent_data = True

    world = bpy.data.worlds.new("white")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    sc.world = world

    bpy.ops.wm.ply_import(filepath=str(head_path), forward_axis="Y", up_axis="Z")
    head = bpy.context.selected_objects[0]
    head.name = "head"
    skin = bpy.data.materials.new("skin")
    skin.use_nodes = True
    bsdf = skin.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.57, 0.45, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.5
    head.data.materials.clear()
    head.data.materials.append(skin)
    for poly in head.data.polygons:
        poly.use_smooth = True

    cv = bpy.data.hair_curves.new("hair")
    cv.add_curves([int(c) for c in counts])
    cv.attributes["position"].data.foreach_set("vector", pts.astype(np.float32).ravel())
    if "radius" not in cv.attributes:
        cv.attributes.new("radius", "FLOAT", "POINT")
    hair = bpy.data.objects.new("hair", cv)
    sc.collection.objects.link(hair)
    set_radius(cv, a.radius_mm * 1e-3)
    cv.materials.append(hair_material(bpy, a))

    vl = sc.view_layers[0]
    vl.use_pass_z = True
    aov = vl.aovs.add()
    aov.name = "orient"
    aov.type = "COLOR"
    ims = sc.render.image_settings
    ims.media_type = "MULTI_LAYER_IMAGE"
    ims.color_depth = "32"
    ims.exr_codec = "ZIP"
    return sc, hair, head


def set_radius(cv, radius: float):
    cv.attributes["radius"].data.foreach_set("value", np.full(len(cv.points), radius, np.float32))
    cv.update_tag()


def hair_material(bpy, a):
    """Principled Hair BSDF, plus the orientation AOV: (cos 2θ, sin 2θ, 1) of the projected tangent.

    With T and P the tangent and position in Blender camera space (x right, y up, z backward), the
    image-space direction of the strand (u right, v down) is (du, dv) ∝ (C.y, C.x), C = T × P."""
    m = bpy.data.materials.new("hair")
    m.use_nodes = True
    nt = m.node_tree
    nodes, links = nt.nodes, nt.links
    for n in list(nodes):
        if n.type != "OUTPUT_MATERIAL":
            nodes.remove(n)
    out = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
    hb = nodes.new("ShaderNodeBsdfHairPrincipled")
    c = COLORS[a.color]
    hb.parametrization = c["parametrization"]
    if c["parametrization"] == "MELANIN":
        hb.inputs["Melanin"].default_value = c["melanin"]
        hb.inputs["Melanin Redness"].default_value = c["redness"]
    else:
        hb.inputs["Color"].default_value = (*c["color"], 1.0)
    hb.inputs["Roughness"].default_value = 0.3
    if "Random Color" in hb.inputs:  # melanin only: Blender 5.0 has no such socket with a direct colour
        hb.inputs["Random Color"].default_value = 0.1
    links.new(hb.outputs[0], out.inputs["Surface"])

    geo = nodes.new("ShaderNodeNewGeometry")
    tcam = nodes.new("ShaderNodeVectorTransform")
    tcam.vector_type, tcam.convert_from, tcam.convert_to = "VECTOR", "WORLD", "CAMERA"
    pcam = nodes.new("ShaderNodeVectorTransform")
    pcam.vector_type, pcam.convert_from, pcam.convert_to = "POINT", "WORLD", "CAMERA"
    links.new(geo.outputs["Tangent"], tcam.inputs[0])
    links.new(geo.outputs["Position"], pcam.inputs[0])
    cross = nodes.new("ShaderNodeVectorMath")
    cross.operation = "CROSS_PRODUCT"
    links.new(tcam.outputs[0], cross.inputs[0])
    links.new(pcam.outputs[0], cross.inputs[1])
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(cross.outputs[0], sep.inputs[0])

    def math(op, x, y):
        n = nodes.new("ShaderNodeMath")
        n.operation = op
        for i, v in enumerate((x, y)):
            if isinstance(v, float):
                n.inputs[i].default_value = v
            else:
                links.new(v, n.inputs[i])
        return n.outputs[0]

    du, dv = sep.outputs["Y"], sep.outputs["X"]
    uu, vv = math("MULTIPLY", du, du), math("MULTIPLY", dv, dv)
    norm = math("ADD", math("ADD", uu, vv), 1e-30)
    c2 = math("DIVIDE", math("SUBTRACT", uu, vv), norm)
    s2 = math("DIVIDE", math("MULTIPLY", math("MULTIPLY", du, dv), 2.0), norm)
    comb = nodes.new("ShaderNodeCombineXYZ")
    links.new(c2, comb.inputs[0])
    links.new(s2, comb.inputs[1])
    comb.inputs[2].default_value = 1.0
    aov = nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = "orient"
    links.new(comb.outputs[0], aov.inputs["Color"])
    return m


def add_cameras(bpy, sc, a, target: np.ndarray, radius: float):
    """One camera object per view. Returns [(name, object, PinholeCamera)], the OpenCV camera converted
    from the Blender camera object (the add-on's conversion, addon/hairrecon/core/camera.py)."""
    h = a.height
    w = int(round(h * 2 / 3))
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = w, h, 100
    sc.render.pixel_aspect_x = sc.render.pixel_aspect_y = 1.0
    # Fit the bounding sphere (plus 4%) into the image width: fx = (W/2) / tan(asin(r/D)).
    half = math.asin(min(0.99, 1.04 * radius / a.distance))
    fx = 0.5 * w / math.tan(half)
    sensor = 36.0
    lens = fx * sensor / w
    mathutils = sys.modules["mathutils"]
    cams = []
    for i, d in enumerate(camera_directions(a)):
        name = f"view_{i:03d}"
        cam = bpy.data.cameras.new(name)
        cam.sensor_fit = "HORIZONTAL"
        cam.sensor_width = sensor
        cam.lens = lens
        cam.clip_start = 0.05
        cam.clip_end = 100.0
        ob = bpy.data.objects.new(name, cam)
        sc.collection.objects.link(ob)
        eye = target + a.distance * d
        r_cv, t_cv = look_at_rt(eye, target)
        # Blender camera axes: x right, y up, z backward = OpenCV's (x, -y, -z).
        rot_b = (np.diag([1.0, -1.0, -1.0]) @ r_cv).T
        m = np.eye(4)
        m[:3, :3] = rot_b
        m[:3, 3] = eye
        ob.matrix_world = mathutils.Matrix(m.tolist())
        cams.append((name, ob))
    bpy.context.view_layer.update()
    return [(name, ob, camera.opencv_from_blender(camera.blender_camera(ob, sc))) for name, ob in cams]


def render_exr(bpy, sc, path: Path) -> dict:
    """Renders the scene's camera into a multilayer EXR; its channels by name ("ViewLayer.Depth.Z", ...)."""
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return hairrecon.read_exr(str(path))


def write_depth(path: Path, d: np.ndarray):
    """A depth map as the capture stores it: 32-bit float OpenEXR, R = G = B = depth."""
    d = np.asarray(d, np.float32)
    hairrecon.write_image(str(path), np.stack([d, d, d], axis=2))


def depth_exr(path: Path, z: np.ndarray):
    """Depth along the optical axis in metres, 0 where no surface; R = G = B = depth."""
    write_depth(path, np.where(z < 1e9, z, 0.0))


def linear_to_srgb8(rgb: np.ndarray) -> np.ndarray:
    """Scene-linear float RGB to 8-bit sRGB (Blender's "Standard" view transform), clipped."""
    return np.round(linear_to_srgb(rgb) * 255.0).astype(np.uint8)


def photo_fusion_depth(depth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """A depth map for the raw-mesh fusion from a photograph's own depth (Cycles' sample-0 depth, 0 where
    that sample saw nothing) and its hair mask: -1 (unknown, `hairrecon fuse-depth` skips it) where the
    pixel holds hair (mask > 0) but its sample went through it to the background, so that the gaps
    between strands do not carve the hair away; the depth elsewhere."""
    d = np.asarray(depth, np.float32).copy()
    d[(mask > 0) & ~(d > 0)] = -1.0
    return d


def mean_hair_coverage(masks: list[np.ndarray]) -> float:
    """Mean coverage (0..1) of the pixels that hold any hair, over all views' 16-bit masks."""
    tot, n = 0.0, 0
    for m in masks:
        h = m[m > 0]
        tot += float(h.sum()) / 65535.0
        n += h.size
    return tot / n if n else 0.0


def find_hairrecon(explicit: str | None) -> str | None:
    if explicit:
        return explicit
    cand = REPO / "target" / "release" / "hairrecon"
    if cand.is_file():
        return str(cand)
    return shutil.which("hairrecon")


def write_jpeg(path: Path, rgb8: np.ndarray, quality: int = synthetic_wild.JPEG_QUALITY):
    """An 8-bit sRGB (H, W, 3) array as a JPEG file, with Blender's writer (the bytes as given, no colour
    transform)."""
    import bpy  # noqa: PLC0415

    h, w = rgb8.shape[:2]
    img = bpy.data.images.new(path.stem, w, h, alpha=False)
    px = np.ones((h, w, 4), np.float32)
    px[:, :, :3] = rgb8 / 255.0
    img.pixels.foreach_set(px[::-1].ravel())  # Blender's rows are bottom first
    img.file_format = "JPEG"
    img.save(filepath=str(path), quality=quality)
    bpy.data.images.remove(img)


def main(argv=None):
    a = parse_args(argv)
    if not a.wild:
        return render_capture(a)
    t0 = time.time()
    project = a.out.resolve()
    # The rendered capture, removed once the project is made unless --keep-capture (kept for --resume).
    a.out = project / "_capture"
    rc = render_capture(a)
    if rc != 0:
        return rc
    frame = synthetic_wild.make_project(a.out, project, a.seed, write_jpeg)
    if not a.keep_capture:
        shutil.rmtree(a.out)
    print(
        f"render_synthetic: wild project {project} (frame scale {frame['scale']:.5f} m per unit) in "
        f"{time.time() - t0:.1f} s; import it with: hairrecon import colmap {project}/sparse/0 --images "
        f"{project}/images --mesh {project}/mesh.ply --out CAPTURE --height {a.height // a.photo_scale}",
        flush=True,
    )
    return 0


def render_capture(a) -> int:
    t_start = time.time()
    import bpy  # noqa: PLC0415  (imported late so that --help works without Blender)
    import mathutils  # noqa: F401, PLC0415

    # One-point strands (some .hair files have them) cannot be drawn: they are dropped.
    pts, counts = hairrecon.read_strands(str(a.hair), skip_short_strands=True)
    pts, counts = pts.astype(np.float64), counts.astype(np.int64)
    axes = a.hair_axes or ("x,-z,y" if a.hair_up == "y" else "x,y,z")
    pts = map_axes(pts, axes) * a.hair_scale + np.asarray(a.hair_offset)
    head_v = hairrecon.read_mesh(str(a.head))["vertices"].astype(np.float64)
    out = a.out.resolve()
    for sub in ("images", "masks", "gt/orientation", "gt/depth", "fusion/depth", "_tmp"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    if not a.skip_photos:
        hairrecon.write_strands(str(out / "gt" / "strands.hair"), pts.astype(np.float32), counts.astype(np.uint32))
        shutil.copyfile(a.head, out / "head.ply")
        if a.scalp:
            shutil.copyfile(a.scalp, out / "scalp.ply")

    sc, hair, _head = build_scene(bpy, a, out / "head.ply", pts, counts)
    allp = np.concatenate([pts, head_v])
    lo, hi = allp.min(0), allp.max(0)
    target = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(allp - target, axis=1).max())
    cams = add_cameras(bpy, sc, a, target, radius)
    clutter = None
    if a.background == "clutter":
        clutter = synthetic_backdrop.add_clutter(bpy, sc, a.seed, head_v, target)
        box = synthetic_backdrop.fusion_box(pts, head_v)
        clutter["fusion_box_m"] = [[round(float(x), 4) for x in b] for b in box]
        print(f"render_synthetic: clutter background: {clutter}", flush=True)

    def fusion_crop(name: str, d: np.ndarray) -> np.ndarray:
        """The room is no part of the raw mesh: surfaces outside the fusion box are removed."""
        if clutter is None:
            return d
        pin = next(p for n, _o, p in cams if n == name)
        return synthetic_backdrop.crop_depth(d, pin.K, pin.R, pin.t, *box)

    w, h = sc.render.resolution_x, sc.render.resolution_y
    print(
        f"render_synthetic: {len(counts)} strands, {len(pts)} points, {a.views} views of {w}x{h}, "
        f"{a.samples} spp, colour {a.color}, lens {cams[0][1].data.lens:.1f} mm at {a.distance} m",
        flush=True,
    )
    views = range(len(cams)) if a.only_view is None else [a.only_view]

    # Pass 1: the photographs, masks, ground-truth orientation and depth.
    sc.cycles.samples = a.samples
    for n, i in enumerate([] if a.skip_photos else views):
        name, ob, *_ = cams[i]
        t0 = time.time()
        done = [out / "images" / f"{name}.png", out / "masks" / f"{name}.png"]
        done += [out / "gt" / d / f"{name}.exr" for d in ("orientation", "depth")]
        if a.resume and all(f.is_file() for f in done):
            print(f"  view {n + 1}/{len(views)} {name}: kept from the interrupted run", flush=True)
            continue
        sc.camera = ob
        ex = render_exr(bpy, sc, out / "_tmp" / f"{name}.exr")
        rgb = np.stack([ex[f"ViewLayer.Combined.{c}"] for c in "RGB"], axis=2)
        hairrecon.write_image(str(out / "images" / f"{name}.png"), linear_to_srgb8(rgb))
        o = np.stack([ex[f"ViewLayer.orient.{c}"] for c in "RGB"], axis=2)
        cov = np.clip(o[:, :, 2], 0.0, 1.0)
        hairrecon.write_image(str(out / "masks" / f"{name}.png"), np.round(cov * 65535).astype(np.uint16))
        vec = o[:, :, :2]
        nrm = np.linalg.norm(vec, axis=2)
        hair_px = cov > 0
        unit = np.where(nrm[:, :, None] > 1e-12, vec / np.maximum(nrm, 1e-12)[:, :, None], 0.0)
        unit[~hair_px] = 0.0
        coherence = np.where(hair_px, np.clip(nrm / np.maximum(cov, 1e-12), 0.0, 1.0), 0.0)
        orientation = np.stack([unit[:, :, 0], unit[:, :, 1], hair_px, coherence], axis=2).astype(np.float32)
        hairrecon.write_image(str(out / "gt" / "orientation" / f"{name}.exr"), orientation)  # R G B A
        depth_exr(out / "gt" / "depth" / f"{name}.exr", ex["ViewLayer.Depth.Z"])
        print(
            f"  view {n + 1}/{len(views)} {name}: {time.time() - t0:.1f} s, hair pixels {int(hair_px.sum())}",
            flush=True,
        )

    # Pass 2: depth maps for the raw mesh: the photographs' own depth where the hair looks like a
    # surface in them; else ribbons through the centrelines (so the depth is that of the strands
    # themselves, not of a tube's surface), wide enough to close the hair into a surface.
    fusion = a.fusion
    coverage = None
    if a.only_view is None:
        masks = [hairrecon.read_image(str(out / "masks" / f"{name}.png")) for name, *_ in cams]
        coverage = mean_hair_coverage(masks)
        if fusion == "auto":
            fusion = "photo" if coverage >= PHOTO_FUSION_MIN_COVERAGE else "ribbons"
        print(f"  mean mask coverage of hair pixels {coverage:.3f}: fusion depth maps from {fusion}", flush=True)
    roots = pts[np.concatenate([[0], np.cumsum(counts)[:-1]])]
    # Ribbons must close the gaps between strands AND cover a pixel, or the single sample per
    # pixel sees through them and the fusion carves the hair away.
    pixel = a.distance / float(cams[0][2].K[0, 0])
    fr = a.fusion_radius_mm * 1e-3 if a.fusion_radius_mm else max(0.5 * median_root_spacing(roots), 0.5 * pixel)
    fr = max(fr, a.radius_mm * 1e-3)
    t_fusion = time.time()
    if a.only_view is None and fusion == "photo":
        for (name, *_), m in zip(cams, masks):
            g = fusion_crop(name, hairrecon.read_exr(str(out / "gt" / "depth" / f"{name}.exr"))["R"])
            write_depth(out / "fusion" / "depth" / f"{name}.exr", photo_fusion_depth(g, m))
        print(f"  fusion depth maps ({a.views} views, from the photographs' depth): {time.time() - t_fusion:.1f} s")
    elif a.only_view is None:
        sc.render.use_persistent_data = False  # the ribbons are new geometry: sync the scene afresh
        set_radius(hair.data, fr)
        sc.cycles_curves.shape = "RIBBONS"
        sc.cycles.samples = 1
        sc.cycles.max_bounces = 0
        filt = sc.cycles.filter_width
        sc.cycles.filter_width = 0.01
        for i, (name, ob, *_) in enumerate(cams):
            sc.camera = ob
            ex = render_exr(bpy, sc, out / "_tmp" / f"{name}.exr")
            z = ex["ViewLayer.Depth.Z"]
            if clutter is None:
                depth_exr(out / "fusion" / "depth" / f"{name}.exr", z)
            else:
                write_depth(out / "fusion" / "depth" / f"{name}.exr", fusion_crop(name, np.where(z < 1e9, z, 0.0)))
        print(f"  fusion depth maps ({a.views} views, hair radius {fr * 1e3:.2f} mm): {time.time() - t_fusion:.1f} s")
        # Back to the photographed scene for scene.blend.
        set_radius(hair.data, a.radius_mm * 1e-3)
        sc.cycles_curves.shape = a.curve_shape
        sc.cycles.samples = a.samples
        sc.cycles.max_bounces = 12
        sc.cycles.filter_width = filt
    shutil.rmtree(out / "_tmp", ignore_errors=True)

    spec = {
        "version": 1,
        "units": "metres",
        "convention": "opencv",
        "views": [
            {
                "name": name,
                "image": f"images/{name}.png",
                "mask": f"masks/{name}.png",
                **pin.to_json(),  # width, height, K, R, t
                "gt_orientation": f"gt/orientation/{name}.exr",
                "gt_depth": f"gt/depth/{name}.exr",
            }
            for i, (name, _ob, pin) in enumerate(cams)
            if i in views
        ],
        "raw_mesh": "raw_mesh.ply",
        "head_mesh": "head.ply",
        "scalp_mesh": "scalp.ply" if a.scalp else None,
        "gt_strands": "gt/strands.hair",
    }
    hairrecon.write_capture(str(out), spec)  # checked against the schema (rust/core/src/capture.rs)
    meta = {
        "hair": str(a.hair),
        "strands": int(len(counts)),
        "points": int(len(pts)),
        "color": a.color,
        "preset": a.preset,
        "rig": a.rig,
        "samples": a.samples,
        "radius_mm": a.radius_mm,
        "curve_shape": a.curve_shape,
        "fusion": fusion,
        "hair_coverage": coverage,
        "fusion_radius_mm": fr * 1e3,
        "distance_m": a.distance,
        "seed": a.seed,
        "blender": bpy.app.version_string,
    }
    if clutter is not None:  # absent: the uniform white environment (captures made before the option)
        meta["background"] = a.background
        meta["clutter"] = clutter
    (out / "render_info.json").write_text(json.dumps(meta, indent=2))
    if not a.no_blend:
        sc.camera = cams[views[0]][1]
        bpy.ops.wm.save_as_mainfile(filepath=str(out / "scene.blend"), compress=True)
    t_render = time.time() - t_start
    print(f"render_synthetic: rendered in {t_render:.1f} s", flush=True)

    voxel_mm = a.voxel_mm or (1.0 if fusion == "photo" else 2.0)
    fuse_args = ["--depth-dir", "fusion/depth", "--voxel-mm", str(voxel_mm)]
    if fusion == "photo":
        # Share of the ground-truth hair seen in >= 2 photographs within 3 mm of the mesh, paper
        # preset (`hairrecon fuse-depth CAP --no-fuse --check-gt`), straight / wavy / curly:
        #   2 mm voxels, 2-voxel truncation, median over views:      96.1 / 89.0 / 82.1%
        #   1 mm voxels, 3-voxel truncation, 0.3 quantile (these):  96.7 / 96.1 / 96.6%
        # Wavy and curly hair seen from outside is a fuzzy shell of curls: a lower quantile keeps
        # the surface on its outer curls rather than between them, and 1 mm voxels follow them.
        fuse_args += ["--truncation-voxels", "3", "--quantile", "0.3"]
    else:
        # The ribbons widen the hair by their radius, not the skin: the inset stops at the head.
        fuse_args += ["--inset-mm", f"{meta['fusion_radius_mm']:.4f}", "--inset-above-head"]
    if a.no_fuse or a.only_view is not None:
        print(f"render_synthetic: now run: hairrecon fuse-depth {out} {' '.join(fuse_args)}", flush=True)
        return 0
    exe = find_hairrecon(a.hairrecon_bin)
    if exe is None:
        print(
            "render_synthetic: no hairrecon binary (build it: cargo build --release -p hairrecon-cli); "
            f"then run: hairrecon fuse-depth {out} {' '.join(fuse_args)}",
            file=sys.stderr,
        )
        return 2
    cmd = [exe, "fuse-depth", str(out), *fuse_args, "--check-capture"]
    print("render_synthetic: " + " ".join(cmd), flush=True)
    t0 = time.time()
    rc = subprocess.call(cmd)
    print(f"render_synthetic: fuse-depth {time.time() - t0:.1f} s; total {time.time() - t_start:.1f} s", flush=True)
    return rc


if __name__ == "__main__":
    rc = main()
    # Under `blender -b -P`, sys.exit would stop Blender with a traceback-free code, which is what we want.
    sys.exit(rc)
