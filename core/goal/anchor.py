"""No rigid drift, and the far side stays: which lattice nodes to hold besides the user's.

Springs with rest lengths cost nothing under a rigid motion, so with too few fixed nodes a
drag is cheapest as a translation and turn of the whole lattice: drag one corner of the
cow's lattice and the cow slides away instead of stretching. Worse, once the user's own
moves pin every rigid motion (the whole top layer grabbed down), the springs' cheapest
answer is still to carry everything along with the edit. An artist expects the part away
from the edit to stay put, and the push to squash the model against it.

The rule (``Goal.anchor == "far-side"``, the default): when some fixed node has been moved
from its rest place, or a handle placed, one lattice face is held where it is:

- where the edits push one way (a grab, a handle dragged), the face they push towards along
  the lattice axis nearest that direction: push the top down and the ground stays; unless
  that face is less than half as far from the edits as the face behind them (pulling the
  nose forward holds the tail);
- otherwise (a scale or a turn about the edit's middle) the face farthest from the edits.

Distances are measured at rest, from each face's plane to the nearest edit; a face with an
edit on it is never held. The face is held unless the user fixed a node on the far side
themselves (nearer the face than half the way to the nearest edit) and their fixed nodes
already stop every rigid motion: then they decide, as in the paper's examples, which fix
both ends and solve exactly as without the rule.
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
    targets: np.ndarray | None = None,
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
    targets : (h, 3) where the handles' points must land (each pushes by ``target - point``);
        None: the handles push nowhere in particular
    mirror_axis : under symmetry, the faces across this axis are not candidates (holding
        one would break the symmetry, and the mirror already stops motion along it)

    Returns
    -------
    (n,) bool, True for the nodes to hold that are not already fully fixed (all False when
    nothing needs holding), and the face's name ("" when none).
    """
    none = np.zeros(lattice.n_nodes, dtype=bool)
    fixed = np.asarray(fixed, dtype=bool)
    uvw, pushes = edits(lattice, nodes, fixed, points, targets)
    if not len(uvw):
        return none, ""
    face = far_face(lattice, uvw, pushes, mirror_axis)
    if face is None:  # edits on every face: they hold the lattice well enough
        return none, ""
    if user_holds(lattice, fixed, uvw, face) and rigid_freedom(nodes, fixed, rows) == 0:
        return none, ""
    axis, side = face
    hold = (np.abs(lattice.grid_parameters()[:, axis] - side) < 1e-9) & ~fixed.all(axis=1)
    if not hold.any():
        return none, ""
    return hold, f"{AXES[axis]} {'max' if side else 'min'}"


#: a push has a direction when the mean of the edits' pushes is at least this fraction of
#: their mean length (a grab: 1; a scale or turn about the edit's middle: about 0)
COHERENT = 0.5
#: ... and it runs along the lattice axis whose direction is within 60 degrees of it
ALONG = 0.5


def edits(
    lattice: Lattice,
    nodes: np.ndarray,
    fixed: np.ndarray,
    points: np.ndarray | None = None,
    targets: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Where the user edited, in lattice coordinates, and how far each edit pushes.

    The edits are the fixed nodes moved from their rest places (pushed by the move) and the
    handles' rest points (pushed from there to their targets; by nothing without targets).
    Returns ``(uvw, pushes)``, (e, 3) each."""
    rest = lattice.rest_nodes
    moved = fixed.any(axis=1) & np.any(np.abs(nodes - rest) > 1e-12 * lattice.size, axis=1)
    uvw = [lattice.grid_parameters()[moved]]
    pushes = [(nodes - rest)[moved]]
    if points is not None and len(points):
        points = np.reshape(points, (-1, 3))
        uvw.append(lattice.to_parameters(points))
        pushes.append(
            np.zeros_like(points) if targets is None else np.reshape(targets, (-1, 3)) - points
        )
    return np.vstack(uvw), np.vstack(pushes)


def push_axis(lattice: Lattice, pushes: np.ndarray) -> tuple[int, int] | None:
    """The lattice axis a coherent push runs along and the side it pushes towards (0: the
    low face, 1: the high one), or None when the edits push nowhere in particular."""
    if not len(pushes):
        return None
    mean = pushes.mean(axis=0)
    spread = float(np.linalg.norm(pushes, axis=1).mean())
    if spread <= 0 or np.linalg.norm(mean) < COHERENT * spread:
        return None
    dirs = lattice.axes / np.linalg.norm(lattice.axes, axis=1)[:, None]
    align = dirs @ (mean / np.linalg.norm(mean))
    axis = int(np.argmax(np.abs(align)))
    if abs(align[axis]) < ALONG:
        return None
    return axis, int(align[axis] > 0)


def far_face(
    lattice: Lattice,
    uvw: np.ndarray,
    pushes: np.ndarray,
    mirror_axis: int | None = None,
) -> tuple[int, int] | None:
    """The face to hold, ``(axis, side)``, for edits at ``uvw`` pushing by ``pushes``, or
    None when every face has an edit on it.

    Where the push has a direction (a grab, a handle dragged), the face it pushes towards
    along its axis is held, unless that face is less than half as far from the edits as
    the face behind them (pulling the nose forward holds the tail, not the air in front of
    the nose). Otherwise (a scale, a turn, edits pushing every way) the face farthest from
    the edits is held (ties go to the first axis, the low face first). Distances are
    measured at rest, from each face's plane to the nearest edit."""
    lengths = np.linalg.norm(lattice.axes, axis=1)
    tiny = 1e-9 * lattice.size

    def distance(axis: int, side: int) -> float:
        if axis == mirror_axis:
            return 0.0
        return float(np.min(np.abs(uvw[:, axis] - side))) * lengths[axis]

    along = push_axis(lattice, pushes)
    if along is not None:
        axis, towards = along
        ahead, behind = distance(axis, towards), distance(axis, 1 - towards)
        if ahead > tiny and 2 * ahead >= behind:
            return axis, towards
        if behind > tiny:
            return axis, 1 - towards
    best, face = tiny, None
    for axis in range(3):
        for side in (0, 1):
            d = distance(axis, side)
            if d > best * (1 + 1e-12):
                best, face = d, (axis, side)
    return face


def user_holds(lattice: Lattice, fixed: np.ndarray, uvw: np.ndarray, face: tuple[int, int]) -> bool:
    """True when the user fixed a node (on any axis) on the far side of ``face``: within
    less than half the way from the face to the nearest edit, along the face's axis."""
    axis, side = face
    reach = 0.5 * float(np.min(np.abs(uvw[:, axis] - side)))
    gap = np.abs(lattice.grid_parameters()[:, axis] - side)
    return bool(np.any(fixed.any(axis=1) & (gap < reach - 1e-9)))
