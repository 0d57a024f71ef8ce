"""The timeline's edit rules (Qt-free): set and remove a key, go to a key, the frame range,
rate and interpolation. Every rule is a function of an
:class:`~isochor.app.editor.edit.EditBase` (``Document.base()``) and its own arguments and
returns the :class:`~isochor.app.editor.edit.Edit` to commit (a new state with the words of
its undo step), or None when nothing would change. What the rules mean for the artist is in
:mod:`isochor.app.editor.timeline`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .edit import Edit, EditBase
from .state import DocState, SolveSummary
from .timeline import pose_flags, pose_of, same_pose

#: the undo words of a timeline setting
SETTING_WORDS = {"rate": "Frame rate", "interpolation": "Interpolation"}


def edit_set_key(base: EditBase, frame: int) -> Edit | None:
    """Key the working edit (moves, pins, axis pins, handles, target) at ``frame``,
    replacing a key there; None when that key holds this edit already. The working edit and
    its solve stay as they are."""
    st = base.state
    tl = st.timeline
    pose = pose_of(st, frame)
    old = tl.key_at(pose.frame)
    if old is not None and same_pose(old, pose, st.lattice):
        return None
    words = f"{'Replace' if old is not None else 'Set'} key at frame {pose.frame}"
    return Edit(replace(st, timeline=tl.with_key(pose)), words)


def edit_remove_key(base: EditBase, frame: int) -> Edit | None:
    """Remove the key at ``frame`` (None: there is none). The working edit stays."""
    st = base.state
    if st.timeline.key_at(frame) is None:
        return None
    new = replace(st, timeline=st.timeline.without_key(frame))
    return Edit(new, f"Remove key at frame {frame}")


def edit_go_to_key(base: EditBase, frame: int, solved=None) -> Edit | None:
    """Load the key at ``frame`` as the working edit (None: no key there, or the working
    edit is that key's already). ``solved``: the key's own solve
    (:class:`~isochor.core.solve.records.SolveResult`) when it is known; the state is then
    solved with it, else it starts from the nodes on screen, its fixed nodes where the key
    puts them."""
    st = base.state
    pose = st.timeline.key_at(frame)
    if pose is None or same_pose(pose_of(st, frame), pose, st.lattice):
        return None
    return Edit(posed_state(st, pose, base.start(), solved), f"Go to key {frame}")


def edit_frame_range(base: EditBase, start: int, end: int) -> Edit | None:
    """The frames to solve and play, ``start`` to ``end`` (both included)."""
    st = base.state
    tl = st.timeline
    new = tl.changed(start=int(start), end=int(end))
    if new == tl:
        return None
    return Edit(replace(st, timeline=new), f"Frame range {new.start}–{new.end}")


def edit_timeline_setting(base: EditBase, name: str, value) -> Edit | None:
    """``rate`` (frames a second) or ``interpolation`` (``linear``, ``smooth``)."""
    if name not in SETTING_WORDS:
        raise ValueError(f"unknown timeline setting {name!r}")
    st = base.state
    tl = st.timeline
    new = tl.changed(**{name: value})
    if new == tl:
        return None
    shown = f"{new.rate:g} fps" if name == "rate" else new.interpolation
    return Edit(replace(st, timeline=new), f"{SETTING_WORDS[name]} {shown}")


def posed_state(st: DocState, pose, base: np.ndarray, solved=None) -> DocState:
    """``st`` with key ``pose``'s edit as its working edit (its timeline and goal kept)."""
    lattice = st.lattice
    nodes, pins, moved = pose_flags(pose, lattice)
    ratio = st.goal.target_ratio if pose.target_ratio is None else pose.target_ratio
    changes = {
        "pin_axes": pins,
        "moved": moved,
        "goal": replace(st.goal, target_ratio=ratio),
        "handles": pose.edit.handles,
    }
    if solved is not None:
        summary = SolveSummary.of(solved, len(st.surface.levels))
        return replace(st, nodes=np.array(solved.nodes), solved=True, result=summary, **changes)
    _, fixed = pose.edit.apply(lattice)
    start = np.where(fixed, nodes, base)
    if not moved.any() and not pose.edit.handles and ratio == 1.0:
        # nothing moved, no handle, the volume kept: the rest lattice is the answer
        return replace(st, nodes=lattice.rest_nodes, solved=True, result=None, **changes)
    return st.edited(nodes=start, **changes)
