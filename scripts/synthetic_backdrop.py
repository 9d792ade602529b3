"""A cluttered room and a clothed torso for synthetic captures (``render_synthetic.py --background clutter``).

Real photographs of a head have a room behind it and shoulders under it; a uniform background lets a
hair mask win by colour alone (issue 52, item 3). This module adds, seeded by the render's ``--seed``:

- **a room**: a floor and four walls at ``ROOM_HALF`` metres from the head (beyond the camera ring,
  1 m by default) with procedural textures (bricks, noise, waves, voronoi, checker), and boxes standing
  against the walls as shelves, panels and pictures. Its colours are drawn from a palette that holds
  hair-like browns and blacks and skin-like tones (the head's own skin colour among them), so that colour
  alone cannot tell hair from background. The room is seen by camera rays only (Cycles ray visibility):
  the head, hair and torso are lit exactly as in the uniform white environment, and the room takes no
  light from them. It has no ceiling: the cameras (on the upper hemisphere) never look up at one.
- **a torso**: shoulders and chest lofted from superellipse rings, the top ring inside the bundled head's
  shoulder stub (read from the head mesh's lowest 2 cm, so it follows another head too), with a
  procedural cloth (stripes, plaid or knit) in a seeded colour. It is an ordinary object: it occludes
  the hair behind it, casts shadows and appears in the fusion depth maps. The hair is not draped over
  it: strands of long hair that pass through the shoulders are hidden where they are inside.

The masks need no change: they are the coverage of an AOV that only the hair's material writes, per
camera sample at its first hit, so hair hidden by the torso (or the head) is not mask.

``fusion_box`` and ``crop_depth`` (no bpy) keep the room out of the raw mesh: the fusion depth maps
keep the surfaces inside a box around the head, hair and upper torso; pixels that see past the box
(the room) become "saw nothing" (0), pixels that see something else outside it "unknown" (-1).
"""

from __future__ import annotations

import math

import numpy as np

# Distance (metres) from the head's centre to the walls, and of the floor below it.
ROOM_HALF = 2.2
FLOOR_BELOW = 1.3
WALL_TOP = 2.5  # above the head's centre: views at 0 degrees elevation see up to ~1.3 m above it at 3.2 m
# How far the fusion box reaches below the head mesh's lowest point (the upper torso).
FUSION_TORSO_DEPTH = 0.15
FUSION_PAD = 0.03

# Linear RGB. Hair-like browns and blacks, skin-like tones (the first is the head's skin), others.
HAIR_LIKE = [(0.06, 0.03, 0.015), (0.2, 0.1, 0.05), (0.015, 0.013, 0.012), (0.25, 0.07, 0.03), (0.5, 0.35, 0.18)]
SKIN_LIKE = [(0.8, 0.57, 0.45), (0.6, 0.38, 0.27), (0.35, 0.2, 0.13), (0.7, 0.5, 0.38)]
OTHER = [(0.7, 0.7, 0.68), (0.1, 0.2, 0.5), (0.15, 0.3, 0.12), (0.9, 0.88, 0.82), (0.5, 0.1, 0.1), (0.3, 0.3, 0.32)]
PALETTE = HAIR_LIKE + SKIN_LIKE + OTHER
CLOTH = [(0.05, 0.08, 0.2), (0.02, 0.02, 0.02), (0.4, 0.05, 0.05), (0.12, 0.2, 0.1), (0.6, 0.6, 0.58), (0.3, 0.2, 0.12)]
TEXTURES = ["brick", "noise", "wave", "voronoi", "checker"]


def _color(rng, pool=PALETTE):
    c = np.asarray(pool[rng.integers(len(pool))], np.float64) * rng.uniform(0.85, 1.15)
    return (*np.clip(c, 0.0, 1.0).tolist(), 1.0)


def _mesh_object(bpy, sc, name, verts, faces, material):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in verts], [], [tuple(map(int, f)) for f in faces])
    me.update()
    me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    sc.collection.objects.link(ob)
    return ob


