"""A drag of the node selection, Qt-free: a mouse drag, a gizmo arrow, or a grab, rotate or
scale gesture (:mod:`isochor.app.editor.transform`). It is one edit however many frames it lasts:
where it started, where its rows are now, and the edit it makes when it ends.
"""

from __future__ import annotations

import numpy as np

from .edit import Edit
from .state import StateCell, lead_rows, plural
from .transform import apply


class DragSession:
    """A drag of the selected nodes: where it started and where the nodes are now.

    ``free`` are the solver's nodes for the nodes not dragged: the start (no live solve) or
    the newest live preview, given by the caller with every move. ``verb`` names the undo
    step ("Move", "Rotate", "Scale"). ``mirror`` (a :class:`isochor.core.goal.symmetry.Mirror`,
    or None) copies each dragged node's place, mirrored, onto its partner: the partners are
    dragged too.
    """

    def __init__(
        self, before: StateCell, rows: np.ndarray, base: np.ndarray, verb: str = "Move", mirror=None
    ) -> None:
        self.before = before
        self.selected = np.array(rows, dtype=int)
        self.mirror = mirror
        rows = self.selected
        if mirror is not None:
            rows = np.union1d(rows, np.asarray(mirror.partner)[rows])
        self.rows = np.asarray(rows, dtype=int)
        self.base = np.array(base, dtype=np.float64)
        self.nodes = self.base.copy()
        self.verb = verb
        self.handles = before.state.handles  #: the handles a live preview solves with

    def rename(self, verb: str) -> None:
        """The gesture changed its mode (G, R, S again): its undo step's verb."""
        self.verb = verb

    @property
    def text(self) -> str:
        """The undo step's words: ``"Scale 9 nodes"``, ``"Move 1 node, mirrored"``."""
        mirrored = ", mirrored" if len(self.rows) > len(self.selected) else ""
        return f"{self.verb} {plural(len(self.selected))}{mirrored}"

    def place(self, positions, free: np.ndarray | None = None) -> np.ndarray:
        """The nodes with the selected rows at ``positions`` ((k, 3), in the order of
        ``selected``), their partners mirrored; returns them."""
        nodes = self.base.copy() if free is None else np.array(free, dtype=np.float64)
        nodes[self.selected] = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        if self.mirror is not None:
            nodes = self._mirrored(nodes)
        self.nodes = nodes
        return nodes

    def move(self, delta, free: np.ndarray | None = None) -> np.ndarray:
        """The nodes with the selected ones at ``base + delta``; returns them."""
        delta = np.asarray(delta, dtype=np.float64)
        return self.place(self.base[self.selected] + delta, free)

    def transform(self, matrix, free: np.ndarray | None = None) -> np.ndarray:
        """The nodes with the selected ones mapped from ``base`` by the (4, 4) affine
        ``matrix`` (a grab, rotate or scale); returns them."""
        return self.place(apply(matrix, self.base[self.selected]), free)

    def _mirrored(self, nodes: np.ndarray) -> np.ndarray:
        """``nodes`` with the partners of the selected rows at their mirror images (a node
        selected with its partner keeps its own place; one on the plane stays on it)."""
        fixed = np.zeros(nodes.shape, bool)
        out, _ = self.mirror.mirror_rows(nodes, fixed, lead_rows(self.mirror, self.selected))
        return np.array(out, dtype=np.float64)

    def with_dragged(self, nodes: np.ndarray) -> np.ndarray:
        """``nodes`` (e.g. a live preview) with the dragged nodes where the cursor put them."""
        out = np.array(nodes, dtype=np.float64)
        out[self.rows] = self.nodes[self.rows]
        return out

    def fixed(self) -> np.ndarray:
        """(n, 3) bool: the coordinates a live preview solve holds (the old fixed ones and
        the dragged nodes)."""
        fixed = self.before.state.fixed_axes.copy()
        fixed[self.rows] = True
        return fixed

    def finish(self, free: np.ndarray | None = None) -> Edit | None:
        """The edit the drag made; ``free`` are the newest live nodes, if any. None when
        it moved no node (a scale by 1, a scale or turn of one node about itself): that
        is no edit, and fixes nothing."""
        moved = np.abs(self.nodes[self.rows] - self.base[self.rows])
        scale = max(1.0, float(np.abs(self.base).max()))
        if not moved.size or moved.max() <= 16 * np.finfo(float).eps * scale:  # roundings
            return None
        nodes = self.nodes if free is None else self.with_dragged(free)
        return Edit(self.before.state.moved_to(nodes, self.rows), self.text)
