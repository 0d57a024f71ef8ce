"""No rigid drift: which lattice nodes to hold when the user's fixed nodes do not.

Springs with rest lengths cost nothing under a rigid motion, so with too few fixed nodes a
drag is cheapest as a translation and turn of the whole lattice: drag one corner of the
cow's lattice and the cow slides away instead of stretching. An artist expects the part
away from the edit to stay put.

The rule (``Goal.anchor == "far-side"``, the default): when the fixed coordinates still
allow a rigid motion of the lattice, and some fixed node has been moved from its rest place,
the lattice face farthest from the moved nodes is held where it is. "Farthest" is measured
at rest: each of the six faces scores the distance from its plane to the nearest moved node,
and the highest score wins (ties go to the first axis, the low face first). Holding a whole
face removes every rigid motion, and the edit squashes or stretches the lattice between the
moved nodes and the held face. A user who pins enough nodes to hold the lattice (three
nodes not on one line, for example) gets exactly what they pinned.
"""

from __future__ import annotations

import numpy as np

from ..lattice import Lattice

AXES = "xyz"


def rigid_freedom(points: np.ndarray, fixed: np.ndarray, rows: np.ndarray | None = None) -> int:
    """How many independent rigid motions (of 6) leave every fixed coordinate in place.

    A small rigid motion moves a point ``p`` by ``t + w x p``; a fixed coordinate ``a`` of
    ``p`` asks ``e_a . (t + w x p) = t_a + w . (p x e_a) = 0``. A linear constraint
    ``sum_j r_j . x_j`` (a handle) asks ``t . sum_j r_j + w . sum_j p_j x r_j = 0``. The
    motions left are the null space of those rows.

    Parameters
    ----------
    points : (n, 3) node positions
    fixed : (n, 3) bool, the fixed coordinates
    rows : (k, n, 3) linear constraints on the nodes besides them, or None
    """
    nodes_, axes = np.nonzero(fixed)
    p = (points - points.mean(axis=0)) / max(float(np.ptp(points, axis=0).max()), 1e-300)
    e = np.eye(3)[axes]
    m = np.hstack([e, np.cross(p[nodes_], e)])
    if rows is not None and len(rows):
        m = np.vstack([m, np.hstack([rows.sum(axis=1), np.cross(p, rows).sum(axis=1)])])
    if not len(m):
        return 6
    s = np.linalg.svd(m, compute_uv=False)
    return 6 - int(np.sum(s > 1e-9 * s[0]))


def held_face(
    lattice: Lattice,
    nodes: np.ndarray,
    fixed: np.ndarray,
    *,
    rows: np.ndarray | None = None,
    points: np.ndarray | None = None,
    mirror_axis: int | None = None,
) -> tuple[np.ndarray, str]:
    """The nodes the far-side rule holds, and a name for them (``"x min"``, ...).

    Parameters
    ----------
    lattice : the lattice (its rest nodes tell which nodes were moved, and face distances)
    nodes : (n, 3) current node positions
    fixed : (n, 3) bool, the fixed coordinates
    rows : (k, n, 3) the handles' linear constraints, which hold the lattice too
    points : (h, 3) the handles' rest points: edits, like the moved nodes
    mirror_axis : under symmetry, the faces across this axis are not candidates (holding
        one would break the symmetry, and the mirror already stops motion along it)

    Returns
    -------
    (n,) bool, True for the nodes to hold that are not already fully fixed (all False when
    nothing needs holding), and the face's name ("" when none).
    """
    none = np.zeros(lattice.n_nodes, dtype=bool)
    rest = lattice.rest_nodes
    moved = fixed.any(axis=1) & np.any(np.abs(nodes - rest) > 1e-12 * lattice.size, axis=1)
    uvw = lattice.grid_parameters()
    edits = uvw[moved]
    if points is not None and len(points):
        edits = np.vstack([edits, lattice.to_parameters(points)])
    if not len(edits) or rigid_freedom(nodes, fixed, rows) == 0:
        return none, ""
    lengths = np.linalg.norm(lattice.axes, axis=1)
    best, face = -1.0, (0, 0)
    for axis in range(3):
        for side in (0, 1):
            if axis == mirror_axis:
                continue
            score = float(np.min(np.abs(edits[:, axis] - side))) * lengths[axis]
            if score > best + 1e-12 * lattice.size:
                best, face = score, (axis, side)
    if best <= 0:  # moved nodes on every face: they fix the lattice well enough
        return none, ""
    axis, side = face
    hold = (np.abs(uvw[:, axis] - side) < 1e-9) & ~fixed.all(axis=1)
    return hold, f"{AXES[axis]} {'max' if side else 'min'}"
