"""The mesh and its lattice as Isochor sees them, free of bpy: arrays in the lattice
object's local space, Blender's point order turned into Isochor's, and the Isochor session
that solves them.

Blender's lattice modifier evaluates a vertex in the lattice object's local space
(``lattice.matrix_world^-1 @ mesh.matrix_world``): ``x(p) = p + sum_i w_i(p) (P_i - R_i)``
with ``P_i`` the points' ``co_deform`` and ``R_i`` their rest grid (``co``: from
``points[0].co`` to ``points[-1].co``), the weights per axis by its interpolation type.
Isochor's local bases evaluate exactly that (INTERFACES.md), with the frame
``origin = points[0].co`` and ``axes = diag(points[-1].co - points[0].co)``.

Blender numbers the points u fastest (``points[(w * pv + v) * pu + u]``); Isochor numbers its
nodes i slowest (``(i * m + j) * n + k``), i along u.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Blender's interpolation types and Isochor's basis names for them
BASES = {
    "KEY_BSPLINE": "bspline",
    "KEY_CATMULL_ROM": "catmull-rom",
    "KEY_CARDINAL": "cardinal",
    "KEY_LINEAR": "linear",
}


def isochor_order(points: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    """``(pu * pv * pw, ...)`` values in Blender's point order -> Isochor's node order."""
    pu, pv, pw = shape
    values = np.asarray(points)
    grid = values.reshape((pw, pv, pu) + values.shape[1:])
    return np.ascontiguousarray(np.swapaxes(grid, 0, 2)).reshape(values.shape)


def blender_order(nodes: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    """Isochor's node order -> Blender's point order (the inverse of :func:`isochor_order`)."""
    pu, pv, pw = shape
    values = np.asarray(nodes)
    grid = values.reshape((pu, pv, pw) + values.shape[1:])
    return np.ascontiguousarray(np.swapaxes(grid, 0, 2)).reshape(values.shape)


@dataclass
class Rig:
    """A mesh under a lattice, in the lattice object's local space, Isochor's node order.

    ``vertices`` (v, 3) and ``faces`` (f, 3) the meshes as they enter the modifier (one
    after the other, ``counts`` vertices each); ``shape``
    (points u, v, w); ``basis`` the three Isochor basis names; ``origin`` (3,) and ``axes``
    (3, 3) the rest grid's box; ``nodes`` (n, 3) the points' co_deform; ``pinned`` (n,)
    the points the solve keeps where they are; ``preserve`` Isochor's ``"total"`` (the
    meshes' volumes summed) or ``"per-body"`` (each closed body its own)."""

    vertices: np.ndarray
    faces: np.ndarray
    shape: tuple[int, int, int]
    basis: tuple[str, str, str]
    origin: np.ndarray
    axes: np.ndarray
    nodes: np.ndarray
    pinned: np.ndarray
    outside: bool = False
    counts: tuple[int, ...] = ()
    preserve: str = "total"

    def session(self, target: float = 1.0, progress=None):
        """An Isochor session on this rig (the model volume at the rest grid is V0): the
        nodes where the points are, the pinned ones fixed; ``progress(stage, fraction)``
        as :class:`isochor.Session` calls it."""
        import isochor

        options = {"outside": True} if self.outside else {}
        session = isochor.Session(
            (self.vertices, self.faces),
            lattice=self.shape,
            basis=self.basis,
            frame=(self.origin, self.axes),
            target=target,
            preserve=self.preserve,
            progress=progress,
            **options,
        )
        self.load(session)
        return session

    def shown(self, session, nodes: np.ndarray) -> np.ndarray:
        """The points to write for solved ``nodes``: with Blender's "outside" option the
        inner ones on the faces' interpolation (as Blender keeps them), else the nodes."""
        return session.lattice.effective_nodes(nodes) if self.outside else nodes

    def written(self) -> np.ndarray:
        """(n,) Blender's order: the points a solve writes: the free ones, and with
        "outside" the inner ones too (they follow the faces)."""
        mask = ~self.pinned
        if self.outside:
            i, j, k = np.unravel_index(np.arange(len(mask)), self.shape)
            l, m, n = self.shape
            inner = (i > 0) & (i < l - 1) & (j > 0) & (j < m - 1) & (k > 0) & (k < n - 1)
            mask = mask | inner
        return blender_order(mask, self.shape)

    def load(self, session) -> None:
        """The session's nodes set to this rig's points, its fixed nodes to the pins."""
        np.copyto(session.nodes, self.nodes)
        session.fixed[:] = self.pinned[:, None]

    def lattice(self):
        """Isochor's FFD of this rig (the map Blender's modifier evaluates)."""
        from isochor.core.lattice import Lattice

        return Lattice(self.shape, self.origin, self.axes, self.basis, self.outside)

    def solid(self) -> Solid:
        """The :class:`Solid` whose volume a solve of this rig keeps."""
        from isochor.core.io.repair import clean_closed_surface

        clean, _, _ = clean_closed_surface(self.vertices, self.faces)
        own = clean.own_vertices
        return Solid(
            faces=clean.faces,
            rows=rows_at(clean.vertices[:own], self.vertices),
            caps=clean.vertices[own:],
            holes=clean.cap_vertices,
        )


@dataclass(frozen=True)
class Solid:
    """The closed solid Isochor keeps the volume of, capped once at rest by Isochor's own
    repair (:func:`isochor.core.io.repair.clean_closed_surface`): the mesh's triangles,
    each body turned to face outward, and a fan over each hole from a cap point that the
    lattice maps like any vertex.

    ``faces`` (f, 3) number the mesh's vertices ``rows`` first (a mesh vertex at the place
    of each of Isochor's welded vertices), then the cap points; ``caps`` (h, 3) the cap
    points at rest in the lattice object's space; ``holes`` how many were capped."""

    faces: np.ndarray
    rows: np.ndarray
    caps: np.ndarray
    holes: int

    def volume(self, vertices: np.ndarray, caps: np.ndarray) -> float:
        """The signed volume with the mesh's vertices at ``vertices`` (the mesh's order)
        and the cap points at ``caps`` (both in one space)."""
        p = np.concatenate([np.asarray(vertices, float)[self.rows], np.asarray(caps, float)])
        p = p - p.mean(axis=0)  # about the middle: the rounding of the tetrahedra is small
        a, b, c = (p[self.faces[:, i]] for i in range(3))
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def rows_at(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(p,) the row of ``vertices`` at each of ``points`` (exact copies of some rows: the
    repair welds by keeping one vertex of each group and copies the ones it splits)."""

    def key(a):
        return np.ascontiguousarray(a, dtype=np.float64).view(np.dtype((np.void, 24))).ravel()

    table = key(vertices)
    order = np.argsort(table)
    at = np.searchsorted(table[order], key(points))
    found = order[np.minimum(at, len(order) - 1)]
    if len(points) and not np.array_equal(key(vertices[found]), key(points)):
        raise ValueError("a repaired vertex is not one of the mesh's")
    return found
