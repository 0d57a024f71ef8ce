"""The edit rule of the lattice itself (Qt-free): a new lattice of another shape around the
same model.

:func:`edit_lattice` is a function of an :class:`~isochor.app.editor.edit.EditBase`
(``Document.base()``) and the new shape, like every edit rule; the problems built before are
the base's :class:`~isochor.app.editor.problems.ProblemCache`, so returning to a lattice
reuses its problem with its caches.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...core.errors import IsochorError
from ...core.lattice import MAX_NODES, MIN_NODES, basis_names
from ...core.localbasis import BERNSTEIN, MAX_LOCAL, MIN_LOCAL
from ...core.scenario.problem import build
from .edit import Edit, EditBase
from .state import DocState, plural


def edit_lattice(base: EditBase, shape, basis=None, outside=None) -> Edit | None:
    """A new lattice of ``shape`` nodes around the same model, at rest; ``basis`` (one name
    or three, :data:`isochor.core.localbasis.NAMES`) changes its basis too (None keeps it),
    and ``outside`` Blender's Outside option (None keeps it, but for Bernstein, which has
    none; True with Bernstein is refused).

    Moves, pins and the timeline's keys are dropped (they name nodes of the old lattice);
    the model pyramid is reused, and so is a problem built before for the same shape, with
    its caches.
    """
    shape = tuple(int(s) for s in shape)
    st = base.state
    basis = st.lattice.basis if basis is None else basis_names(basis)
    local = basis[0] != BERNSTEIN
    low, high = (MIN_LOCAL, MAX_LOCAL) if local else (MIN_NODES, MAX_NODES)
    if len(shape) != 3 or not all(low <= s <= high for s in shape):
        which = "a local basis" if local else "the Bernstein basis"
        raise IsochorError(f"A lattice with {which} has {low} to {high} nodes per axis.")
    if outside is None:  # kept where the basis has it: a change to Bernstein drops it
        outside = st.lattice.outside and local
    elif outside and not local:
        raise IsochorError("The Outside option needs a local basis (B-spline, ...), not Bernstein.")
    outside = bool(outside)
    if (
        shape == tuple(st.lattice.shape)
        and basis == st.lattice.basis
        and outside == st.lattice.outside
    ):
        return None
    old = st.problem
    scenario = old.scenario.with_(
        lattice_nodes=shape,
        lattice_basis=basis,
        lattice_outside=outside,
        moves=(),
        pins=(),
        axis_pins=(),
        timeline=None,
    )
    if base.problems is None:
        problem = build(scenario, model=old.model)
    else:
        problem = base.problems.built(scenario, old.model)
    n = problem.surface.lattice.n_nodes
    # at rest: a cached problem may come from the opened scenario, whose moves and pins
    # name the nodes of the lattice the user has just left
    state = DocState(
        problem,
        problem.surface.lattice.rest_nodes,
        np.zeros(n, bool),
        np.zeros(n, bool),
        goal=st.goal,
        solved=st.goal.target_ratio == 1.0 and not st.handles,
        handles=st.handles,
        timeline=replace(st.timeline, keys=()),
    )
    keys = len(st.timeline.keys)
    dropped = f", {plural(keys, 'key')} dropped" if keys else ""
    named = "" if not local else f" ({'/'.join(dict.fromkeys(basis))})"
    named += ", outside" if outside else ""
    return Edit(state, "Rebuild lattice {}x{}x{}".format(*shape) + named + dropped)
