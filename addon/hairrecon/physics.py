"""Test Hair Physics: Blender's own hair dynamics on the reconstructed strands, while the head turns and nods.

The check never touches the user's scene. It builds a new scene, ``Hair Physics``, in the canonical frame
(metres, Z up; the frame Fit Head found when the head or scalp is a fitted one), with copies of:

- the head (world-space mesh, modifiers applied) as a collision object,
- the hair's scalp (its ``surface``) as the emitter of a hair particle system made from a seeded sample of
  the strands, each resampled to a few points (as an artist simulates guides), with hair dynamics on,

both parented to an empty at the bottom of the head that turns the head by ±``turn_deg`` about the
vertical and nods it by ``nod_deg`` (``core.physics_measures.head_keys``). Stepping the frames runs the
simulation into the particle system's memory cache; each frame's strand points are read back through the
particle system's path cache (``ParticleSystem.co_hair``) and measured in the head's frame
(``core.physics_measures``). A finished check leaves its scene for the user to play and look at; a failed
or cancelled one removes everything it made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import bpy
import numpy as np
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree

from . import scene_build
from .core.physics_measures import Measures, PhysicsInputError, head_keys, pick, resample
from .session import UserError, fitted_frame

SCENE_NAME = "Hair Physics"


@dataclass
class PhysicsSettings:
    strands: int = 400  # strands simulated (a seeded sample)
    points: int = 17  # points per simulated strand: 9, 17 or 33 (the path cache then passes through them)
    frames: int = 48
    fps: int = 24
    turn_deg: float = 45.0
    nod_deg: float = 20.0
    seed: int = 0


def canonical_matrix(*objs) -> Matrix:
    """The similarity from the scene's frame to the canonical one (metres, Z up, face toward -Y): the
    frame Fit Head stored on the first of ``objs`` that has one, else the identity."""
    for o in objs:
        f = fitted_frame(o)
        if f is not None:
            r = np.asarray(f["rotation"], np.float64).reshape(3, 3) * float(f["scale"])
            m = np.eye(4)
            m[:3, :3], m[:3, 3] = r, np.asarray(f["translation"], np.float64)
            return Matrix(m.tolist())
    return Matrix.Identity(4)


def _world_mesh(obj, depsgraph, to_canonical: Matrix, name: str) -> bpy.types.Mesh:
    """A new mesh: ``obj`` evaluated (modifiers applied), in the canonical frame."""
    mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph), depsgraph=depsgraph)
    mesh.name = name
    mesh.transform(to_canonical @ obj.matrix_world)
    return mesh


def _hair_points(obj) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A Curves object's points (object space, float32, (N, 3)), per-strand counts and object-to-world matrix."""
    cv = obj.data
    pts = np.empty(len(cv.points) * 3, np.float32)
    cv.points.foreach_get("position", pts)
    counts = np.empty(len(cv.curves), np.int32)
    cv.curves.foreach_get("points_length", counts)
    return pts.reshape(-1, 3), counts.astype(np.int64), np.asarray(obj.matrix_world, np.float64)


def check_inputs(hair, head) -> None:
    """Raises UserError naming what is missing or wrong."""
    if hair is None or hair.type != "CURVES":
        raise UserError("select the hair Curves object to simulate (Test Hair Physics works on the active object)")
    surface = hair.data.surface
    if surface is None or surface.type != "MESH":
        raise UserError(f"the hair {hair.name!r} has no scalp surface to grow from; reconstruct it, or set its Surface")
    if head is None:
        raise UserError("no head to collide with: pick the Head object in the Hair tab (Fit Head adds one)")
    if head.type != "MESH" or len(head.data.polygons) == 0:
        raise UserError(f"the head {head.name!r} is not a mesh with faces")
    if len(hair.data.curves) == 0:
        raise UserError(f"the hair {hair.name!r} holds no strands")


