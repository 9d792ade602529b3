"""The Hair tab of the 3D viewport's sidebar."""

from __future__ import annotations

import bpy


def _scalp_used(s) -> str:
    """What Reconstruct Hair grows hair on, for the panel."""
    if s.scalp_source == "OBJECT":
        if s.scalp_object is None:
            return "No scalp: pick one, or Fit Head adds one"
        return f"Hair grows on {s.scalp_object.name}"
    if s.head_object is None or not s.scalp_vertex_group:
        return "No scalp: pick a vertex group, or Fit Head adds a scalp"
    return f"Hair grows on {s.head_object.name}'s group {s.scalp_vertex_group}"


def _landmarks_line(scene) -> str:
    """How many landmark empties Fit Head will start from, for the panel ("" when none or the library
    is missing)."""
    try:
        from .scene_read import landmarks
        from .session import library

        found = landmarks(scene, library().head_landmarks())
    except Exception:  # noqa: BLE001 - a panel line never fails the panel; Fit Head says what is wrong
        return ""
    if not found:
        return ""
    if len(found) < 3:
        return f"{len(found)} landmark empties: Fit Head needs three or more to use them"
    return f"Fit Head starts from {len(found)} landmark empties"


class HAIRRECON_PT_reconstruct(bpy.types.Panel):
    bl_label = "Hair Reconstruction"
    bl_idname = "HAIRRECON_PT_reconstruct"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Hair"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.hairrecon
        wm = context.window_manager

        col = layout.column(heading="Input")
        col.prop(s, "camera_collection")
        col.prop(s, "photo_folder")
        col.prop(s, "mask_folder")
        col.prop(s, "raw_mesh")

        col = layout.column()
        col.prop(s, "scalp_source")
        if s.scalp_source == "OBJECT":
            col.prop(s, "scalp_object")
            col.prop(s, "head_object")
        else:
            col.prop(s, "head_object")
            if s.head_object is not None:
                col.prop_search(s, "scalp_vertex_group", s.head_object, "vertex_groups")
            else:
                col.prop(s, "scalp_vertex_group")
        col.label(text=_scalp_used(s), icon="INFO")

        col = layout.column()
        col.prop(s, "quality")
        sub = col.column(align=True)
        sub.prop(s, "guides")
        sub.prop(s, "children")
        col.prop(s, "dr")
        sub = col.column(align=True)
        sub.enabled = s.dr
        sub.prop(s, "dr_iters_guides")
        sub.prop(s, "dr_iters_children")

        layout.separator()
        if wm.hairrecon_running:
            layout.progress(factor=wm.hairrecon_progress, type="BAR", text=wm.hairrecon_status or "Running")
            layout.label(text="Press Esc in the viewport to cancel", icon="INFO")
        elif wm.hairrecon_fitting:
            layout.label(text="Fitting the head to the raw mesh...", icon="TIME")
        else:
            row = layout.row(align=True)
            row.operator("hairrecon.fit_head", icon="USER")
            row.operator("hairrecon.reconstruct", icon="CURVES")
            layout.operator("hairrecon.add_landmarks", icon="EMPTY_AXIS")
            line = _landmarks_line(context.scene)
            if line:
                layout.label(text=line, icon="INFO")
        ob = context.active_object
        if ob is not None and ob.type == "CURVES":
            layout.operator("hairrecon.test_physics", icon="PHYSICS")
        row = layout.row(align=True)
        row.operator("hairrecon.import_capture", text="Import Capture", icon="IMPORT")
        row.operator("hairrecon.export_hair", text="Export Hair", icon="EXPORT")


class HAIRRECON_PT_advanced(bpy.types.Panel):
    bl_label = "Advanced"
    bl_parent_id = "HAIRRECON_PT_reconstruct"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Hair"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        s = context.scene.hairrecon
        layout.prop(s, "seed")
        layout.prop(s, "hull_trim")
        layout.prop(s, "parting")
        layout.prop(s, "curl")
        if s.curl in ("CUSTOM", "COILS"):
            layout.prop(s, "curl_radius_mm")
            layout.prop(s, "curl_period_mm")
            layout.prop(s, "curl_left")
        layout.prop(s, "stop_after")


CLASSES = (HAIRRECON_PT_reconstruct, HAIRRECON_PT_advanced)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
