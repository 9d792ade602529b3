"""The Hair panel's settings, stored on the scene (``scene.hairrecon``) so they are saved in the
.blend and batch runs pick them up."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty, FloatProperty, BoolProperty

# guides, children, iterations per quality preset
PRESETS = {
    "PREVIEW": (300, 3000, 100),
    "STANDARD": (2000, 50000, 500),
    "HIGH": (4000, 100000, 1500),
}


def _is_mesh(_self, obj):
    return obj.type == "MESH"


def _apply_preset(self, _context):
    if self.quality in PRESETS:
        g, c, i = PRESETS[self.quality]
        # assign only when different: each assignment would call _to_custom
        self["guides"], self["children"], self["iterations"] = g, c, i


def _to_custom(self, _context):
    g, c, i = self.guides, self.children, self.iterations
    if self.quality in PRESETS and PRESETS[self.quality] != (g, c, i):
        self["quality"] = 3  # CUSTOM (index into the enum items)


class HairreconSettings(bpy.types.PropertyGroup):
    camera_collection: PointerProperty(
        name="Cameras",
        type=bpy.types.Collection,
        description="Collection holding the calibrated cameras (one per photo)",
    )
    photo_folder: StringProperty(
        name="Photos",
        subtype="DIR_PATH",
        description="Folder of photos named after the cameras, for cameras without a background image",
    )
    mask_folder: StringProperty(
        name="Masks",
        subtype="DIR_PATH",
        description="Optional folder of hair masks named after the cameras (or their photos); white = hair",
    )
    raw_mesh: PointerProperty(
        name="Raw Mesh",
        type=bpy.types.Object,
        poll=_is_mesh,
        description="Photogrammetry mesh of the head and hair (MetaShape, RealityCapture, COLMAP)",
    )
    scalp_source: EnumProperty(
        name="Scalp",
        items=[
            ("OBJECT", "Object", "A mesh object covering the scalp, where the hair grows"),
            ("VERTEX_GROUP", "Vertex Group", "A vertex group of the head mesh"),
        ],
        default="OBJECT",
    )
    scalp_object: PointerProperty(name="Scalp Object", type=bpy.types.Object, poll=_is_mesh)
    head_object: PointerProperty(name="Head Mesh", type=bpy.types.Object, poll=_is_mesh)
    scalp_vertex_group: StringProperty(name="Vertex Group", description="The head mesh's vertex group of the scalp")
    quality: EnumProperty(
        name="Quality",
        items=[
            ("PREVIEW", "Preview", "Few strands, few iterations: a quick look"),
            ("STANDARD", "Standard", "2,000 guides and 50,000 strands, as in the paper"),
            ("HIGH", "High", "More guides, strands and iterations"),
            ("CUSTOM", "Custom", "Counts set by hand"),
        ],
        default="STANDARD",
        update=_apply_preset,
    )
    guides: IntProperty(name="Guides", default=2000, min=1, soft_max=20000, update=_to_custom,
                        description="Number of guide strands grown and optimized first")
    children: IntProperty(name="Strands", default=50000, min=0, soft_max=200000, update=_to_custom,
                          description="Number of child strands interpolated from the guides and optimized")
    iterations: IntProperty(name="Iterations", default=500, min=0, soft_max=5000, update=_to_custom,
                            description="Optimization iterations (used when the library supports it)")
    seed: IntProperty(name="Seed", default=0, min=0)
    stop_after: StringProperty(
        name="Stop After",
        description="Advanced: stop the pipeline after this stage: orient2d, orient3d, direction, init (empty = run it all)",
    )


CLASSES = (HairreconSettings,)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.hairrecon = PointerProperty(type=HairreconSettings)
    wm = bpy.types.WindowManager
    wm.hairrecon_running = BoolProperty(default=False, options={"SKIP_SAVE"})
    wm.hairrecon_progress = FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR", options={"SKIP_SAVE"})
    wm.hairrecon_status = StringProperty(default="", options={"SKIP_SAVE"})


def unregister():
    wm = bpy.types.WindowManager
    for n in ("hairrecon_running", "hairrecon_progress", "hairrecon_status"):
        if hasattr(wm, n):
            delattr(wm, n)
    del bpy.types.Scene.hairrecon
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
