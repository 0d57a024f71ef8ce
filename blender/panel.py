"""The sidebar panel (View3D > Sidebar > Isochor) and the scene's settings it shows."""

from __future__ import annotations

import bpy

from .scene import holes_capped


class IsochorSettings(bpy.types.PropertyGroup):
    pins: bpy.props.EnumProperty(
        name="Pins",
        items=[
            ("SELECTED", "Selected Points", "Pin the lattice's selected points"),
            ("GROUP", "Vertex Group", "Pin the lattice points in a vertex group"),
        ],
        default="SELECTED",
    )
    group: bpy.props.StringProperty(name="Group", description="The lattice's vertex group of pins")
    preserve: bpy.props.EnumProperty(
        name="Volumes",
        description="How the meshes under the lattice count",
        items=[
            ("TOTAL", "Summed", "Keep the sum of the volumes of every mesh under the lattice"),
            ("BODIES", "Each Body", "Keep each closed body's own volume (each mesh, each part)"),
        ],
        default="TOTAL",
    )
    ratio: bpy.props.FloatProperty(
        name="Volume Ratio",
        description="The volume to keep, as a ratio of the mesh's rest volume",
        default=1.0,
        min=0.05,
        max=20.0,
    )
    live: bpy.props.BoolProperty(name="Live", default=False)
    frame_start: bpy.props.IntProperty(name="Start", default=1)
    frame_end: bpy.props.IntProperty(name="End", default=24)
    volume: bpy.props.FloatProperty(name="Volume", default=0.0)
    volume_ratio: bpy.props.FloatProperty(name="Ratio", default=0.0)
    holes: bpy.props.IntProperty(name="Holes Capped", default=0)


class VIEW3D_PT_isochor(bpy.types.Panel):
    bl_label = "Isochor"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Isochor"

    def draw(self, context):
        props, layout = context.scene.isochor, self.layout
        layout.prop(props, "pins")
        if props.pins == "GROUP":
            lattice = _lattice(context)
            if lattice is not None:
                layout.prop_search(props, "group", lattice, "vertex_groups")
            else:
                layout.prop(props, "group")
        layout.prop(props, "preserve")
        layout.prop(props, "ratio")
        row = layout.row(align=True)
        row.operator("isochor.preserve_volume", icon="MOD_LATTICE")
        row.operator("isochor.live", text="Stop Live" if props.live else "Live", depress=props.live)
        box = layout.box()
        box.label(text="Bake keyframed points")
        row = box.row(align=True)
        row.prop(props, "frame_start")
        row.prop(props, "frame_end")
        box.operator("isochor.bake", icon="KEYINGSET")
        layout.operator("isochor.export_scenario", text="Export Scenario", icon="EXPORT")
        row = layout.row()
        if props.volume_ratio:
            capped = f", {holes_capped(props.holes)}" if props.holes else ""
            row.label(
                text=f"Volume {props.volume:.4g} ({100 * props.volume_ratio:.2f} % of rest{capped})"
            )
        else:
            row.label(text="Volume: not measured")
        row.operator("isochor.measure", text="", icon="FILE_REFRESH")
        if props.holes:
            layout.operator("isochor.add_caps", icon="MESH_DATA")


def _lattice(context):
    obj = context.active_object
    if obj is None:
        return None
    if obj.type == "LATTICE":
        return obj
    mods = [m for m in getattr(obj, "modifiers", []) if m.type == "LATTICE" and m.object]
    return mods[0].object if mods else None


CLASSES = (IsochorSettings, VIEW3D_PT_isochor)