def _box(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return v, f


def _textured(bpy, name, kind, rng, scale):
    """A diffuse material whose colour is a procedural texture of `kind` in object coordinates."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nodes, links = nt.nodes, nt.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Roughness"].default_value = 0.8
    coord = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (scale, scale, scale)
    mapping.inputs["Location"].default_value = tuple(rng.uniform(-10, 10, 3).tolist())
    links.new(coord.outputs["Object"], mapping.inputs["Vector"])
    c1, c2, c3 = _color(rng), _color(rng), _color(rng)
    if kind == "brick":
        t = nodes.new("ShaderNodeTexBrick")
        t.inputs["Color1"].default_value = c1
        t.inputs["Color2"].default_value = c2
        t.inputs["Mortar"].default_value = c3
        links.new(mapping.outputs["Vector"], t.inputs["Vector"])
        links.new(t.outputs["Color"], bsdf.inputs["Base Color"])
        return m
    if kind == "checker":
        t = nodes.new("ShaderNodeTexChecker")
        t.inputs["Color1"].default_value = c1
        t.inputs["Color2"].default_value = c2
        links.new(mapping.outputs["Vector"], t.inputs["Vector"])
        links.new(t.outputs["Color"], bsdf.inputs["Base Color"])
        return m
    if kind == "noise":
        t = nodes.new("ShaderNodeTexNoise")
        t.inputs["Detail"].default_value = 6.0
        fac = t.outputs["Fac"]
    elif kind == "wave":
        t = nodes.new("ShaderNodeTexWave")
        t.wave_type = "BANDS" if rng.random() < 0.5 else "RINGS"
        t.inputs["Distortion"].default_value = float(rng.uniform(2, 10))
        t.inputs["Detail"].default_value = 3.0
        fac = t.outputs["Fac"]
    else:  # voronoi
        t = nodes.new("ShaderNodeTexVoronoi")
        fac = t.outputs["Distance"]
    links.new(mapping.outputs["Vector"], t.inputs["Vector"])
    ramp = nodes.new("ShaderNodeValToRGB")
    els = ramp.color_ramp.elements
    els[0].position, els[0].color = 0.2, c1
    els[1].position, els[1].color = 0.8, c2
    els.new(0.5).color = c3
    links.new(fac, ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    return m


def _camera_only(ob):
    """Seen by camera rays only: it neither lights, reflects in, nor shadows anything."""
    for ray in ("diffuse", "glossy", "transmission", "volume_scatter", "shadow"):
        setattr(ob, f"visible_{ray}", False)


def add_room(bpy, sc, rng, centre: np.ndarray) -> list:
    """Floor, four walls and boxes against the walls, around `centre` (the head's centre). Returns the objects."""
    cx, cy, cz = map(float, centre)
    h, zf, zt = ROOM_HALF, cz - FLOOR_BELOW, cz + WALL_TOP
    obs = []
    floor = [(cx - h, cy - h, zf), (cx + h, cy - h, zf), (cx + h, cy + h, zf), (cx - h, cy + h, zf)]
    kind = ["wave", "checker", "brick"][rng.integers(3)]
    obs.append(_mesh_object(bpy, sc, "floor", floor, [(0, 1, 2, 3)], _textured(bpy, "floor", kind, rng, 2.0)))
    # The walls: (corner a, corner b) along the floor, counter-clockwise seen from above.
    corners = [(cx - h, cy - h), (cx + h, cy - h), (cx + h, cy + h), (cx - h, cy + h)]
    for i in range(4):
        (ax, ay), (bx, by) = corners[i], corners[(i + 1) % 4]
        v = [(ax, ay, zf), (bx, by, zf), (bx, by, zt), (ax, ay, zt)]
        kind = TEXTURES[rng.integers(len(TEXTURES))]
        mat = _textured(bpy, f"wall_{i}", kind, rng, float(rng.uniform(1.0, 4.0)))
        obs.append(_mesh_object(bpy, sc, f"wall_{i}", v, [(0, 1, 2, 3)], mat))
        # Boxes against this wall: shelves, cabinets, panels, pictures.
        along = np.array([bx - ax, by - ay]) / (2 * h)
        inward = np.array([-along[1], along[0]])
        for j in range(int(rng.integers(3, 6))):
            w, tall, deep = rng.uniform(0.3, 1.2), rng.uniform(0.2, 1.4), rng.uniform(0.02, 0.4)
            s = rng.uniform(0.3, 2 * h - 0.3 - w)
            z0 = zf if rng.random() < 0.4 else zf + rng.uniform(0.3, FLOOR_BELOW + 1.2)
            p0 = np.array([ax, ay]) + along * s
            p1 = p0 + along * w + inward * deep
            lo = (min(p0[0], p1[0]), min(p0[1], p1[1]), z0)
            hi = (max(p0[0], p1[0]), max(p0[1], p1[1]), z0 + tall)
            bv, bf = _box(lo, hi)
            if rng.random() < 0.5:
                mat = bpy.data.materials.new(f"box_{i}_{j}")
                mat.use_nodes = True
                mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = _color(rng)
            else:
                mat = _textured(bpy, f"box_{i}_{j}", TEXTURES[rng.integers(len(TEXTURES))], rng, 6.0)
            obs.append(_mesh_object(bpy, sc, f"box_{i}_{j}", bv, bf, mat))
    for ob in obs:
        _camera_only(ob)
    return obs


def neck_ring(head_v: np.ndarray) -> tuple[float, float, float, float, float]:
    """(bottom z, centre x, centre y, half width, half depth) of the head mesh's lowest 2 cm."""
    zb = float(head_v[:, 2].min())
    ring = head_v[head_v[:, 2] < zb + 0.02]
    lo, hi = ring.min(0), ring.max(0)
    return zb, float(lo[0] + hi[0]) / 2, float(lo[1] + hi[1]) / 2, float(hi[0] - lo[0]) / 2, float(hi[1] - lo[1]) / 2


# Torso profile under the head's shoulder stub: (z above the stub's lowest point in metres, width and
# depth as multiples of the stub's half width and half depth). The upper rings lie just inside the
# bundled head's neck and shoulder slope, the ring at +2 cm just outside the stub's rim, so that the
# joint shows no gap.
TORSO_PROFILE = [
    (0.05, 0.5, 0.75),
    (0.04, 0.68, 0.85),
    (0.03, 0.88, 0.95),
    (0.02, 1.02, 1.02),
    (0.0, 1.1, 1.06),
    (-0.02, 1.25, 1.1),
    (-0.045, 1.4, 1.15),
    (-0.08, 1.47, 1.12),
    (-0.25, 1.42, 1.1),
    (-0.45, 1.3, 1.08),
    (-0.75, 1.25, 1.05),
]


def torso_mesh(head_v: np.ndarray, segments: int = 64, exponent: float = 3.0):
    """Vertices and quad/triangle faces of the torso: superellipse rings along TORSO_PROFILE, the
    bottom closed by a fan."""
    zb, cx, cy, hw, hd = neck_ring(head_v)
    prof = np.array(TORSO_PROFILE)
    # Resample the profile finely (smooth shoulders).
    zs = np.concatenate([np.linspace(0.05, -0.1, 16), np.linspace(-0.125, -0.75, 26)])
    wx = np.interp(-zs, -prof[:, 0], prof[:, 1]) * hw
    wy = np.interp(-zs, -prof[:, 0], prof[:, 2]) * hd
    a = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    c, s = np.cos(a), np.sin(a)
    e = 2.0 / exponent
    ux, uy = np.sign(c) * np.abs(c) ** e, np.sign(s) * np.abs(s) ** e
    verts = []
    for z, x, y in zip(zs, wx, wy):
        verts += [(cx + x * ux[k], cy + y * uy[k], zb + z) for k in range(segments)]
    faces = []
    for r in range(len(zs) - 1):
        for k in range(segments):
            k1 = (k + 1) % segments
            # Counter-clockwise seen from outside (normals out).
            faces.append((r * segments + k, (r + 1) * segments + k, (r + 1) * segments + k1, r * segments + k1))
    centre = len(verts)
    verts.append((cx, cy, zb + zs[-1]))
    last = (len(zs) - 1) * segments
    faces += [(last + (k + 1) % segments, last + k, centre) for k in range(segments)]
    return np.array(verts), faces


def cloth_material(bpy, rng):
    """Principled BSDF with a procedural cloth pattern (stripes, plaid or knit) in a seeded colour."""
    m = bpy.data.materials.new("cloth")
    m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Roughness"].default_value = 0.9
    base = np.asarray(CLOTH[rng.integers(len(CLOTH))]) * rng.uniform(0.8, 1.2)
    other = np.asarray(_color(rng)[:3])
    coord = nodes.new("ShaderNodeTexCoord")
    pattern = ["stripes", "plaid", "knit"][rng.integers(3)]

    def wave(axis, scale):
        t = nodes.new("ShaderNodeTexWave")
        t.wave_type, t.bands_direction = "BANDS", axis
        t.inputs["Scale"].default_value = scale
        t.inputs["Distortion"].default_value = 1.0
        links.new(coord.outputs["Object"], t.inputs["Vector"])
        return t.outputs["Fac"]

    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["A"].default_value = (*np.clip(base, 0, 1).tolist(), 1.0)
    mix.inputs["B"].default_value = (*np.clip(other, 0, 1).tolist(), 1.0)
    if pattern == "knit":
        n = nodes.new("ShaderNodeTexNoise")
        n.inputs["Scale"].default_value = 60.0
        n.inputs["Detail"].default_value = 8.0
        links.new(coord.outputs["Object"], n.inputs["Vector"])
        fac = n.outputs["Fac"]
    else:
        fac = wave("Z", float(rng.uniform(4, 12)))
        if pattern == "plaid":
            mul = nodes.new("ShaderNodeMath")
            mul.operation = "MULTIPLY"
            links.new(fac, mul.inputs[0])
            links.new(wave("X", float(rng.uniform(4, 12))), mul.inputs[1])
            fac = mul.outputs[0]
    links.new(fac, mix.inputs["Factor"])
    # Wrinkles: low-frequency noise darkens the cloth a little.
    wr = nodes.new("ShaderNodeTexNoise")
    wr.inputs["Scale"].default_value = 8.0
    links.new(coord.outputs["Object"], wr.inputs["Vector"])
    dark = nodes.new("ShaderNodeMix")
    dark.data_type, dark.blend_type = "RGBA", "MULTIPLY"
    dark.inputs["Factor"].default_value = 0.4
    links.new(mix.outputs["Result"], dark.inputs["A"])
    links.new(wr.outputs["Fac"], dark.inputs["B"])
    links.new(dark.outputs["Result"], bsdf.inputs["Base Color"])
    return m, pattern, tuple(float(x) for x in np.clip(base, 0, 1))


def add_torso(bpy, sc, rng, head_v: np.ndarray):
    """The torso object under the head; returns (object, info dict for render_info.json)."""
    verts, faces = torso_mesh(head_v)
    mat, pattern, color = cloth_material(bpy, rng)
    ob = _mesh_object(bpy, sc, "torso", verts, faces, mat)
    for poly in ob.data.polygons:
        poly.use_smooth = True
    zmin = float(verts[:, 2].min())
    return ob, {"cloth": pattern, "cloth_color": [round(c, 4) for c in color], "torso_bottom_z_m": round(zmin, 4)}


def add_clutter(bpy, sc, seed: int, head_v: np.ndarray, centre: np.ndarray) -> dict:
    """The room and the torso, seeded; returns what render_info.json records of them."""
    rng = np.random.default_rng([seed, 52])
    room = add_room(bpy, sc, rng, centre)
    _torso, info = add_torso(bpy, sc, rng, head_v)
    return {"room_objects": len(room), "room_half_m": ROOM_HALF, **info}


# ---------------------------------------------------------------------------------------------
# The fusion box (no bpy)
# ---------------------------------------------------------------------------------------------


def fusion_box(hair_pts: np.ndarray, head_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box whose surfaces the raw mesh keeps: hair, head and the torso down to FUSION_TORSO_DEPTH
    below the head mesh, padded by FUSION_PAD (the torso's width from TORSO_PROFILE)."""
    zb, cx, cy, hw, hd = neck_ring(head_v)
    prof = np.array(TORSO_PROFILE)
    wmax, dmax = prof[:, 1].max() * hw, prof[:, 2].max() * hd
    torso_lo = np.array([cx - wmax, cy - dmax, zb - FUSION_TORSO_DEPTH])
    torso_hi = np.array([cx + wmax, cy + dmax, zb])
    allp = np.concatenate([hair_pts, head_v])
    lo = np.minimum(allp.min(0), torso_lo) - FUSION_PAD
    hi = np.maximum(allp.max(0), torso_hi) + FUSION_PAD
    return lo, hi


def crop_depth(depth: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray, lo, hi) -> np.ndarray:
    """A planar depth map (0: saw nothing, < 0: unknown) with its surfaces outside the box [lo, hi]
    removed: 0 where the ray leaves the box before its hit (it crossed the box empty), -1 where the hit
    lies outside the box but before the ray's exit (what is behind it is unknown)."""
    d = np.asarray(depth, np.float64)
    h, w = d.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K).T  # camera space, z = 1
    dirs = rays @ R  # world direction per unit of planar depth (R^T r)
    c = -R.T @ t
    p = c + dirs * d[..., None]
    inside = np.all((p >= lo) & (p <= hi), axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (np.asarray(lo) - c) / dirs
        t1 = (np.asarray(hi) - c) / dirs
    t_exit = np.nanmin(np.where(np.isnan(np.maximum(t0, t1)), np.inf, np.maximum(t0, t1)), axis=-1)
    out = np.where(inside, d, np.where(d >= t_exit, 0.0, -1.0))
    out = np.where(d > 0, out, d)  # keep "saw nothing" and "unknown" as they were
    return out.astype(np.float32)
