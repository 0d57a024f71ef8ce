"""Selection helpers on the lattice (Qt-free): a layer, a row or a face of the lattice from
the selected nodes, and the inverse of the selection.

Nodes are addressed ``(i, j, k)``; axis 0, 1, 2 is the lattice's first, second and third
index (x, y and z for the usual axis-aligned lattice). :class:`SelectionRules` is a part of
:class:`~isochor.app.editor.document.Document`: it uses the document's ``state``, ``selection``
and ``select``.
"""

from __future__ import annotations

import numpy as np

AXES = "xyz"


def ijk_table(lattice) -> np.ndarray:
    """(n, 3) int: the (i, j, k) of every node row."""
    return np.stack(np.unravel_index(np.arange(lattice.n_nodes), lattice.shape), axis=1)


def layer(lattice, rows, axis: int) -> np.ndarray:
    """The rows of the lattice layers across ``axis`` through the given rows: every node with
    the same index along ``axis`` (the same i for axis 0) as one of them."""
    ijk = ijk_table(lattice)
    rows = np.asarray(rows, dtype=int)
    return np.flatnonzero(np.isin(ijk[:, axis], ijk[rows, axis]))


def line(lattice, rows, axis: int) -> np.ndarray:
    """The rows of the lattice rows along ``axis`` through the given rows: every node with
    the same two other indices as one of them."""
    ijk = ijk_table(lattice)
    rows = np.asarray(rows, dtype=int)
    others = [a for a in range(3) if a != axis]
    keys = {tuple(k) for k in ijk[rows][:, others]}
    return np.flatnonzero([tuple(k) in keys for k in ijk[:, others]])


def faces_containing(lattice, rows) -> list[tuple[int, bool]]:
    """The boundary faces ``(axis, max side)`` of the lattice that hold every given row."""
    ijk = ijk_table(lattice)[np.asarray(rows, dtype=int)]
    if len(ijk) == 0:
        return []
    out = []
    for axis in range(3):
        for side, index in ((False, 0), (True, lattice.shape[axis] - 1)):
            if (ijk[:, axis] == index).all():
                out.append((axis, side))
    return out


def face_name(axis: int, side: bool) -> str:
    """``"x min"``, ``"z max"``: a lattice face, as the far-side anchor names them."""
    return f"{AXES[axis]} {'max' if side else 'min'}"


def face(lattice, rows, toward=None) -> tuple[np.ndarray, str]:
    """The rows of the lattice face that holds all the given rows, and its name.

    A node on an edge or a corner lies on two or three faces: the one facing ``toward``
    (a world direction, e.g. towards the viewer) is chosen, else the first. Nothing
    (an empty array and ``""``) when no face holds them all.
    """
    found = faces_containing(lattice, rows)
    if not found:
        return np.zeros(0, dtype=int), ""
    axis, side = found[0]
    if toward is not None and len(found) > 1:
        toward = np.asarray(toward, dtype=np.float64)
        normals = np.linalg.inv(lattice.axes).T  # rows: the normals of the faces across u, v, w

        def facing(f):
            n = normals[f[0]] / np.linalg.norm(normals[f[0]])
            return float(n @ toward) * (1.0 if f[1] else -1.0)

        axis, side = max(found, key=facing)
    ijk = ijk_table(lattice)
    index = lattice.shape[axis] - 1 if side else 0
    return np.flatnonzero(ijk[:, axis] == index), face_name(axis, side)


class SelectionRules:
    """Selections made from the selection, mixed into the document. Each returns True when
    the selection changed (nothing changes without a selected node)."""

    def select_layer(self, axis: int) -> bool:
        """The layers across ``axis`` through the selected nodes."""
        if len(self.selection) == 0:
            return False
        return self.select(layer(self.state.lattice, self.selection, axis))

    def select_line(self, axis: int) -> bool:
        """The lattice rows along ``axis`` through the selected nodes."""
        if len(self.selection) == 0:
            return False
        return self.select(line(self.state.lattice, self.selection, axis))

    def select_face(self, toward=None) -> str:
        """The lattice face that holds the whole selection (facing ``toward`` when there
        are several): its name, or ``""`` when no face holds it (nothing changes then)."""
        rows, name = face(self.state.lattice, self.selection, toward)
        if name:
            self.select(rows)
        return name

    def select_inverse(self) -> bool:
        """Every node that is not selected (no node selected: all of them)."""
        rows = np.setdiff1d(np.arange(self.state.lattice.n_nodes), self.selection)
        return self.select(rows)
