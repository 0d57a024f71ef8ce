"""Symmetric editing: a mirror across one of the lattice's mid-planes.

With ``Goal.symmetry == "x"`` node ``(i, j, k)`` and its partner ``(l-1-i, j, k)`` are mirror
images across the plane ``x = c`` through the middle of the lattice box, before and after
the solve. An edit on one side is mirrored to the other (:meth:`Mirror.symmetric`), a node
on the plane stays on it, and the solve keeps the result symmetric *exactly*: the free
coordinates of one side are the solver's variables and their partners follow them
(:meth:`Mirror.ties`, used by :class:`isochor.core.solve.solver.Coordinates`), so a symmetric edit
gives a lattice symmetric to rounding, whatever the model is like. (Held as constraints,
the symmetry would be met only to the solver's tolerance.)

The mirror is a reflection of world coordinates, so the lattice frame must be axis-aligned
(every lattice Isochor fits is; a scenario's own frame may not be).
"""

from __future__ import annotations

import numpy as np

from ..errors import IsochorError
from ..lattice import Lattice
from .handles import Handle
from .spec import SYMMETRIES


class Mirror:
    """The reflection across the lattice's mid-plane normal to ``axis`` (0, 1, 2)."""

    def __init__(self, lattice: Lattice, axis: int) -> None:
        axes = lattice.axes
        if np.max(np.abs(axes - np.diag(np.diag(axes)))) > 1e-12 * lattice.size:
            raise IsochorError(
                f"symmetry {'xyz'[axis]}: the lattice frame is not aligned with the x, y "
                "and z axes, so its mid-plane is no mirror of the lattice"
            )
        self.lattice, self.axis = lattice, axis
        self.plane = float(lattice.origin[axis] + 0.5 * axes[axis, axis])
        ijk = np.indices(lattice.shape).reshape(3, -1).T
        ijk[:, axis] = lattice.shape[axis] - 1 - ijk[:, axis]
        l, m, n = lattice.shape
        self.partner = (ijk[:, 0] * m + ijk[:, 1]) * n + ijk[:, 2]
        self.on_plane = self.partner == np.arange(lattice.n_nodes)

    @classmethod
    def of(cls, lattice: Lattice, symmetry: str) -> Mirror | None:
        """The mirror of ``symmetry`` ("x", "y", "z"), or None for "none"."""
        if symmetry not in SYMMETRIES:
            raise IsochorError(f"symmetry: must be one of {', '.join(SYMMETRIES)}")
        return None if symmetry == "none" else cls(lattice, "xyz".index(symmetry))

    @property
    def name(self) -> str:
        return "xyz"[self.axis]

    def point(self, points) -> np.ndarray:
        """Points mirrored across the plane (any shape ending in 3)."""
        out = np.array(points, dtype=np.float64)
        out[..., self.axis] = 2 * self.plane - out[..., self.axis]
        return out

    def handle(self, h: Handle) -> Handle:
        return Handle(self.point(h.at), self.point(h.to))

    def asymmetry(self, nodes: np.ndarray) -> float:
        """Largest distance between a node and its partner's mirror image, / lattice size."""
        nodes = np.asarray(nodes, dtype=np.float64)
        return float(np.max(np.abs(nodes[self.partner] - self.point(nodes)))) / self.lattice.size

    def mirror_rows(self, nodes, fixed, rows) -> tuple[np.ndarray, np.ndarray]:
        """Copies of ``nodes`` (n, 3) and ``fixed`` (n, 3) bool with the positions and fixed
        coordinates of ``rows`` mirrored onto their partners; rows on the plane are put
        back on it."""
        nodes = np.array(nodes, dtype=np.float64)
        fixed = np.array(fixed, dtype=bool)
        rows = np.atleast_1d(np.asarray(rows, dtype=int))
        nodes[self.partner[rows]] = self.point(nodes[rows])
        fixed[self.partner[rows]] = fixed[rows]
        nodes[self.on_plane, self.axis] = self.plane
        return nodes, fixed

    def symmetric(self, nodes, fixed) -> tuple[np.ndarray, np.ndarray]:
        """The edit ``(nodes, fixed)`` made symmetric, for the solve.

        A coordinate fixed on one side only is fixed on the other at the mirrored place;
        where both are fixed, the one the user moved from its rest place wins; both moved
        to places that are not mirror images is an error. Nodes on the plane are put on
        it, and free nodes start at the mirror image of their partner on the low side.
        """
        nodes = np.array(nodes, dtype=np.float64)
        fixed = np.array(fixed, dtype=bool)
        rest = self.lattice.rest_nodes
        tol = 1e-9 * self.lattice.size
        moved = np.abs(nodes - rest) > tol
        low = np.flatnonzero(np.arange(len(nodes)) < self.partner)
        for r in low:
            p = self.partner[r]
            image = self.point(nodes[r])
            for a in range(3):
                if fixed[r, a] and fixed[p, a] and abs(nodes[p, a] - image[a]) > tol:
                    if moved[r, a] and moved[p, a]:
                        ijk = self.lattice.ijk
                        raise IsochorError(
                            f"symmetry {self.name}: nodes {list(ijk(r))} and {list(ijk(p))} "
                            "are mirror partners but were moved to places that are not "
                            "mirror images; move one of them, or turn symmetry off"
                        )
                    if moved[p, a]:
                        nodes[r, a] = self.point(nodes[p])[a]
                        continue
                if fixed[r, a] or not fixed[p, a]:
                    nodes[p, a] = image[a]
                else:
                    nodes[r, a] = self.point(nodes[p])[a]
            fixed[r] = fixed[p] = fixed[r] | fixed[p]
        nodes[self.on_plane, self.axis] = self.plane
        return nodes, fixed

    def ties(self, free: np.ndarray) -> tuple[np.ndarray, ...]:
        """How the high side follows the low side in a solve with these free coordinates.

        Returns ``(free, dst, src, sign, offset)``: the free mask of the solver's own
        variables (the low side's free coordinates and the in-plane ones of nodes on the
        plane), and flat indices with ``x.flat[dst] = sign * x.flat[src] + offset``.
        """
        free = np.array(free, dtype=bool)
        high = np.arange(len(free)) > self.partner
        tied = free & high[:, None]
        dst = np.flatnonzero(tied.ravel())
        rows, axes = np.divmod(dst, 3)
        src = 3 * self.partner[rows] + axes
        mirrored = axes == self.axis
        sign = np.where(mirrored, -1.0, 1.0)
        offset = np.where(mirrored, 2 * self.plane, 0.0)
        own = free & ~high[:, None]
        own[self.on_plane, self.axis] = False
        return own, dst, src, sign, offset
