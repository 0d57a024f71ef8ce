"""The selection (Qt-free): the selected node rows and the selected handle, and the
lattice's layers, rows and faces through them.

Nodes are addressed ``(i, j, k)``; axis 0, 1, 2 is the lattice's first, second and third
index (x, y and z for the usual axis-aligned lattice). :class:`Selection` is a part of the
:class:`~isochor.app.editor.document.Document`: it owns what is selected, reads the
document's current state through a callable and tells the document's listeners of a change
through a callback.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .state import DocState

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


class Selection:
    """The selected node rows and the selected handle of one document.

    A node selection and a handle's exclude each other: selecting nodes deselects the
    handle, selecting a handle deselects the nodes. Every method that selects returns True
    when the selection changed and then calls ``changed`` (the document tells its listeners
    ``"selection"``); nothing changes, and nothing is told, otherwise.

    Parameters
    ----------
    state : returns the document's current state (the lattice and handles to select from)
    changed : called after every change
    """

    def __init__(self, state: Callable[[], DocState], changed: Callable[[], None]) -> None:
        self._state = state
        self._changed = changed
        self.rows = np.zeros(0, dtype=int)  #: (k,) int, the selected node rows, sorted
        self.handle: int | None = None  #: the selected handle, if any

    # -- nodes ---------------------------------------------------------------------------------
    def select(self, rows, mode: str = "replace") -> bool:
        """``replace`` the selection by the given rows, ``add`` them, or ``toggle`` them."""
        rows = np.unique(np.asarray(list(rows), dtype=int))
        n = self._state().lattice.n_nodes
        if len(rows) and (rows.min() < 0 or rows.max() >= n):
            raise IndexError(f"node rows must lie in [0, {n})")
        if mode == "add":
            rows = np.union1d(self.rows, rows)
        elif mode == "toggle":
            rows = np.setxor1d(self.rows, rows)
        elif mode != "replace":
            raise ValueError(f"unknown selection mode {mode!r}")
        if np.array_equal(rows, self.rows):
            return False
        self.rows = rows.astype(int)
        if len(rows):
            self.handle = None  # a node selection replaces a handle's
        self._changed()
        return True

    def add(self, rows) -> bool:
        """The given rows added to the selection."""
        return self.select(rows, "add")

    def toggle(self, rows) -> bool:
        """The given rows selected when they were not, deselected when they were."""
        return self.select(rows, "toggle")

    def all(self) -> bool:
        """Every node."""
        return self.select(range(self._state().lattice.n_nodes))

    def none(self) -> bool:
        """No node."""
        return self.select(())

    def inverse(self) -> bool:
        """Every node that is not selected (no node selected: all of them)."""
        return self.select(np.setdiff1d(np.arange(self._state().lattice.n_nodes), self.rows))

    # -- from the selected nodes (nothing changes without one) ---------------------------------
    def layer(self, axis: int) -> bool:
        """The lattice layers across ``axis`` through the selected nodes."""
        if len(self.rows) == 0:
            return False
        return self.select(layer(self._state().lattice, self.rows, axis))

    def row(self, axis: int) -> bool:
        """The lattice rows along ``axis`` through the selected nodes."""
        if len(self.rows) == 0:
            return False
        return self.select(line(self._state().lattice, self.rows, axis))

    def face(self, toward=None) -> str:
        """The lattice face that holds the whole selection (facing ``toward`` when there
        are several): its name, or ``""`` when no face holds it (nothing changes then)."""
        rows, name = face(self._state().lattice, self.rows, toward)
        if name:
            self.select(rows)
        return name

    # -- the handle ----------------------------------------------------------------------------
    def select_handle(self, index: int | None) -> bool:
        """Select handle ``index`` (None: no handle); a selected handle deselects the
        nodes."""
        if index is not None and not 0 <= index < len(self._state().handles):
            raise IndexError(f"no handle {index}")
        if index == self.handle:
            return False
        self.handle = index
        if index is not None and len(self.rows):
            self.rows = np.zeros(0, dtype=int)
        self._changed()
        return True

    # -- following the document ----------------------------------------------------------------
    def follow(self, st: DocState, new_scene: bool) -> None:
        """The document's current state became ``st`` (an edit, undo or redo): drop what it
        no longer has, all the nodes with a new lattice (``new_scene``). Silent: the
        document tells its listeners of the new state, and they redraw the selection with
        it."""
        if new_scene:
            self.rows = np.zeros(0, dtype=int)
        else:
            self.rows = self.rows[self.rows < st.lattice.n_nodes]
        if self.handle is not None and self.handle >= len(st.handles):
            self.handle = None
