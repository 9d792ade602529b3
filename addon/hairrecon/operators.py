"""Operators: reconstruct hair, import a capture folder as a scene, export hair curves.

Errors are caught here and reported once with ``self.report({'ERROR'}, ...)``; every operator
leaves the scene as it was when it fails.
"""

from __future__ import annotations

import json
import traceback
from pathlib import Path

import bpy
import numpy as np
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from . import scene_build
from .core.camera import PinholeCamera
from .core.capture import CaptureInputError, read_capture_json
from .session import RUNNING, Session, UserError, describe, library

LAST_SUMMARY: dict = {}  # the summary of the last successful reconstruction (for batch scripts)


def _set_status(context, running: bool, fraction: float = 0.0, text: str = ""):
    wm = context.window_manager
    wm.hairrecon_running = running
    wm.hairrecon_progress = fraction
    wm.hairrecon_status = text
    if context.workspace is not None:
        context.workspace.status_text_set(f"Hair reconstruction {100 * fraction:.0f}%: {text}   (Esc to cancel)" if running else None)
    for area in context.screen.areas if context.screen else ():
        if area.type == "VIEW_3D":
            area.tag_redraw()


class HAIRRECON_OT_reconstruct(bpy.types.Operator):
    """Reconstruct hair strands from the cameras' photos, the raw mesh and the scalp"""

    bl_idname = "hairrecon.reconstruct"
    bl_label = "Reconstruct Hair"
    # UNDO without REGISTER: an "Adjust Last Operation" redo would rerun the whole reconstruction
    # synchronously, freezing Blender for minutes
    bl_options = {"UNDO"}

    output_directory: StringProperty(
        name="Output Directory",
        subtype="DIR_PATH",
        default="",
        description="Keep the capture folder and the library's results here (default: a temporary folder, deleted afterwards)",
        options={"SKIP_SAVE"},
    )

    @classmethod
    def poll(cls, context):
        if "reconstruct" in RUNNING:
            cls.poll_message_set("a hair reconstruction is already running")
            return False
        if "fit_head" in RUNNING:
            cls.poll_message_set("a head fit is running")
            return False
        return context.scene is not None

    def _finish(self, context, session: Session) -> set:
        try:
            summary = session.finish(context)
        except UserError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        except Exception as e:  # noqa: BLE001 - the library's Cancelled and anything unexpected
            hr = library()
            if isinstance(e, hr.Cancelled):
                self.report({"ERROR"}, "Hair reconstruction cancelled; nothing was added")
            else:
                traceback.print_exc()
                self.report({"ERROR"}, f"Hair reconstruction failed: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, describe(summary))
        LAST_SUMMARY.clear()
        LAST_SUMMARY.update(summary)
        if bpy.app.background:
            print(json.dumps({"hairrecon_summary": summary}, default=str), flush=True)
        return {"FINISHED"}

    def _prepare(self, context):
        try:
            return Session.prepare(context, self.output_directory)
        except UserError as e:
            self.report({"ERROR"}, str(e))
        except Exception as e:  # noqa: BLE001
            traceback.print_exc()
            self.report({"ERROR"}, f"cannot prepare the reconstruction: {e}")
        return None

    def _start(self, context):
        """A prepared and started session, or None after reporting why not."""
        session = self._prepare(context)
        if session is None:
            return None
        try:
            session.start()
        except Exception as e:  # noqa: BLE001
            session.cleanup()
            self.report({"ERROR"}, str(e) if isinstance(e, UserError) else f"cannot start the reconstruction: {e}")
            return None
        return session

    def execute(self, context):
        """Synchronous path: background mode, scripts, tests."""
        session = self._start(context)
        if session is None:
            return {"CANCELLED"}
        session.wait(echo=bpy.app.background)
        return self._finish(context, session)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        session = self._start(context)
        if session is None:
            return {"CANCELLED"}
        RUNNING["reconstruct"] = session
        self._timer = context.window_manager.event_timer_add(0.2, window=context.window)
        context.window_manager.progress_begin(0, 1000)
        _set_status(context, True, 0.0, "starting")
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _end_modal(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        _set_status(context, False)
        RUNNING.pop("reconstruct", None)

    def modal(self, context, event):
        session: Session = RUNNING.get("reconstruct")
        if session is None:
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            session.cancel()
            _set_status(context, True, context.window_manager.hairrecon_progress, "cancelling")
            return {"RUNNING_MODAL"}
        if event.type == "TIMER":
            if session.done():
                self._end_modal(context)
                return self._finish(context, session)
            f, text = session.progress()
            context.window_manager.progress_update(int(1000 * f))
            _set_status(context, True, f, text)
        return {"PASS_THROUGH"}

    def cancel(self, context):
        # Blender ends the modal operator (file load, window closed): stop the job, drop the files
        session = RUNNING.get("reconstruct")
        if session is not None:
            session.cancel()
            session.wait()
            session.cleanup()
            self._end_modal(context)


class HAIRRECON_OT_import_capture(bpy.types.Operator):
    """Build a scene from a hairrecon capture folder: cameras with their photos, raw mesh, head, scalp"""

    bl_idname = "hairrecon.import_capture"
    bl_label = "Import Hair Capture"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(name="Capture Folder", subtype="DIR_PATH")
    import_ground_truth: BoolProperty(
        name="Ground Truth Strands", default=False, description="Also import the capture's ground-truth strands (hidden)"
    )

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        created = scene_build.Created()
        try:
            level, msg = build_capture_scene(context, created, Path(bpy.path.abspath(self.directory)), self.import_ground_truth)
        except (UserError, CaptureInputError) as e:
            created.remove()
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        except Exception as e:  # noqa: BLE001
            created.remove()
            hr = library()
            if isinstance(e, hr.HairreconError):
                self.report({"ERROR"}, f"not a valid capture: {e}")
            else:
                traceback.print_exc()
                self.report({"ERROR"}, f"cannot import the capture: {e}")
            return {"CANCELLED"}
        self.report(level, msg)
        return {"FINISHED"}


def build_capture_scene(context, created: scene_build.Created, d: Path, import_ground_truth: bool = False) -> tuple[set, str]:
    """Builds the scene of the capture folder ``d``: a collection with the cameras (photos as background
    images), the raw mesh, the head and the scalp; sets the render resolution, the scene camera and the
    panel's settings. Every datablock goes into ``created`` (the caller removes them on failure); the
    scene's settings change only once everything exists. Returns the report ``(level, message)``.
    Raises UserError, CaptureInputError or the library's errors."""
    hr = library()
    if not (d / "capture.json").is_file():
        raise UserError(f"{d} has no capture.json; pick a capture folder")
    hr.load_capture(str(d))  # validates, with messages that name the view and file
    spec = read_capture_json(d)
    views = spec["views"]
    sizes = {(v["width"], v["height"]) for v in views}
    if len(sizes) != 1:
        raise UserError(
            f"the views have different image sizes {sorted(sizes)}; a Blender scene has one render resolution"
        )
    scene = context.scene
    name = d.name or "capture"
    top = created.add(bpy.data.collections.new(f"Capture {name}"))
    cams = created.add(bpy.data.collections.new(f"Cameras {name}"))
    top.children.link(cams)
    aspects, cam_objs, skews = set(), [], 0
    for v in views:
        cam = PinholeCamera(np.array(v["K"], float), np.array(v["R"], float), np.array(v["t"], float), v["width"], v["height"])
        obj, s = scene_build.camera_object(created, cams, v["name"], cam, d / v["image"])
        aspects.add((round(s.pixel_aspect_x, 6), round(s.pixel_aspect_y, 6)))
        skews += abs(s.skew) > 1e-6
        cam_objs.append(obj)
    if len(aspects) != 1:
        raise UserError("the views have different pixel aspect ratios (fx/fy); Blender has one per scene")
    meshes = {}
    for key, label in (("raw_mesh", "raw_mesh"), ("head_mesh", "head"), ("scalp_mesh", "scalp")):
        if spec.get(key):
            m = hr.read_mesh(str(d / spec[key]))
            uvs = m.get("uvs") if key == "scalp_mesh" else None
            meshes[key] = scene_build.mesh_object(created, top, label, m["vertices"], m["triangles"], uvs)
    if "raw_mesh" in meshes:
        meshes["raw_mesh"].display_type = "WIRE"
    gt = None
    if import_ground_truth and spec.get("gt_strands"):
        pts, counts = hr.read_strands(str(d / spec["gt_strands"]))
        cv = created.add(scene_build.new_hair_curves("ground_truth", np.asarray(pts).reshape(-1, 3), counts, 4e-5, 1e-5))
        gt = created.add(bpy.data.objects.new("ground_truth", cv))
        top.objects.link(gt)

    # everything exists: now change the scene's settings (undone by undo, not by `created`)
    scene.collection.children.link(top)
    if gt is not None:
        gt.hide_viewport = True
        gt.hide_render = True
    (w, h), (pax, pay) = sizes.pop(), aspects.pop()
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    r.pixel_aspect_x, r.pixel_aspect_y = pax, pay
    scene.camera = cam_objs[0]
    s = scene.hairrecon
    s.camera_collection = cams
    s.photo_folder = ""
    masks = [v.get("mask") for v in views]
    if all(masks) and len({str(Path(m).parent) for m in masks}) == 1 and all(
        Path(m).stem == v["name"] == o.name for m, v, o in zip(masks, views, cam_objs)
    ):
        s.mask_folder = str(d / Path(masks[0]).parent)
    else:
        s.mask_folder = ""
    if "raw_mesh" in meshes:
        s.raw_mesh = meshes["raw_mesh"]
    if "scalp_mesh" in meshes:
        s.scalp_source = "OBJECT"
        s.scalp_object = meshes["scalp_mesh"]
    if "head_mesh" in meshes:
        s.head_object = meshes["head_mesh"]
    msg = f"Imported {len(views)} cameras ({w}x{h})"
    if skews:
        msg += f"; {skews} views have a skewed K, which Blender cameras cannot represent (skew dropped)"
    return ({"WARNING"} if skews else {"INFO"}), msg


class HAIRRECON_OT_export_hair(bpy.types.Operator, ExportHelper):
    """Write the selected hair curves (world space, root to tip) as .hair, .data or .ply"""

    bl_idname = "hairrecon.export_hair"
    bl_label = "Export Hair Strands"
    bl_options = {"REGISTER"}

    filename_ext = ".hair"
    filter_glob: StringProperty(default="*.hair;*.data;*.ply", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return any(o.type == "CURVES" for o in context.selected_objects)

    def check(self, context):
        # keep .data and .ply as typed; ExportHelper would force .hair
        return False

    def execute(self, context):
        path = Path(bpy.path.abspath(self.filepath))
        if path.suffix.lower() not in (".hair", ".data", ".ply"):
            self.report({"ERROR"}, f"{path.name}: choose a .hair, .data or .ply file (Alembic: File > Export > Alembic)")
            return {"CANCELLED"}
        objs = [o for o in context.selected_objects if o.type == "CURVES"]
        if not objs:
            self.report({"ERROR"}, "select the hair curves objects to export")
            return {"CANCELLED"}
        pts_all, counts_all = [], []
        depsgraph = context.evaluated_depsgraph_get()
        for o in objs:
            cv = o.evaluated_get(depsgraph).data
            n = len(cv.points)
            p = np.empty(n * 3, np.float32)
            cv.attributes["position"].data.foreach_get("vector", p)
            off = np.empty(len(cv.curves) + 1, np.int32)
            cv.curve_offset_data.foreach_get("value", off)
            m = np.array(o.matrix_world, np.float64)
            p = p.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            pts_all.append(p.astype(np.float32))
            counts_all.append(np.diff(off).astype(np.uint32))
        pts = np.concatenate(pts_all)
        counts = np.concatenate(counts_all)
        try:
            library().write_strands(str(path), np.ascontiguousarray(pts), np.ascontiguousarray(counts))
        except Exception as e:  # noqa: BLE001
            self.report({"ERROR"}, f"cannot write {path}: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {len(counts)} strands ({len(pts)} points) to {path}")
        return {"FINISHED"}


def menu_import(self, context):
    self.layout.operator(HAIRRECON_OT_import_capture.bl_idname, text="Hair Capture (hairrecon)")


def menu_export(self, context):
    self.layout.operator(HAIRRECON_OT_export_hair.bl_idname, text="Hair Strands (.hair, .data, .ply)")


CLASSES = (HAIRRECON_OT_reconstruct, HAIRRECON_OT_import_capture, HAIRRECON_OT_export_hair)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
    RUNNING.pop("reconstruct", None)
