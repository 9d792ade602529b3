"""One reconstruction run: scene -> capture folder -> library job -> hair Curves.

Used by the operator in both of its modes: the modal path polls :meth:`Session.progress` from a
window timer and calls :meth:`Session.cancel` on Esc; the synchronous path (background mode, batch
scripts, tests) waits in :meth:`Session.wait`. The library runs in its own thread with the GIL
released; nothing here touches bpy from another thread. :meth:`Session.finish` builds the objects on
the main thread and removes whatever it made if anything fails, so a failed or cancelled run leaves
the scene as it was.
"""

from __future__ import annotations

import inspect
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Optional

import bpy
import numpy as np

from .core.capture import CaptureInputError, MeshData, check_mesh, check_views, direct_color, hair_color, write_capture
from . import scene_build, scene_read


# custom property that Fit Head puts on the objects it adds: the similarity from the scene's frame to
# the canonical one, as JSON (``scale``, ``rotation`` by rows, ``translation``)
FRAME_PROPERTY = "hairrecon_to_canonical"
# the modal jobs running now, at most one of each kind ("reconstruct": a Session, "fit_head": a FitRun);
# Reconstruct Hair and Fit Head refuse to start while either runs
RUNNING: dict = {}


class UserError(Exception):
    """A problem to report to the user as it is (one clear message)."""


def panel_cameras(s) -> list:
    """The camera objects of the Hair panel's Cameras collection; UserError when there are none."""
    if s.camera_collection is None:
        raise UserError("no cameras: pick the collection that holds the calibrated cameras (Hair tab > Cameras)")
    cams = scene_read.cameras_of(s.camera_collection)
    if not cams:
        raise UserError(f"the collection {s.camera_collection.name!r} holds no cameras; add the calibrated cameras to it")
    return cams


def fitted_frame(obj) -> Optional[dict]:
    """The frame Fit Head found, when ``obj`` is one of the objects it added (else None)."""
    try:
        text = obj.get(FRAME_PROPERTY) if obj is not None else None
    except ReferenceError:
        return None
    if not isinstance(text, str):
        return None
    import json

    try:
        frame = json.loads(text)
    except ValueError:
        return None
    return frame if isinstance(frame, dict) and {"scale", "rotation", "translation"} <= frame.keys() else None


def library():
    """The hairrecon Rust module (bundled with the extension as a wheel)."""
    try:
        import hairrecon
    except ImportError as e:
        raise UserError(
            f"the hairrecon library is not installed ({e}); reinstall the extension from its zip file"
        ) from None
    return hairrecon


def _accepts(fn, name: str) -> bool:
    if fn is None:
        return False
    sig = getattr(fn, "__text_signature__", None) or ""
    if name in sig:
        return True
    try:
        return name in inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False


def curl_option(mode: str, radius_mm: float, period_mm: float, left: bool) -> str:
    """The library's `curl` argument for the panel's Curls settings."""
    if mode in ("CUSTOM", "COILS"):
        curl = f"{radius_mm:g},{period_mm:g},{-1 if left else 1}"
        return curl if mode == "CUSTOM" else f"fine:{curl}"
    return "off" if mode == "OFF" else "auto"