class PhysicsCheck:
    """One check: ``__init__`` builds the scene (or raises UserError and leaves nothing), ``step`` simulates
    and measures one frame and returns False after the last, ``remove`` deletes what it made."""

    def __init__(self, context, hair, head, settings: Optional[PhysicsSettings] = None):
        self.settings = s = settings or PhysicsSettings()
        check_inputs(hair, head)
        if s.points not in (9, 17, 33):
            raise UserError(f"Test Hair Physics simulates 9, 17 or 33 points per strand, not {s.points}")
        self.created = scene_build.Created()
        self.window = context.window
        self.previous_scene = context.scene
        try:
            self._build(context, hair, head, s)
        except PhysicsInputError as e:
            self.remove()
            raise UserError(f"Test Hair Physics: the hair {hair.name!r}: {e}") from None
        except BaseException:
            self.remove()
            raise
        self.frame = 0

    def _build(self, context, hair, head, s: PhysicsSettings):
        dg = context.evaluated_depsgraph_get()
        surface = hair.data.surface
        to_c = canonical_matrix(head, surface)
        created = self.created
        scene = created.add(bpy.data.scenes.new(SCENE_NAME))
        self.scene = scene
        scene.frame_start, scene.frame_end = 1, s.frames
        scene.render.fps = s.fps
        scene.unit_settings.system = "METRIC"
        scene.gravity = (0.0, 0.0, -9.81)

        head_mesh = created.add(_world_mesh(head, dg, to_c, f"{SCENE_NAME} Head"))
        scalp_mesh = created.add(_world_mesh(surface, dg, to_c, f"{SCENE_NAME} Scalp"))
        v = np.empty(len(head_mesh.vertices) * 3)
        head_mesh.vertices.foreach_get("co", v)
        v = v.reshape(-1, 3)
        lo, hi = v.min(axis=0), v.max(axis=0)
        pivot = Vector(((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]))
        # the meshes are placed around the pivot, so that rotating the empty turns the head about its neck
        shift = Matrix.Translation(-pivot)
        head_mesh.transform(shift)
        scalp_mesh.transform(shift)

        motion = created.add(bpy.data.objects.new(f"{SCENE_NAME} Motion", None))
        scene.collection.objects.link(motion)
        motion.location = pivot
        for frame, yaw, pitch in head_keys(s.frames, s.turn_deg, s.nod_deg):
            motion.rotation_euler = (math.radians(pitch), 0.0, math.radians(yaw))
            motion.keyframe_insert("rotation_euler", frame=frame)
        self.action = motion.animation_data.action if motion.animation_data else None
        if self.action is not None:
            created.add(self.action)

        self.head = created.add(bpy.data.objects.new(f"{SCENE_NAME} Head", head_mesh))
        self.scalp = created.add(bpy.data.objects.new(f"{SCENE_NAME} Scalp", scalp_mesh))
        for o in (self.head, self.scalp):
            scene.collection.objects.link(o)
            o.parent = motion
        self.head.modifiers.new("Collision", "COLLISION")
        self.head.collision.thickness_outer = 0.001
        self.head.collision.thickness_inner = 0.01
        self.head.collision.cloth_friction = 5.0

        pts, counts, to_world = _hair_points(hair)
        which = pick(counts, s.strands, s.seed)
        starts = np.concatenate([[0], np.cumsum(counts)])[which]
        picked = pts[np.concatenate([np.arange(a, a + n) for a, n in zip(starts, counts[which])])].astype(np.float64)
        m = np.asarray(to_c, np.float64) @ to_world
        picked = picked @ m[:3, :3].T + m[:3, 3] - np.asarray(pivot)
        strands = resample(picked, counts[which], np.arange(len(which)), s.points)
        self.which = which
        # the rest pose: the first frame, read back through the path cache as every other frame
        self.measures = Measures()
        cv = created.add(scene_build.new_hair_curves(f"{SCENE_NAME} Hair", strands.reshape(-1, 3),
                                                     np.full(len(which), s.points), 4e-5, 1e-5))
        tmp = created.add(bpy.data.objects.new(f"{SCENE_NAME} Hair", cv))
        scene.collection.objects.link(tmp)
        tmp.parent = self.scalp
        cv.surface = self.scalp
        if self.scalp.data.uv_layers.active is not None:
            cv.surface_uv_map = self.scalp.data.uv_layers.active.name
        scene.view_layers[0].update()
        particles_before = set(bpy.data.particles)
        with context.temp_override(scene=scene, view_layer=scene.view_layers[0], active_object=tmp, object=tmp,
                                   selected_objects=[tmp], selected_editable_objects=[tmp]):
            result = bpy.ops.curves.convert_to_particle_system()
        for p in set(bpy.data.particles) - particles_before:
            created.add(p)
        if "FINISHED" not in result or not self.scalp.particle_systems:
            raise UserError("Blender could not turn the strands into a hair particle system")
        # the Curves copy served only the conversion
        bpy.data.objects.remove(tmp)
        bpy.data.hair_curves.remove(cv)
        self.created.items = [d for d in self.created.items if d is not tmp and d is not cv]

        psys = self.scalp.particle_systems[0]
        ps = psys.settings
        ps.display_step = int(math.log2(s.points - 1))
        ps.render_step = ps.display_step
        ps.child_type = "NONE"
        psys.use_hair_dynamics = True
        cloth = psys.cloth
        cloth.settings.quality = 8  # substeps per frame: 4 lets strands stretch more in collisions
        cloth.collision_settings.distance_min = 0.002
        cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, s.frames
        mat = scene_build.hair_material("Hair Physics")
        created.add(mat)
        self.scalp.data.materials.append(mat)
        ps.material = len(self.scalp.data.materials)

        co = np.empty(len(head_mesh.vertices) * 3)
        head_mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        self.bvh = BVHTree.FromPolygons(co.tolist(), [tuple(p.vertices) for p in head_mesh.polygons])
        self.rims = _rims(head_mesh)
        self.box = (co.min(axis=0), co.max(axis=0))

    def show(self):
        """Makes the check's scene the window's (the user sees the hair move)."""
        if self.window is not None:
            self.window.scene = self.scene

    def step(self) -> bool:
        """Simulates and measures the next frame; False when every frame is done."""
        s = self.settings
        if self.frame >= s.frames:
            return False
        self.frame += 1
        self.scene.frame_set(self.frame)
        dg = self.scene.view_layers[0].depsgraph
        dg.update()
        so = self.scalp.evaluated_get(dg)
        ps = so.particle_systems[0]
        n = len(self.which)
        inv = so.matrix_world.inverted()
        pos = np.empty((n, s.points, 3))
        depth = np.zeros((n, s.points))  # how far inside the head; 0 for a point that is not a number
        lo, hi = self.box
        for i in range(n):
            # the path cache has 2^display_step = points - 1 segments: its points are the simulated ones
            for j in range(s.points):
                q = inv @ Vector(ps.co_hair(so, particle_no=i, step=j))
                pos[i, j] = q
                loc, normal, face, dist = self.bvh.find_nearest(q)
                if loc is None:
                    continue
                qa = np.asarray(q)
                inside = (q - loc).dot(normal) < 0 and (lo <= qa).all() and (qa <= hi).all()
                depth[i, j] = dist if inside and not _on_rim(self.rims.get(face), loc) else -dist
        self.measures.add(self.frame, pos, depth)
        return self.frame < s.frames

    def run(self) -> dict:
        """Every frame; the summary."""
        while self.step():
            pass
        return self.summary()

    def summary(self) -> dict:
        out = self.measures.summary()
        out["scene"] = self.scene.name
        return out

    def remove(self):
        """Deletes the scene and everything the check made; the window shows the user's scene again."""
        if self.window is not None and self.previous_scene is not None:
            try:
                self.window.scene = self.previous_scene
            except ReferenceError:
                pass
        self.created.remove()


