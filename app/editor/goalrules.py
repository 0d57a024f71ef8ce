"""The edit rules of what a solve holds besides the moved nodes (Qt-free).

The goal's settings (hold the far side, keep the centre of mass, preserve each body, the
fold guard, the symmetry, the target volume), pins on some axes only, and what the far-side
anchor holds for the state on screen. Every rule is a function of an
:class:`~isochor.app.editor.edit.EditBase` (``Document.base()``) and its own arguments and
returns the :class:`~isochor.app.editor.edit.Edit` to commit (a new state, unsolved, with the
words of its undo step), or None when nothing would change.
"""

from __future__ import annotations

import contextlib
from dataclasses import replace

import numpy as np

from ...core.errors import IsochorError
from ...core.goal.anchor import held_face
from ...core.goal.handles import handle_rows
from ...core.goal.spec import PRESERVE, SYMMETRIES, check_ratio
from .edit import Edit, EditBase
from .selection import face_name, ijk_table
from .state import AXES, DocState, axes_words, plural

__all__ = [
    "SETTING_WORDS",
    "Edit",
    "edit_anchor",
    "edit_fold_guard",
    "edit_keep_centroid",
    "edit_pin_axes",
    "edit_pin_axis",
    "edit_preserve",
    "edit_setting",
    "edit_symmetry",
    "edit_target",
    "held",
]

#: the words of each setting's undo step: setting -> {value: words}
SETTING_WORDS: dict[str, dict[object, str]] = {
    "anchor": {"far-side": "Hold far side on", "none": "Hold far side off"},
    "keep_centroid": {True: "Keep centre of mass", False: "Keep centre of mass off"},
    "preserve": {"per-body": "Preserve each body", "total": "Preserve total volume"},
    "fold_guard": {True: "Fold guard on", False: "Fold guard off"},
}


# -- the goal's settings ---------------------------------------------------------------------
def edit_setting(base: EditBase, name: str, value) -> Edit | None:
    """Set one of the goal's settings (``anchor``, ``keep_centroid``, ``preserve``,
    ``fold_guard``); the nodes on screen are the start of the solve that follows."""
    words = SETTING_WORDS.get(name)
    if words is None:
        raise ValueError(f"unknown goal setting {name!r}")
    if value not in words:
        raise IsochorError(f"{name}: must be one of {', '.join(map(repr, words))}")
    st = base.state
    if getattr(st.goal, name) == value:
        return None
    goal = replace(st.goal, **{name: value})
    return Edit(st.edited(nodes=base.start(), goal=goal), words[value])


def edit_anchor(base: EditBase, on: bool) -> Edit | None:
    """Hold the far side (the lattice face away from the edit) while nothing else holds
    the lattice in place, or let it move."""
    return edit_setting(base, "anchor", "far-side" if on else "none")


def edit_keep_centroid(base: EditBase, on: bool) -> Edit | None:
    """Keep the model's centre of mass where it was, or let it move."""
    return edit_setting(base, "keep_centroid", bool(on))


def edit_preserve(base: EditBase, mode: str) -> Edit | None:
    """``"total"``: one volume; ``"per-body"``: each body keeps its own."""
    if mode not in PRESERVE:
        raise IsochorError(f"preserve: must be one of {', '.join(PRESERVE)}")
    return edit_setting(base, "preserve", mode)


def edit_fold_guard(base: EditBase, on: bool) -> Edit | None:
    """Keep the model from turning inside out, or let the solve fold it."""
    return edit_setting(base, "fold_guard", bool(on))


def edit_target(base: EditBase, percent: float) -> Edit | None:
    """A new target volume, ``percent`` of the original (None: not a positive number or
    no change). Raises :class:`IsochorError` beyond what a lattice can reach."""
    ratio = float(percent) / 100.0
    st = base.state
    if not (np.isfinite(ratio) and ratio > 0) or ratio == st.goal.target_ratio:
        return None
    check_ratio(ratio, "target volume ratio")
    goal = replace(st.goal, target_ratio=ratio)
    return Edit(st.edited(nodes=base.start(), goal=goal), f"Target volume {percent:g} %")


# -- symmetry --------------------------------------------------------------------------------
def edit_symmetry(base: EditBase, symmetry: str) -> Edit | None:
    """Mirror every edit across the lattice's mid-plane normal to ``symmetry`` ("x", "y" or
    "z"), or stop ("none").

    Turning it on makes the edit symmetric at once, as an artist mirroring a model expects:
    one side's places, pins and moves are copied onto the other side (the side of the
    selection; without one the side with more fixed nodes, else the low side), and the
    undo step says which. Raises :class:`IsochorError` for a lattice frame that is not
    aligned with x, y and z."""
    if symmetry not in SYMMETRIES:
        raise IsochorError(f"symmetry: must be one of {', '.join(SYMMETRIES)}")
    st = base.state
    if symmetry == st.goal.symmetry:
        return None
    new = st.edited(nodes=base.start(), goal=replace(st.goal, symmetry=symmetry))
    m = new.mirror
    if m is None:
        return Edit(new, "Symmetry off")
    rows, side = _symmetry_side(new, m, base.rows)
    mirrored = new.mirrored(rows)
    words = f"Symmetry across {symmetry}"
    if not mirrored.same_edit(new):
        words += f", the {side} side mirrored"
    return Edit(mirrored, words)


