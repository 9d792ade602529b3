"""File > Import of photogrammetry calibrations: COLMAP models, Metashape cameras, transforms.json.

Each operator has the hairrecon library import the calibration, its photos and the raw mesh into a
capture folder (``hairrecon.import_colmap`` / ``import_metashape`` / ``import_nerf``: undistorted
working photos ``height`` pixels high), then builds the scene from that folder exactly as Import Hair
Capture does (``operators.build_capture_scene``). The capture keeps the tool's frame and units, and the
scene is built in that frame: no rotation or scale is applied.

On any error the operator reports one message and leaves the scene as it was; a capture folder it
wrote in that run is removed again (the library writes nothing when it fails or is cancelled).
"""

from __future__ import annotations

import shutil
import traceback
from pathlib import Path

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import scene_build
from .core.capture import CaptureInputError
from .operators import build_capture_scene
from .session import UserError, library

CAPTURE_FOLDER_NAME = "hairrecon_capture"

_FRAME_NOTE = (
    "The capture keeps the tool's frame and units, and the scene is built in that frame "
    "(no rotation or scale is applied)"
)


def _abs(path: str) -> Path:
    return Path(bpy.path.abspath(path)) if path else Path()


class _ImportCalibration(ImportHelper):
    """What the three importers share: the photos folder, the raw mesh, the working height, the
    capture folder, and the run itself. Subclasses say where the calibration is (``calibration()``),
    which library function imports it (``_function``) and where photos are by default."""

    bl_options = {"REGISTER", "UNDO"}

    photos_folder: StringProperty(
        name="Photos Folder",
        subtype="DIR_PATH",
        description="The folder the calibration's photo names are relative to",
    )
    mesh_file: StringProperty(
        name="Raw Mesh",
        subtype="FILE_PATH",
        description="The raw mesh of the head and hair from the same tool, in the calibration's frame (PLY or OBJ)",
    )
    height: IntProperty(
        name="Working Height",
        default=512,
        min=16,
        max=16384,
        subtype="PIXEL",
        description="Height of the undistorted working photos in pixels (the width keeps the photos' aspect)",
    )
    capture_folder: StringProperty(
        name="Capture Folder",
        subtype="DIR_PATH",
        description=f"The capture folder to write; it must not exist or be empty "
        f"(empty: {CAPTURE_FOLDER_NAME} in the calibration's folder)",
    )
    exif_orientation: BoolProperty(
        name="EXIF Orientation",
        default=False,
        description="When a photo's stored and EXIF-rotated pixels both fit its camera, take the rotated ones "
        "(default: the stored pixels, as COLMAP reads them)",
    )

    _function = ""  # the library's import function
    _what = ""  # for messages: "the COLMAP model", ...
    photos_required = False

    def calibration(self) -> Path:
        """The calibration the library reads (a folder for COLMAP, a file otherwise)."""
        return _abs(self.filepath)

    def calibration_folder(self) -> Path:
        c = self.calibration()
        return c if c.is_dir() else c.parent

    def _paths(self) -> tuple[Path, Path | None, Path, Path]:
        """(calibration, photos folder or None for the library's default, mesh, capture folder);
        raises UserError for a missing input or an existing non-empty capture folder."""
        cal = self.calibration()
        if not self.filepath or not cal.exists():
            raise UserError(f"{self._what} {cal} does not exist; pick it in the file browser")
        photos = _abs(self.photos_folder) if self.photos_folder else None
        if photos is None and self.photos_required:
            raise UserError(f"give the Photos Folder: {self._what} does not say where its photos are")
        if photos is not None and not photos.is_dir():
            raise UserError(f"the Photos Folder {photos} does not exist")
        if not self.mesh_file:
            raise UserError("give the Raw Mesh (PLY or OBJ) from the same tool, in the calibration's frame")
        mesh = _abs(self.mesh_file)
        out = _abs(self.capture_folder) if self.capture_folder else self.calibration_folder() / CAPTURE_FOLDER_NAME
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise UserError(
                f"the Capture Folder {out} exists and is not empty; choose a new folder or remove this one"
            )
        return cal, photos, mesh, out

    def _run(self, hr, cal: Path, photos: Path | None, mesh: Path, out: Path, wm) -> dict:
        fn = getattr(hr, self._function)
        kwargs = dict(height=self.height, exif_orientation=self.exif_orientation)

        def progress(done, total):
            wm.progress_update(int(1000 * done / max(total, 1)))

        if self.photos_required:
            return fn(str(cal), str(photos), str(mesh), str(out), progress=progress, **kwargs)
        return fn(str(cal), str(mesh), str(out), images=str(photos) if photos else None, progress=progress, **kwargs)

    def execute(self, context):
        wm = context.window_manager
        created = scene_build.Created()
        written = None  # the capture folder this run wrote, removed again if the scene cannot be built
        existed = False
        try:
            hr = library()
            cal, photos, mesh, out = self._paths()
            existed = out.exists()
            wm.progress_begin(0, 1000)
            try:
                result = self._run(hr, cal, photos, mesh, out, wm)
            finally:
                wm.progress_end()
            written = out
            level, msg = build_capture_scene(context, created, out)
        except Exception as e:  # noqa: BLE001 - reported once, the scene left as it was
            created.remove()
            if written is not None:
                shutil.rmtree(written, ignore_errors=True)
                if existed:
                    written.mkdir(exist_ok=True)
            self.report({"ERROR"}, self._message(e))
            return {"CANCELLED"}
        warnings = result.get("warnings") or []
        for w in warnings:
            print(f"hairrecon: import warning: {w}")
        if warnings:
            level = {"WARNING"}
            msg += f"; {len(warnings)} import warning{'s' * (len(warnings) > 1)} (see the console): {warnings[0]}"
        self.report(level, f"{msg} into {out}")
        return {"FINISHED"}

    def _message(self, e: Exception) -> str:
        """One line for the report."""
        if isinstance(e, (UserError, CaptureInputError)):
            return str(e)
        hr = library()
        if isinstance(e, hr.Cancelled):
            return "the import was cancelled; nothing was written"
        if isinstance(e, hr.Error):
            return f"cannot import {self._what}: {e}"
        traceback.print_exc()
        return f"cannot import {self._what}: {e}"