def _rims(mesh) -> dict:
    """For each face with an open edge (a head mesh has holes: the neck, eyes, mouth), its open edges as
    (E, 2, 3) end points."""
    ev = np.empty(len(mesh.edges) * 2, np.int32)
    mesh.edges.foreach_get("vertices", ev)
    loop_edge = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("edge_index", loop_edge)
    start = np.empty(len(mesh.polygons), np.int32)
    total = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("loop_start", start)
    mesh.polygons.foreach_get("loop_total", total)
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    co, ev = co.reshape(-1, 3), ev.reshape(-1, 2)
    # the faces' loops are contiguous runs that together cover every loop: in the order of their starts,
    # loop i belongs to the face whose run holds i
    order = np.argsort(start, kind="stable")
    loop_face = np.repeat(order, total[order])
    uses = np.bincount(loop_edge, minlength=len(ev))
    rims: dict = {}
    for loop in np.flatnonzero(uses[loop_edge] == 1):
        rims.setdefault(int(loop_face[loop]), []).append(co[ev[loop_edge[loop]]])
    return {f: np.array(segs) for f, segs in rims.items()}


def _on_rim(rim, loc, tol: float = 1e-4) -> bool:
    """Whether the closest point ``loc`` lies on one of the face's open edges: there the side of the
    surface a point is on says nothing about being inside (a strand hanging below the neck's opening)."""
    if rim is None:
        return False
    a, b = rim[:, 0], rim[:, 1]
    ab = b - a
    t = np.clip(((np.asarray(loc) - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-30), 0.0, 1.0)
    d = np.linalg.norm(a + t[:, None] * ab - np.asarray(loc), axis=1)
    return bool(d.min() <= tol)


LAST_SUMMARY: dict = {}  # the summary of the last finished check (for batch scripts and tests)
_RUNNING: dict = {}  # the running modal check, at most one


def head_for(context, hair):
    """The collider: the Hair panel's Head, else the hair's surface when it is the head (scalp as a vertex
    group of the head), else None."""
    s = context.scene.hairrecon
    if s.head_object is not None:
        return s.head_object
    surface = hair.data.surface if hair is not None and hair.type == "CURVES" else None
    if surface is not None and s.scalp_source == "GROUP":
        return surface
    return None


class HAIRRECON_OT_test_physics(bpy.types.Operator):
    """Simulate the active hair with Blender's hair dynamics while the head turns and nods, in a new scene,
    and measure whether the strands behave (roots, stretch, head penetration, explosions)"""

    bl_idname = "hairrecon.test_physics"
    bl_label = "Test Hair Physics"
    bl_options = {"REGISTER"}

    strands: bpy.props.IntProperty(name="Strands", default=400, min=1, soft_max=5000,
                                   description="Strands simulated: a seeded sample of the hair's")
    frames: bpy.props.IntProperty(name="Frames", default=48, min=12, soft_max=480,
                                  description="Frames simulated at the scene's frame rate (24 fps: 2 s)")
    points: bpy.props.EnumProperty(name="Points", default="17", items=[(n, n, f"{n} points per strand") for n in ("9", "17", "33")],
                                   description="Points per simulated strand (the strands are resampled)")

    @classmethod
    def poll(cls, context):
        o = context.active_object
        return o is not None and o.type == "CURVES" and not _RUNNING

    def _settings(self) -> PhysicsSettings:
        return PhysicsSettings(strands=self.strands, frames=self.frames, points=int(self.points))

    def _begin(self, context) -> Optional[PhysicsCheck]:
        hair = context.active_object
        try:
            return PhysicsCheck(context, hair, head_for(context, hair), self._settings())
        except UserError as e:
            self.report({"ERROR"}, str(e))
        except Exception as e:  # noqa: BLE001
            self.report({"ERROR"}, f"Test Hair Physics could not build its scene: {e}")
        return None

    def _done(self, check: PhysicsCheck, summary: dict) -> set:
        from .core.physics_measures import describe

        LAST_SUMMARY.clear()
        LAST_SUMMARY.update(summary)
        self.report({"INFO"} if summary["ok"] else {"WARNING"},
                    f"Hair physics in scene {check.scene.name!r}: {describe(summary)}")
        check.scene.frame_set(1)
        return {"FINISHED"}

    def execute(self, context):
        """Synchronous: background mode, scripts, tests."""
        check = self._begin(context)
        if check is None:
            return {"CANCELLED"}
        try:
            summary = check.run()
        except Exception as e:  # noqa: BLE001
            check.remove()
            self.report({"ERROR"}, f"Test Hair Physics failed: {e}")
            return {"CANCELLED"}
        return self._done(check, summary)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        check = self._begin(context)
        if check is None:
            return {"CANCELLED"}
        check.show()
        _RUNNING["check"] = check
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.progress_begin(0, check.settings.frames)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        _RUNNING.clear()

    def modal(self, context, event):
        check: PhysicsCheck = _RUNNING.get("check")
        if check is None:
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            self._end(context)
            check.remove()
            self.report({"INFO"}, "Test Hair Physics cancelled; its scene was removed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            more = check.step()
        except Exception as e:  # noqa: BLE001
            self._end(context)
            check.remove()
            self.report({"ERROR"}, f"Test Hair Physics failed at frame {check.frame}: {e}")
            return {"CANCELLED"}
        context.window_manager.progress_update(check.frame)
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"Hair physics: frame {check.frame} of {check.settings.frames}   (Esc to cancel)")
        if more:
            return {"RUNNING_MODAL"}
        self._end(context)
        return self._done(check, check.summary())

    def cancel(self, context):
        check = _RUNNING.get("check")
        if check is not None:
            self._end(context)
            check.remove()


CLASSES = (HAIRRECON_OT_test_physics,)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
