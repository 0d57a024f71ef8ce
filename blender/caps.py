"""The caps Isochor puts over an open mesh's holes, made real geometry of the mesh (the
panel's "Add Caps"), so that Blender itself can measure the volume a solve keeps.

A hole is a loop of boundary edges (edges with one face). Isochor closes it with a fan: one
cap point, the loop's midpoint weighted by edge length (the centre of the loop as a wire:
``sum(|e| * mid(e)) / sum(|e|)`` over its edges), and a triangle from each edge to it, wound
against the edge's own face so the closed solid is consistently oriented
(:func:`isochor.core.io.caps.cap_holes`, which
:func:`isochor.core.io.repair.clean_closed_surface` runs).
The cap point is a point of space under the lattice like any vertex, so a real cap vertex
moves with Blender's Lattice modifier exactly as Isochor's virtual one moves with its FFD:
the volume Blender measures on the capped mesh is the one the solve keeps."""

from __future__ import annotations

import numpy as np

from .rig import rows_at
from .scene import RigError


def add_caps(obj) -> int:
    """Add the caps of ``obj``'s holes to its mesh data (vertices and triangles);
    returns how many holes were capped. Refused, in one line, in the mesh's Edit Mode
    and on a mesh with shape keys (the cap vertices would have no place in the keys)."""
    import bmesh

    from isochor.core.io.repair import clean_closed_surface

    if obj is None or obj.type != "MESH":
        raise RigError("Isochor: select the open mesh to cap")
    if obj.mode == "EDIT":
        raise RigError(f"Isochor: leave Edit Mode of {obj.name!r} to add its caps")
    mesh = obj.data
    if mesh.shape_keys is not None:
        raise RigError(f"Isochor: {obj.name!r} has shape keys; add the caps before the keys")
    mesh.calc_loop_triangles()
    if not len(mesh.loop_triangles):
        raise RigError(f"Isochor: mesh {obj.name!r} has no faces")
    vertices = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", vertices)
    vertices = vertices.reshape(-1, 3)
    faces = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", faces)
    clean, _, _ = clean_closed_surface(vertices, faces.reshape(-1, 3).astype(np.int64))
    if not clean.cap_vertices:
        return 0
    own = clean.own_vertices
    index = np.concatenate([rows_at(clean.vertices[:own], vertices),
                            len(vertices) + np.arange(clean.cap_vertices)])  # fmt: skip
    bm = bmesh.new()
    try:
        bm.from_mesh(mesh)
        for co in clean.vertices[own:]:
            bm.verts.new(co)
        bm.verts.ensure_lookup_table()
        for tri in index[clean.faces[clean.own_faces :]]:
            bm.faces.new([bm.verts[int(i)] for i in tri])
        bm.to_mesh(mesh)
    finally:
        bm.free()
    mesh.update()
    return int(clean.cap_vertices)
