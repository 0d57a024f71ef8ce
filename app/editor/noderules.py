"""The edit rules of the lattice nodes themselves (Qt-free): type a position, pin and unpin,
reset every node to rest.

Every rule is a function of an :class:`~isochor.app.editor.edit.EditBase`
(``Document.base()``) and its own arguments and returns the
:class:`~isochor.app.editor.edit.Edit` to commit (a new state, unsolved, with the words of
its undo step), or None when nothing would change. With symmetry on, what a rule does to a
node it does mirrored to the node's partner. Pins on some axes only are the goal's
(:mod:`isochor.app.editor.goalrules`); a drag is the document's
(:class:`~isochor.app.editor.drag.DragSession`).
"""

from __future__ import annotations

import numpy as np

from .edit import Edit, EditBase
from .state import plural


def edit_position(base: EditBase, axis: int, value: float) -> Edit | None:
    """Type a coordinate: the selection (its centre, for several) goes to ``value``."""
    rows = base.rows
    if len(rows) == 0 or not np.isfinite(value):
        return None
    nodes = base.start()
    now = nodes[rows, axis].mean()
    if abs(value - now) <= 1e-12 * max(1.0, abs(value)):
        return None
    nodes[rows, axis] += value - now
    st = base.state
    new = st.moved_to(nodes, rows).mirrored(rows)
    m = st.mirror
    mirrored = ", mirrored" if m is not None and (m.partner[rows] != rows).any() else ""
    return Edit(new, f"Move {plural(len(rows))}{mirrored}")


def edit_pins(base: EditBase, rows, pin: bool) -> Edit | None:
    """Pin (or unpin) ``rows`` on every axis; None means every node."""
    st = base.state
    rows = np.arange(st.lattice.n_nodes) if rows is None else np.unique(np.asarray(rows, int))
    if len(rows) == 0:
        return None
    changes = (~st.pin_axes[rows].all(axis=1)).any() if pin else st.fixed[rows].any()
    if not changes:
        return None
    new = st.edited(nodes=base.start()).pinned_as(rows, pin).mirrored(rows)
    what = "all nodes" if len(rows) == st.lattice.n_nodes else plural(len(rows))
    return Edit(new, f"{'Pin' if pin else 'Unpin'} {what}")


def edit_toggle_pin(base: EditBase) -> Edit | None:
    """Pin the selection, or unpin it when all of it is fixed already."""
    rows = base.rows
    if len(rows) == 0:
        return None
    return edit_pins(base, rows, not bool(base.state.fixed[rows].all()))


def edit_reset(base: EditBase) -> Edit | None:
    """Every node back to rest, nothing pinned, no handle (at rest there is nothing to
    solve)."""
    st = base.state
    n = st.lattice.n_nodes
    rest = st.lattice.rest_nodes
    changed = st.pinned.any() or st.moved.any() or st.handles
    if not (changed or not np.array_equal(st.nodes, rest)):
        return None
    new = st.edited(
        nodes=rest,
        pin_axes=np.zeros((n, 3), bool),
        moved=np.zeros(n, bool),
        solved=st.goal.target_ratio == 1.0,
        handles=(),
    )
    return Edit(new, "Reset nodes")