class Session:
    """A prepared capture and its running (or finished) job."""

    def __init__(self, capture_dir: Path, out_dir: Path, keep: bool, options: dict, surface: str, group: str):
        self.capture_dir = capture_dir
        self.out_dir = out_dir
        self.keep = keep
        self.options = options
        self.surface_name = surface
        self.group = group
        self.job = None
        self.started = 0.0
        self.result: Optional[dict] = None
        # the hair material's direct colour, from the hair's colour in the photos; None: a default brown
        self.hair_color: Optional[tuple] = None

    # --- preparing ----------------------------------------------------------------------------

    @classmethod
    def prepare(cls, context, output_directory: str = "") -> "Session":
        """Reads the scene's Hair panel settings, writes the capture and validates it with the
        library. Raises UserError with one clear message; never changes bpy.data."""
        hr = library()
        s = context.scene.hairrecon
        scene = context.scene
        cams = panel_cameras(s)
        try:
            views = scene_read.read_views(scene, cams, s.photo_folder, s.mask_folder)
            check_views(views)
            depsgraph = context.evaluated_depsgraph_get()
            raw = scene_read.raw_mesh_data(s.raw_mesh, depsgraph)
            check_mesh(raw, "raw mesh")
            head: Optional[MeshData] = None
            if s.scalp_source == "OBJECT":
                if s.scalp_object is None:
                    raise UserError("no scalp: pick the scalp mesh object (Hair tab > Scalp), or a vertex group of the head mesh")
                if s.scalp_object.type != "MESH":
                    raise UserError(f"the scalp {s.scalp_object.name!r} is not a mesh object")
                scalp, _ = scene_read.scalp_data(s.scalp_object, depsgraph)
                surface, group = s.scalp_object.name, ""
                # The head, when there is one, hides the strands behind it (DR, visual hull) and keeps
                # them out of it; without it the hull cuts what the cameras see through the head.
                if s.head_object is not None:
                    if s.head_object.type != "MESH":
                        raise UserError(f"the head mesh {s.head_object.name!r} is not a mesh object")
                    v, t, _ = scene_read.mesh_of(s.head_object, depsgraph)
                    head = MeshData(s.head_object.name, v, t)
                    check_mesh(head, "head mesh")
            else:
                obj = s.head_object
                if obj is None or obj.type != "MESH":
                    raise UserError("no head mesh: pick the head mesh whose vertex group is the scalp (Hair tab > Scalp)")
                if not s.scalp_vertex_group:
                    raise UserError(f"no scalp vertex group: pick the vertex group of {obj.name!r} that covers the scalp")
                v, t, _ = scene_read.mesh_of(obj, depsgraph)
                head = MeshData(obj.name, v, t)
                check_mesh(head, "head mesh")
                scalp, _ = scene_read.scalp_data(obj, depsgraph, s.scalp_vertex_group)
                surface, group = obj.name, s.scalp_vertex_group
            check_mesh(scalp, "scalp")
        except CaptureInputError as e:
            raise UserError(str(e)) from None

        keep = bool(output_directory)
        if keep:
            root = Path(bpy.path.abspath(output_directory))
            capture_dir = root / "capture"
            out_dir = root / "result"
            if capture_dir.exists():
                shutil.rmtree(capture_dir)
            capture_dir.mkdir(parents=True, exist_ok=True)
        else:
            root = Path(tempfile.mkdtemp(prefix="hairrecon-"))
            capture_dir, out_dir = root / "capture", root / "result"
            capture_dir.mkdir()
        try:
            # a scalp (or head) that Fit Head added carries the frame it found: the run works in the
            # canonical frame and its strands come back in the scene's
            frame = fitted_frame(s.scalp_object if s.scalp_source == "OBJECT" else s.head_object)
            write_capture(capture_dir, views, raw, hr, head_mesh=head, scalp_mesh=scalp, to_canonical=frame)
            hr.load_capture(str(capture_dir))
        except CaptureInputError as e:
            cls._remove(root, keep)
            raise UserError(str(e)) from None
        except hr.HairreconError as e:
            cls._remove(root, keep)
            raise UserError(f"the capture is not valid: {e}") from None
        except Exception:
            cls._remove(root, keep)
            raise
        out_dir.mkdir(parents=True, exist_ok=True)
        options = {"guides": int(s.guides), "children": int(s.children), "seed": int(s.seed)}
        if s.stop_after.strip():
            options["stop_after"] = s.stop_after.strip()
        if _accepts(getattr(hr, "Reconstruction", None), "dr"):
            options["dr"] = bool(s.dr)
            options["dr_iters_guides"] = int(s.dr_iters_guides)
            options["dr_iters_children"] = int(s.dr_iters_children)
        elif s.dr:
            log("this hairrecon library has no strand optimization (DR); the grown strands are the result")
        if _accepts(getattr(hr, "Reconstruction", None), "hull_trim"):
            options["hull_trim"] = bool(s.hull_trim)
        if _accepts(getattr(hr, "Reconstruction", None), "parting"):
            options["parting"] = bool(s.parting)
        if _accepts(getattr(hr, "Reconstruction", None), "curl"):
            options["curl"] = curl_option(s.curl, s.curl_radius_mm, s.curl_period_mm, s.curl_left)
        session = cls(capture_dir, out_dir, keep, options, surface, group)
        session.root = root
        seen = hair_color(views)
        session.hair_color = direct_color(seen) if seen is not None else None
        return session

    @staticmethod
    def _remove(root: Path, keep: bool):
        if not keep:
            shutil.rmtree(root, ignore_errors=True)

    def cleanup(self):
        self._remove(self.root, self.keep)

    # --- running ------------------------------------------------------------------------------

    def start(self):
        hr = library()
        if not hasattr(hr, "Reconstruction"):
            raise UserError(
                f"the hairrecon library {getattr(hr, '__version__', '?')} has no Reconstruction; install a newer extension"
            )
        self.job = hr.Reconstruction(str(self.capture_dir), str(self.out_dir), **self.options)
        self.started = time.monotonic()
        self.job.start()

    def progress(self) -> tuple[float, str]:
        f, text = self.job.progress()
        return float(f), str(text)

    def done(self) -> bool:
        return bool(self.job.done())

    def cancel(self):
        self.job.cancel()

    def wait(self, echo: bool = False, poll: float = 0.1):
        """Blocks until the job ends; with echo, prints progress lines as they change."""
        last = None
        while not self.done():
            if echo:
                f, text = self.progress()
                line = f"hairrecon: {100 * f:5.1f}% {text}"
                if line != last:
                    print(line, flush=True)
                    last = line
            time.sleep(poll)

    # --- finishing ----------------------------------------------------------------------------

    def finish(self, context) -> dict:
        """Builds the hair objects from the job's result (main thread). Raises UserError (or the
        library's Cancelled) and leaves bpy.data as it was on any failure. Returns a summary."""
        hr = library()
        created = scene_build.Created()
        try:
            try:
                result = self.job.result()
            except hr.Cancelled:
                raise
            except hr.HairreconError as e:
                raise UserError(f"the reconstruction failed: {e}") from None
            self.result = result
            surface = bpy.data.objects.get(self.surface_name)
            if surface is None or surface.type != "MESH":
                raise UserError(f"the scalp object {self.surface_name!r} was removed during the reconstruction")
            files = [(k, result.get(k)) for k in ("strands", "guides")]
            files = [(k, p) for k, p in files if p]
            if not files:
                raise UserError("the reconstruction wrote no strands (check Stop After)")
            sets = {}
            for k, p in files:
                pts, counts = hr.read_strands(str(p))
                if len(counts) == 0:
                    raise UserError(f"the reconstruction's {k} file {p} holds no strands")
                if not np.isfinite(pts).all():
                    raise UserError(f"the reconstruction's {k} file {p} holds points that are not finite numbers")
                sets[k] = (np.asarray(pts, np.float32).reshape(-1, 3), np.asarray(counts, np.int64))
            had_uv = surface.data.uv_layers.active is not None
            had_rest = surface.add_rest_position_attribute
            uv_layer_name = scene_build.ensure_uv_map(surface, self.group or None)
            try:
                material = created.add(scene_build.hair_material("Hair", self.hair_color))
                summary = {"objects": [], "seconds": time.monotonic() - self.started}
                base = f"{surface.name} Hair"
                for k in ("strands", "guides"):
                    if k not in sets:
                        continue
                    pts, counts = sets[k]
                    name = base if k == "strands" else f"{base} Guides"
                    obj, dist = scene_build.add_hair_object(context, created, name, pts, counts, surface, material)
                    if k == "guides" and "strands" in sets:
                        obj.hide_render = True
                    summary["objects"].append(obj.name)
                    summary[k] = {"object": obj.name, "count": int(len(counts)), "max_root_distance_m": float(dist.max())}
                # the Deform Curves on Surface node needs the scalp's rest position
                surface.add_rest_position_attribute = True
            except Exception:
                surface.add_rest_position_attribute = had_rest
                if not had_uv:
                    layer = surface.data.uv_layers.get(uv_layer_name)
                    if layer is not None:
                        surface.data.uv_layers.remove(layer)
                raise
            if summary["objects"]:
                first = bpy.data.objects[summary["objects"][0]]
                for o in context.view_layer.objects:
                    o.select_set(False)
                if first.name in context.view_layer.objects:
                    first.select_set(True)
                    context.view_layer.objects.active = first
            summary["stage_times"] = list(result.get("stage_times", []))
            summary["report"] = dict(result.get("report", {}) or {})
            return summary
        except BaseException:
            created.remove()
            raise
        finally:
            self.cleanup()


def describe(summary: dict) -> str:
    parts = []
    for k, label in (("strands", "strands"), ("guides", "guides")):
        if k in summary:
            d = summary[k]
            parts.append(f"{d['count']} {label} in {d['object']!r}")
    worst = max((summary[k]["max_root_distance_m"] for k in ("strands", "guides") if k in summary), default=0.0)
    return f"Hair reconstructed: {', '.join(parts)}; roots within {1000 * worst:.2f} mm of the scalp; {summary['seconds']:.1f} s"


def log(msg: str):
    print(f"hairrecon: {msg}", file=sys.stderr, flush=True)