class HAIRRECON_OT_import_colmap(_ImportCalibration, bpy.types.Operator):
    """Import a COLMAP sparse model with its photos and the raw mesh"""

    bl_description = (
        "Import a COLMAP sparse model (pick cameras.bin or cameras.txt in its folder, e.g. sparse/0) with its photos and the raw mesh: writes a capture folder and builds the scene from it. "
        + _FRAME_NOTE
    )

    bl_idname = "hairrecon.import_colmap"
    bl_label = "Import COLMAP Model"
    filter_glob: StringProperty(default="*.bin;*.txt", options={"HIDDEN"})
    _function = "import_colmap"
    _what = "the COLMAP model"
    photos_required = True

    def calibration(self) -> Path:
        p = _abs(self.filepath)
        return p if p.is_dir() else p.parent


class HAIRRECON_OT_import_metashape(_ImportCalibration, bpy.types.Operator):
    """Import Agisoft Metashape cameras with their photos and the raw mesh"""

    bl_description = (
        "Import Agisoft Metashape cameras (the XML of File > Export > Export Cameras) with their photos and the raw mesh: writes a capture folder and builds the scene from it. "
        + _FRAME_NOTE
    )

    bl_idname = "hairrecon.import_metashape"
    bl_label = "Import Metashape Cameras"
    filename_ext = ".xml"
    filter_glob: StringProperty(default="*.xml", options={"HIDDEN"})
    _function = "import_metashape"
    _what = "the Metashape cameras file"


class HAIRRECON_OT_import_nerf(_ImportCalibration, bpy.types.Operator):
    """Import an instant-ngp or nerfstudio transforms.json with its photos and the raw mesh"""

    bl_description = (
        "Import an instant-ngp or nerfstudio transforms.json with its photos and the raw mesh: writes a capture folder and builds the scene from it. "
        + _FRAME_NOTE
    )

    bl_idname = "hairrecon.import_nerf"
    bl_label = "Import transforms.json"
    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})
    _function = "import_nerf"
    _what = "the transforms.json"


def menu_import(self, context):
    self.layout.operator(HAIRRECON_OT_import_colmap.bl_idname, text="COLMAP Model (hairrecon)")
    self.layout.operator(HAIRRECON_OT_import_metashape.bl_idname, text="Metashape Cameras (hairrecon)")
    self.layout.operator(HAIRRECON_OT_import_nerf.bl_idname, text="transforms.json (hairrecon)")


CLASSES = (HAIRRECON_OT_import_colmap, HAIRRECON_OT_import_metashape, HAIRRECON_OT_import_nerf)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
