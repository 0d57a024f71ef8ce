"""Scenes for the add-on's tests and benchmark, in Blender's Python (bpy, bmesh and numpy
only: the interpreter that holds only bpy runs them too)."""

from __future__ import annotations

import bmesh
import bpy
import numpy as np


def empty_scene() -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)


def sphere(name: str = "ball", subdivisions: int = 3, radius: float = 0.8):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=subdivisions, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def lattice(shape, kind: str, size=(2.0, 2.0, 2.0), name: str = "cage"):
    """A lattice object of ``shape`` points whose rest grid spans ``size`` about the origin."""
    data = bpy.data.lattices.new(name)
    data.points_u, data.points_v, data.points_w = shape
    for axis in "uvw":
        setattr(data, f"interpolation_type_{axis}", kind)
    ob = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(ob)
    first, last = np.array(data.points[0].co), np.array(data.points[-1].co)
    ob.scale = tuple(np.asarray(size) / (last - first))
    return ob


def pin_and_drag(lat, lift: float, height: float | None = None) -> np.ndarray:
    """Pins the bottom two layers (w = 0, 1) and the top layer's middle points, moved up by
    ``lift`` of the lattice's ``height`` (its rest grid's, by default); returns the pinned
    mask (Blender's order)."""
    data = lat.data
    pu, pv, pw = data.points_u, data.points_v, data.points_w
    w, v, u = np.unravel_index(np.arange(len(data.points)), (pw, pv, pu))
    middle = (np.abs(u - (pu - 1) / 2) <= 0.5) & (np.abs(v - (pv - 1) / 2) <= 0.5)
    dragged = (w == pw - 1) & middle
    pinned = (w <= 1) | dragged
    data.points.foreach_set("select", pinned)
    if height is None:
        height = data.points[-1].co[2] - data.points[0].co[2]
    for i in np.flatnonzero(dragged):
        data.points[int(i)].co_deform.z += lift * height
    return pinned
