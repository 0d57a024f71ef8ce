"""Isochor for Blender: volume-preserving solves on Blender's own lattice (an extension,
Blender 4.2+; the manifest is ``blender_manifest.toml``, ``make addon`` builds the zip).

Modules: :mod:`.rig` (the mesh and lattice as arrays, bpy-free: point orders, the Isochor
session, the capped solid whose volume is kept), :mod:`.scene` (reading and checking
Blender's data, writing points, volumes),
:mod:`.solving` (one solve on a background thread, the live solver, the bake),
:mod:`.sessions` (the Isochor session kept between solves of one mesh and lattice),
:mod:`.export` (the scene's problem as an Isochor scenario), :mod:`.caps` (an open mesh's
caps made real geometry), :mod:`.operators` (Preserve
Volume, Live, Bake, Measure, Export Scenario, Add Caps), :mod:`.panel` (the sidebar panel and its
settings), :mod:`.build` (the extension packages; not shipped in them).
"""

from __future__ import annotations

import bpy

from . import operators, panel
from .sessions import SESSIONS

_CLASSES = panel.CLASSES + operators.CLASSES


def register() -> None:
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.isochor = bpy.props.PointerProperty(type=panel.IsochorSettings)


def unregister() -> None:
    del bpy.types.Scene.isochor
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
    SESSIONS.clear()
