"""The Hair panel's settings, stored on the scene (``scene.hairrecon``) so they are saved in the
.blend and batch runs pick them up."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty, FloatProperty, BoolProperty

# guides, children, DR steps on the guides, DR steps on the children, per quality preset
PRESETS = {
    "PREVIEW": (300, 3000, 30, 10),
    "STANDARD": (2000, 50000, 60, 20),
    "HIGH": (4000, 100000, 120, 40),
}
_COUNTS = ("guides", "children", "dr_iters_guides", "dr_iters_children")


def _is_mesh(_self, obj):
    return obj.type == "MESH"


def _apply_preset(self, _context):
    if self.quality in PRESETS:
        # item assignment does not call _to_custom
        for k, v in zip(_COUNTS, PRESETS[self.quality]):
            self[k] = v


def _to_custom(self, _context):
    if self.quality in PRESETS and PRESETS[self.quality] != tuple(getattr(self, k) for k in _COUNTS):
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
    head_object: PointerProperty(
        name="Head Mesh",
        type=bpy.types.Object,
        poll=_is_mesh,
        description="The head without hair (optional with a scalp object): strands behind it are hidden, "
        "none end up inside it",
    )
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
    dr: BoolProperty(name="Optimize strands (DR)", default=True,
                     description="Optimize the strands by differentiable rendering against the photos after growing "
                                 "them (slower, closer to the photos); off keeps the grown strands")
    dr_iters_guides: IntProperty(name="Guide Steps", default=60, min=0, soft_max=2000, update=_to_custom,
                                 description="Optimization steps on the guides (the strands follow them)")
    dr_iters_children: IntProperty(name="Strand Steps", default=20, min=0, soft_max=2000, update=_to_custom,
                                   description="Optimization steps on every strand after the guides")
    seed: IntProperty(name="Seed", default=0, min=0)
    hull_trim: BoolProperty(name="Cut at Visual Hull", default=True,
                            description="Before optimizing, cut each grown strand where a photo sees it outside its "
                                        "hair mask (and not behind the head); off keeps the strands whole")
    parting: BoolProperty(name="Find Partings", default=True,
                          description="Where the photos see the scalp's skin (a parting), the hair beside it "
                                      "leaves it sideways; off leaves the photos' strand directions there")
    curl: EnumProperty(
        name="Curls",
        items=(
            ("AUTO", "Auto", "The photos decide whether the hair is curly, the ringlets' handedness and their "
                             "period (the radius follows from a 60° pitch, 50° for looser curls)"),
            ("OFF", "Off", "Strands follow the hair's visible direction, as for straight and wavy hair"),
            ("CUSTOM", "Custom", "Ringlets of the radius, period and handedness given below"),
            ("COILS", "Tight Coils", "Coils finer than the photos resolve (Auto cannot tell them): strands follow "
                                     "the ropes the photos show, with helices of the radius, period and "
                                     "handedness given below"),
        ),
        default="AUTO",
    )
    curl_radius_mm: FloatProperty(name="Curl Radius (mm)", default=6.5, min=0.5, max=50.0,
                                  description="Radius of the ringlets (Custom curls, Tight Coils)")
    curl_period_mm: FloatProperty(name="Curl Period (mm)", default=22.0, min=2.0, max=200.0,
                                  description="Length along the ringlet per turn (Custom curls, Tight Coils)")
    curl_left: BoolProperty(name="Left-Handed Curls", default=False,
                            description="Custom curls and Tight Coils turn left-handed from root to tip (off: right-handed)")
    stop_after: StringProperty(
        name="Stop After",
        description="Advanced: stop the pipeline after this stage: orient2d, orient3d, partings, direction, init (empty = run it all)",
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
    wm.hairrecon_fitting = BoolProperty(default=False, options={"SKIP_SAVE"})  # Fit Head is running


def unregister():
    wm = bpy.types.WindowManager
    for n in ("hairrecon_running", "hairrecon_progress", "hairrecon_status", "hairrecon_fitting"):
        if hasattr(wm, n):
            delattr(wm, n)
    del bpy.types.Scene.hairrecon
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
