"""Surface handles in the editor (Qt-free): place, move and remove them, and the drag of a
handle's target.

A handle (:class:`isochor.core.goal.handles.Handle`) is a point of the model at rest (``at``)
and the place it must land (``to``); the solve moves the lattice so that the deformed point
follows. A click on the model gives a triangle of the full mesh as drawn (deformed) and the
barycentric weights of the hit point; the same weights on the same triangle of the rest
mesh give ``at`` (:func:`rest_point`). With symmetry on, the solve adds each handle's
mirror image; the document keeps the user's handles only.

The edit rules are functions of an :class:`~isochor.app.editor.edit.EditBase`
(``Document.base()``) and return the :class:`~isochor.app.editor.edit.Edit` to commit, or
None; selecting a handle is the selection's (:class:`~isochor.app.editor.selection.Selection`)
and starting a handle's drag the document's (``Document.begin_handle_drag``).
"""

from __future__ import annotations

import numpy as np

from ...core.goal.handles import Handle
from .edit import Edit, EditBase
from .state import DocState, StateCell


class HandleDrag:
    """A drag of one handle's target, with the drag session's interface
    (:class:`~isochor.app.editor.drag.DragSession`): no node is under the cursor, the handle's
    ``to`` is. ``index`` is the handle's place in ``handles`` (a new handle is the last)."""

    def __init__(self, before: StateCell, handles, index: int, base: np.ndarray, verb: str) -> None:
        self.before = before
        self.handles = tuple(handles)
        self.index = int(index)
        self.start = np.array(self.handles[self.index].to, dtype=np.float64)
        self.base = np.array(base, dtype=np.float64)
        self.nodes = self.base.copy()
        self.rows = np.zeros(0, dtype=int)
        self.selected = self.rows
        self.verb = verb

    @property
    def text(self) -> str:
        return self.verb

    @property
    def target(self) -> np.ndarray:
        """(3,) where the handle's point must land now."""
        return np.array(self.handles[self.index].to)

    def move(self, delta, free: np.ndarray | None = None) -> np.ndarray:
        """The handle's target at ``start + delta``; returns the nodes to show (the start,
        or the newest live preview ``free``)."""
        handles = list(self.handles)
        to = self.start + np.asarray(delta, dtype=np.float64)
        handles[self.index] = handles[self.index].moved_to(to)
        self.handles = tuple(handles)
        self.nodes = self.base.copy() if free is None else np.array(free, dtype=np.float64)
        return self.nodes

    def with_dragged(self, nodes: np.ndarray) -> np.ndarray:
        return np.array(nodes, dtype=np.float64)

    def fixed(self) -> np.ndarray:
        return self.before.state.fixed_axes.copy()

    def finish(self, free: np.ndarray | None = None) -> Edit:
        """The edit: the handles as dropped, the solve starting from the nodes on screen."""
        nodes = self.nodes if free is None else np.array(free, dtype=np.float64)
        return Edit(self.before.state.edited(nodes=nodes, handles=self.handles), self.text)


# -- where handles are ------------------------------------------------------------------------
def rest_point(st: DocState, face: int, weights) -> np.ndarray:
    """(3,) the model's rest point at barycentric ``weights`` of full-mesh triangle ``face``
    (the triangle and weights of a hit on the mesh as drawn)."""
    full = st.surface.full
    corners = np.asarray(full.vertices)[np.asarray(full.faces)[int(face)]]
    return np.asarray(weights, dtype=np.float64) @ corners


def handle_points(st: DocState, nodes: np.ndarray, handles=None) -> np.ndarray:
    """(h, 3) where each handle's point is with ``nodes`` (default handles: ``st``'s)."""
    handles = st.handles if handles is None else handles
    if not handles:
        return np.zeros((0, 3))
    at = np.array([h.at for h in handles], dtype=np.float64)
    return np.array(st.lattice.deform(at, nodes))


def mirror_handles(st: DocState, handles=None) -> tuple[Handle, ...]:
    """The mirror images the solve adds with symmetry on (none with it off)."""
    handles = st.handles if handles is None else handles
    m = st.mirror
    return () if m is None else tuple(m.handle(h) for h in handles)


def new_handle(st: DocState, at, nodes: np.ndarray) -> Handle:
    """A handle on the model's rest point ``at``, to land where that point is with
    ``nodes`` (so nothing moves until it is dragged)."""
    at = np.asarray(at, dtype=np.float64).reshape(3)
    return Handle(at, handle_points(st, nodes, (Handle(at, at),))[0])


# -- edits -----------------------------------------------------------------------------------
def edit_add_handle(base: EditBase, at, to=None) -> Edit:
    """A new handle on the model's rest point ``at``, to land at ``to`` (default: where the
    point is on screen, so nothing moves until it is dragged)."""
    st = base.state
    if to is None:
        handle = new_handle(st, at, base.nodes)
    else:
        handle = Handle(np.asarray(at, dtype=np.float64).reshape(3), to)
    handles = (*st.handles, handle)
    return Edit(st.edited(nodes=base.start(), handles=handles), "Add handle")


def edit_move_handle(base: EditBase, index: int, to) -> Edit | None:
    """Handle ``index`` to land at ``to`` (None: it does already)."""
    st = base.state
    h = st.handles[index]
    to = tuple(float(v) for v in np.asarray(to, dtype=np.float64).reshape(3))
    if to == h.to:
        return None
    handles = list(st.handles)
    handles[index] = h.moved_to(to)
    return Edit(st.edited(nodes=base.start(), handles=tuple(handles)), "Move handle")


def edit_remove_handle(base: EditBase, index: int | None = None) -> Edit | None:
    """Remove handle ``index`` (default: the selected one)."""
    index = base.handle if index is None else index
    st = base.state
    if index is None or not 0 <= index < len(st.handles):
        return None
    handles = st.handles[:index] + st.handles[index + 1 :]
    # nothing moved, no handle and the volume kept: the rest lattice is the answer
    at_rest = not handles and not st.moved.any() and st.goal.target_ratio == 1.0
    new = st.edited(nodes=remaining_start(st), handles=handles, solved=at_rest)
    return Edit(new, "Remove handle")


def remaining_start(st: DocState) -> np.ndarray:
    """Where the solve after a removal starts: the fixed coordinates where they are, the free
    ones at rest. Started from the nodes on screen, the springs (which cost nothing under a
    rigid motion) would keep the turn and shift the removed handle had caused; from rest,
    the solve gives what the remaining edit gives (nothing left: the model at rest)."""
    nodes = np.array(st.nodes, dtype=np.float64)
    free = ~st.fixed_axes
    nodes[free] = st.lattice.rest_nodes[free]
    return nodes
