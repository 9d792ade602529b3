"""Fit Head: the bundled head registered to the raw mesh (``hairrecon.fit_head``), added to the scene as
two mesh objects, ``Fitted Head`` and ``Fitted Scalp``, in a ``Fitted Head`` collection, in the scene's
frame. The user may sculpt or move them; Reconstruct Hair grows hair on the Hair panel's scalp, which
becomes the fitted scalp when none was chosen (or when the chosen one is an earlier fitted scalp).

The inputs follow Reconstruct Hair's rules: the cameras of the panel's Cameras collection and its Raw
Mesh (world space, modifiers applied), and the landmarks the user placed as empties named after them
(``nose_tip``, ``chin``, ``eye_outer_left``, ...; three or more start the fit from the pose they give).
The fit reads no photo. The library fits in a Python thread with
the GIL released (a fit takes seconds), while a modal operator keeps Blender responsive and builds the
objects on the main thread at the end; in background mode (scripts, tests) ``execute`` runs it
synchronously. A failed fit reports one error and leaves the scene as it was.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Optional

import bpy
import numpy as np

from . import scene_build, scene_read
from .core.camera import CameraInputError, blender_camera, opencv_from_blender
from .core.capture import CaptureInputError, check_mesh, write_fit_capture
from .session import FRAME_PROPERTY, RUNNING, UserError, library, panel_cameras

COLLECTION = "Fitted Head"
HEAD_NAME = "Fitted Head"
SCALP_NAME = "Fitted Scalp"
# custom property marking the objects a fit made ("head" or "scalp")
MARK = "hairrecon_fitted"
# custom property holding the similarity from the scene's frame to the canonical one (JSON)
FRAME = FRAME_PROPERTY
# what to do when the fit fails, added to the library's message
ADVICE = ("Pick the raw mesh of the head (with the face) in Raw Mesh, place landmarks on it (empties named "
          "nose_tip, chin, eye_outer_left, eye_outer_right, ear_left, ear_right; left and right the subject's own), "
          "or give the scalp by hand (Hair tab > Scalp)")

class FitRun:
    """One fit: the capture written from the scene, then ``hairrecon.fit_head`` on a thread."""

    def __init__(self, root: Path, capture: Path, raw_name: str, landmarks: int = 0):
        self.root = root
        self.capture = capture
        self.landmarks = landmarks  # how many landmark empties the fit starts from
        self.raw_name = raw_name  # the raw mesh object, named in messages instead of the temporary file
        self.result: Optional[dict] = None
        self.error: Optional[BaseException] = None
        self.started = time.monotonic()
        self.thread: Optional[threading.Thread] = None

    @classmethod
    def prepare(cls, context) -> "FitRun":
        """Writes the capture (cameras and raw mesh) into a temporary folder. Raises UserError; never
        changes bpy.data."""
        hr = library()
        if not hasattr(hr, "fit_head"):
            raise UserError(f"the hairrecon library {getattr(hr, '__version__', '?')} has no fit_head; install a newer extension")
        s = context.scene.hairrecon
        cams = panel_cameras(s)
        try:
            cameras = [(o.name, opencv_from_blender(blender_camera(o, context.scene))) for o in cams]
            raw = scene_read.raw_mesh_data(s.raw_mesh, context.evaluated_depsgraph_get())
            check_mesh(raw, "raw mesh")
            names = hr.head_landmarks() if hasattr(hr, "head_landmarks") else {}
            marks = scene_read.landmarks(context.scene, names)
        except (CameraInputError, CaptureInputError) as e:
            raise UserError(str(e)) from None
        root = Path(tempfile.mkdtemp(prefix="hairrecon-fit-"))
        try:
            capture = write_fit_capture(root / "capture", cameras, raw, hr)
            if marks:
                # the library reads them beside capture.json, in the capture's (the scene's) frame
                (capture.parent / "landmarks.json").write_text(json.dumps(marks))
        except CaptureInputError as e:
            shutil.rmtree(root, ignore_errors=True)
            raise UserError(str(e)) from None
        except Exception:
            shutil.rmtree(root, ignore_errors=True)
            raise
        return cls(root, capture, raw.name, len(marks))

    def run(self):
        """The fit itself (any thread: touches no bpy); removes the temporary folder afterwards."""
        try:
            self.result = library().fit_head(str(self.capture))
        except BaseException as e:  # noqa: BLE001 - handed to the main thread
            self.error = e
        finally:
            shutil.rmtree(self.root, ignore_errors=True)

    def start(self):
        self.thread = threading.Thread(target=self.run, name="hairrecon-fit-head", daemon=True)
        self.thread.start()

    def done(self) -> bool:
        return self.thread is None or not self.thread.is_alive()

    def finish(self, context) -> str:
        """Adds the fitted head and scalp (main thread) and points the panel at them; returns the
        report. Raises UserError (or the library's errors) and leaves bpy.data as it was."""
        if self.error is not None:
            hr = library()
            if isinstance(self.error, hr.Error):
                msg = str(self.error).replace(str(self.capture.parent / "raw_mesh.ply"), repr(self.raw_name))
                msg = msg.replace(f"the landmarks {self.capture.parent / 'landmarks.json'}", "the landmark empties")
                raise UserError(f"Fit Head failed: {msg}. {ADVICE}") from None
            raise self.error
        fit = self.result
        created = scene_build.Created()
        try:
            coll = created.add(bpy.data.collections.new(COLLECTION))
            objs = {}
            for key, name in (("head", HEAD_NAME), ("scalp", SCALP_NAME)):
                v, t = fit[key]
                obj = scene_build.mesh_object(created, coll, name, v, t)
                obj[MARK] = key
                # the frame the fit found, for Reconstruct Hair's capture (session.py)
                obj[FRAME] = json.dumps(fit["to_canonical"])
                objs[key] = obj
        except BaseException:
            created.remove()
            raise
        # everything exists: link it and point the panel at it (undone by undo, not by `created`)
        context.scene.collection.children.link(coll)
        used = use_fitted(context.scene.hairrecon, objs["head"], objs["scalp"])
        seconds = time.monotonic() - self.started
        scale = fit["to_canonical"]["scale"]
        from_marks = ""
        if fit.get("landmarks_rms_mm") is not None:
            from_marks = f", from {self.landmarks} landmarks {fit['landmarks_rms_mm']:.1f} mm from the template's"
            each = fit.get("landmarks_mm") or {}
            if each:
                far = max(each, key=each.get)
                from_marks += f" (farthest: {far}, {each[far]:.1f} mm)"
        msg = (
            f"Fitted the head in {seconds:.1f} s (residual {fit['residual_mm']:.2f} mm{from_marks}, "
            f"{100 * fit['on_mesh_fraction']:.0f}% of the skin on the raw mesh, {1 / scale:.4g} scene units per metre): "
            f"added {objs['head'].name!r} and {objs['scalp'].name!r}; "
        )
        if used is objs["scalp"]:
            msg += f"Reconstruct Hair grows hair on {used.name!r}"
        else:
            msg += f"Reconstruct Hair keeps the scalp you chose ({used})"
        return msg


def _is_fitted(obj, key: str) -> bool:
    try:
        return obj is not None and obj.get(MARK) == key
    except ReferenceError:
        return False


def use_fitted(s, head, scalp):
    """Makes the fitted scalp (and head) the panel's when none was chosen or the chosen one is an
    earlier fit's; returns the scalp object now used, or a description of the user's choice."""
    chosen = (
        s.scalp_object is not None
        if s.scalp_source == "OBJECT"
        else (s.head_object is not None and bool(s.scalp_vertex_group))
    )
    if chosen and not (s.scalp_source == "OBJECT" and _is_fitted(s.scalp_object, "scalp")):
        if s.scalp_source == "OBJECT":
            return repr(s.scalp_object.name)
        return f"the vertex group {s.scalp_vertex_group!r} of {s.head_object.name!r}"
    s.scalp_source = "OBJECT"
    s.scalp_object = scalp
    if s.head_object is None or _is_fitted(s.head_object, "head"):
        s.head_object = head
    return scalp


class HAIRRECON_OT_fit_head(bpy.types.Operator):
    """Fit the bundled head to the raw mesh: adds the fitted head and scalp as objects, and Reconstruct Hair grows hair on the fitted scalp unless another scalp is chosen"""

    bl_idname = "hairrecon.fit_head"
    bl_label = "Fit Head"
    bl_options = {"UNDO"}

    @classmethod
    def poll(cls, context):
        if RUNNING:
            cls.poll_message_set("a head fit or a hair reconstruction is running")
            return False
        return context.scene is not None

    def _start(self, context) -> Optional[FitRun]:
        try:
            run = FitRun.prepare(context)
        except UserError as e:
            self.report({"ERROR"}, str(e))
            return None
        except Exception as e:  # noqa: BLE001
            traceback.print_exc()
            self.report({"ERROR"}, f"cannot prepare the head fit: {e}")
            return None
        return run

    def _finish(self, context, run: FitRun) -> set:
        try:
            msg = run.finish(context)
        except UserError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        except Exception as e:  # noqa: BLE001
            traceback.print_exc()
            self.report({"ERROR"}, f"Fit Head failed: {e}")
            return {"CANCELLED"}
        warning = (run.result or {}).get("warning")
        if warning:
            # a close call: the fit may have taken the back of the head for its face
            self.report({"WARNING"}, f"{msg}. Check the fit: {warning}")
        else:
            self.report({"INFO"}, msg)
        return {"FINISHED"}

    def execute(self, context):
        """Synchronous path: background mode, scripts, tests."""
        run = self._start(context)
        if run is None:
            return {"CANCELLED"}
        run.run()
        return self._finish(context, run)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        run = self._start(context)
        if run is None:
            return {"CANCELLED"}
        run.start()
        RUNNING["fit_head"] = run
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.hairrecon_fitting = True
        if context.workspace is not None:
            context.workspace.status_text_set("Fitting the head to the raw mesh (Esc: stop waiting, add nothing)")
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _end_modal(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.hairrecon_fitting = False
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        RUNNING.pop("fit_head", None)
        for area in context.screen.areas if context.screen else ():
            if area.type == "VIEW_3D":
                area.tag_redraw()

    def modal(self, context, event):
        run: FitRun = RUNNING.get("fit_head")
        if run is None:
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            # the library's fit cannot be interrupted: it ends on its thread and its result is dropped
            self._end_modal(context)
            self.report({"WARNING"}, "Fit Head cancelled; nothing was added")
            return {"CANCELLED"}
        if event.type == "TIMER" and run.done():
            self._end_modal(context)
            return self._finish(context, run)
        return {"PASS_THROUGH"}

    def cancel(self, context):
        if "fit_head" in RUNNING:
            self._end_modal(context)


LANDMARKS = "Landmarks"  # the collection Add Landmarks puts its empties in


def landmark_places(context, names: dict) -> tuple[dict, str]:
    """Where Add Landmarks puts each landmark (name -> world point) and what from: where the panel's
    fitted head (or scalp) has it, or, with no fit, the bundled head's layout about the 3D cursor,
    Z up and the face toward -Y, at a size guessed from the raw mesh (a head and shoulders scan about
    0.7 m across)."""
    s = context.scene.hairrecon
    fitted = next((o for o, k in ((s.head_object, "head"), (s.scalp_object, "scalp")) if _is_fitted(o, k)), None)
    if fitted is not None and fitted.get(FRAME):
        f = json.loads(fitted[FRAME])
        r, t, k = np.array(f["rotation"]), np.array(f["translation"]), float(f["scale"])
        # canonical = k R x + t, so x = R^T (canonical - t) / k
        return {n: (r.T @ (np.array(p) - t) / k).tolist() for n, p in names.items()}, f"where {fitted.name!r} has them"
    per_metre = 1.0
    raw = s.raw_mesh
    if raw is not None and raw.type == "MESH":
        per_metre = max(raw.dimensions) / 0.7 if max(raw.dimensions) > 0 else 1.0
    c = np.array(context.scene.cursor.location)
    return {n: (c + per_metre * np.array(p)).tolist() for n, p in names.items()}, "about the 3D cursor (no fit yet)"


class HAIRRECON_OT_add_landmarks(bpy.types.Operator):
    """Add an empty for each landmark the head fit accepts (nose tip, chin, outer eye corners, ear openings), where the fitted head has it; move each onto its place on the raw mesh, then Fit Head again"""

    bl_idname = "hairrecon.add_landmarks"
    bl_label = "Add Landmarks"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            names = library().head_landmarks()
        except (UserError, AttributeError) as e:
            self.report({"ERROR"}, f"cannot add landmarks: {e}")
            return {"CANCELLED"}
        try:
            have = scene_read.landmarks(context.scene, names)
        except CaptureInputError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        places, where = landmark_places(context, names)
        missing = [n for n in names if n not in have]
        if not missing:
            self.report({"INFO"}, "every landmark has its empty already: move them onto the raw mesh, then Fit Head")
            return {"CANCELLED"}
        coll = bpy.data.collections.get(LANDMARKS)
        if coll is None:
            coll = bpy.data.collections.new(LANDMARKS)
            context.scene.collection.children.link(coll)
        size = 0.005 * (np.linalg.norm(np.subtract(places["ear_left"], places["ear_right"])) / 0.155)
        for n in missing:
            e = bpy.data.objects.new(n, None)
            e.empty_display_type = "SPHERE"
            e.empty_display_size = max(size, 1e-6)
            e.location = places[n]
            coll.objects.link(e)
        self.report({"INFO"}, f"added {len(missing)} landmark empties {where}: move each onto its place on the raw "
                              "mesh (left and right are the subject's own), then Fit Head")
        return {"FINISHED"}


CLASSES = (HAIRRECON_OT_fit_head, HAIRRECON_OT_add_landmarks)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
    RUNNING.pop("fit_head", None)