def _symmetry_side(st: DocState, m, selection: np.ndarray) -> tuple[np.ndarray, str]:
    """The half of the lattice to mirror onto the other, and its face's name."""
    index = ijk_table(st.lattice)[:, m.axis]
    middle = (st.lattice.shape[m.axis] - 1) / 2
    halves = (np.flatnonzero(index < middle), np.flatnonzero(index > middle))
    votes = [int(np.isin(selection, h).sum()) for h in halves]
    if votes[0] == votes[1]:
        votes = [int(st.fixed[h].sum()) for h in halves]
    high = votes[1] > votes[0]
    return halves[int(high)], face_name(m.axis, high).replace(" ", "-")


# -- pins on some axes -----------------------------------------------------------------------
def edit_pin_axes(base: EditBase, rows, axes: str) -> Edit | None:
    """Pin ``rows`` on exactly ``axes`` (some of ``"xyz"``; ``""`` unpins them): a node
    pinned on z keeps its z, the solver moves it in x and y. A moved node pinned on fewer
    than three axes is free on the others."""
    if set(axes) - set(AXES):
        raise ValueError(f"axes must be some of 'xyz', got {axes!r}")
    rows = np.unique(np.asarray(rows, dtype=int))
    mask = np.array([a in axes for a in AXES])
    st = base.state
    if len(rows) == 0 or np.all(st.fixed_axes[rows] == mask):
        return None
    new = st.edited(nodes=base.start()).pinned_on(rows, mask).mirrored(rows)
    if not mask.any():
        return Edit(new, f"Unpin {plural(len(rows))}")
    if mask.all():
        return Edit(new, f"Pin {plural(len(rows))}")
    return Edit(new, f"Pin {plural(len(rows))} on {axes_words(mask)}")


def edit_pin_axis(base: EditBase, rows, axis: int, on: bool) -> Edit | None:
    """Pin (or free) one axis of ``rows``, keeping their other axes as they are."""
    rows = np.unique(np.asarray(rows, dtype=int))
    st = base.state
    current = st.fixed_axes[rows, axis]
    if len(rows) == 0 or (current.all() if on else not current.any()):
        return None
    mask = st.fixed_axes[rows].copy()
    mask[:, axis] = on
    new = st.edited(nodes=base.start()).pinned_on(rows, mask).mirrored(rows)
    verb = "Pin" if on else "Free"
    return Edit(new, f"{verb} {plural(len(rows))} on {AXES[axis]}")


# -- what the far-side anchor holds ----------------------------------------------------------
def held(st: DocState, *, preserve: bool, drag=None) -> tuple[np.ndarray, str]:
    """The nodes the far-side anchor holds for what is on screen, and the face's name.

    ``st`` is the current state, ``preserve`` the document's "preserve volume" switch and
    ``drag`` its running drag, if any. During a drag: what a solve of the drag would hold;
    for a solved state: what its solve held; for a state not solved yet: what its solve
    will hold. Nothing with the volume constraint off (nothing is solved) or the anchor
    off."""
    n = st.lattice.n_nodes
    none = np.zeros(n, dtype=bool), ""
    if not preserve or st.goal.anchor != "far-side":
        return none
    if drag is not None:
        return _held(st, drag.nodes, drag.fixed(), drag.handles)
    r = st.result
    if st.solved and r is not None and r.levels:
        mask = np.zeros(n, dtype=bool)
        mask[list(r.held)] = True
        return mask, r.held_face
    return _held(st, st.nodes, st.fixed_axes, st.handles)


def _held(st: DocState, nodes, fixed, handles) -> tuple[np.ndarray, str]:
    """What the solve of ``nodes`` with ``fixed`` and ``handles`` will hold, as
    :func:`isochor.core.solve.multilevel.solve` decides it (the edit made symmetric, the handles
    with their mirror images)."""
    lattice, mirror = st.lattice, st.mirror
    handles = tuple(handles)
    fixed = np.asarray(fixed, dtype=bool)
    if mirror is not None:
        # moves that are no mirror images: the solve will say why; show the edit as it is
        with contextlib.suppress(IsochorError):
            nodes, fixed = mirror.symmetric(nodes, fixed)
        handles += tuple(mirror.handle(h) for h in handles)
    return held_face(
        lattice,
        nodes,
        fixed,
        rows=handle_rows(lattice, handles)[0] if handles else None,
        points=np.array([h.at for h in handles]).reshape(-1, 3),
        targets=np.array([h.to for h in handles]).reshape(-1, 3),
        mirror_axis=None if mirror is None else mirror.axis,
    )
