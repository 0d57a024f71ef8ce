"""The window's surface handles and symmetry: the Handle tool and its actions, the view's
handle gestures wired to the session, the markers redrawn with every frame, the Inspector's
Handles group, the symmetry choice, and the handle report of a solve in the status line.
GUI thread only; the rules are the document's (:mod:`isochor.app.editor.handlerules`,
:mod:`isochor.app.editor.goalrules`).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QMenu

from ...core.errors import IsochorError
from ..editor import goalrules, handlerules
from ..editor.handlerules import HandleDrag
from ..editor.state import handles_note
from .handlebox import TOOL_TIP
from .panel import bind


def build(win, action) -> None:
    """The Handle tool (H) and Remove Handle (Delete, Backspace) as ``win.act_*``."""
    vp = win.viewport
    win.act_handle_tool = action(
        "&Handle Tool",
        lambda on: setattr(vp, "handle_mode", bool(on)),
        QKeySequence("H"),
        checkable=True,
        tip=TOOL_TIP,
    )
    win.act_remove_handle = action(
        "&Remove Handle",
        lambda: remove_handle(win),
        [QKeySequence("Delete"), QKeySequence("Backspace")],
        tip="Remove the selected surface handle",
    )


def connect(win) -> None:
    s, vp, box = win.session, win.viewport, win.panel.handles
    vp.handleSelected.connect(lambda i: win.doc.selection.select_handle(i))
    vp.handlePlaced.connect(lambda face, w: place(win, face, w))
    vp.handleDragStarted.connect(lambda i, face, w: _drag_started(win, i, face, w))
    vp.handleMenuRequested.connect(lambda i, pos: win.exec_menu(handle_menu(win, i), pos))
    s.selectionChanged.connect(lambda: show(win))
    s.solveDone.connect(lambda *_: report(win))
    bind(win.act_handle_tool, box.tool_box)
    box.handleChosen.connect(lambda i: win.doc.selection.select_handle(i if i >= 0 else None))
    box.removeClicked.connect(lambda: remove_handle(win))
    win.panel.goal.symmetryChosen.connect(lambda value: set_symmetry(win, value))


def place(win, face: int, weights) -> None:
    """A click on the model: a handle on that point (one undo step), selected."""
    doc = win.doc
    if win.commit_edit(handlerules.edit_add_handle(doc.base(), doc.rest_point(face, weights))):
        doc.selection.select_handle(len(doc.state.handles) - 1)
        win.statusBar().showMessage(
            "Handle placed: drag it to pull the model there (X/Y/Z lock an axis).", 5000
        )


def _drag_started(win, index: int, face: int, weights) -> None:
    win._frame_after_solve = False
    doc = win.doc
    at = None if index >= 0 else doc.rest_point(face, weights)
    if win.session.begin_handle_drag(index if index >= 0 else None, at=at):
        win.statusBar().clearMessage()
        win.viewport.scene.set_folds(None)
        win.viewport.show_info(win.session.drag_text())


def remove_handle(win) -> None:
    if win.doc.selection.handle is None:
        win.statusBar().showMessage("Select a handle first (click its orange marker).", 3000)
        return
    win.commit_edit(handlerules.edit_remove_handle(win.doc.base()))


def handle_menu(win, index: int) -> QMenu:
    """The right-click menu of handle ``index``."""
    win.doc.selection.select_handle(index)
    menu = QMenu(win)
    menu.addAction(
        "Remove handle",
        lambda: win.commit_edit(handlerules.edit_remove_handle(win.doc.base(), index)),
    )
    return menu


def set_symmetry(win, value: str) -> None:
    """The symmetry choice: one undo step; the status line says what was mirrored."""
    try:
        edit = goalrules.edit_symmetry(win.doc.base(), value)
    except IsochorError as exc:
        win.error("Cannot mirror this lattice", str(exc))
        show(win)
        return
    if win.commit_edit(edit):
        tail = "" if value == "none" else ": edits on one side are mirrored to the other."
        win.statusBar().showMessage(f"{edit.text}{tail}", 6000)


# -- drawing ------------------------------------------------------------------------------------
def redraw(win, nodes: np.ndarray | None = None, render: bool = True) -> None:
    """The handle markers for the nodes on screen (during a handle drag, its targets);
    ``render=False`` leaves the render to the caller (a frame renders once, after this)."""
    doc, vp = win.doc, win.viewport
    drag = doc.drag
    handles = drag.handles if isinstance(drag, HandleDrag) else doc.state.handles
    nodes = vp.nodes if nodes is None else nodes
    if len(nodes) != doc.state.lattice.n_nodes:
        return
    mirrors = doc.mirror_handles(handles)
    every = (*handles, *mirrors)
    targets = np.array([h.to for h in every]).reshape(-1, 3)
    points = doc.handle_points(nodes, every) if every else np.zeros((0, 3))
    selected = drag.index if isinstance(drag, HandleDrag) else doc.selection.handle
    vp.handles.show(targets, points, len(handles), selected)
    if render:
        vp.update()


def show(win) -> None:
    """The Handles group, the symmetry choice and the markers, for the current state."""
    st = win.state
    r = st.result if st.solved else None
    results = r.handles if r is not None and len(r.handles) == len(st.handles) else None
    win.panel.handles.show_handles(st.handles, results, win.doc.selection.handle)
    win.panel.goal.show_symmetry(st.symmetry)
    if win.viewport.scene.built:
        win.viewport.scene.set_mirror(st.mirror)
    win.act_remove_handle.setEnabled(win.doc.selection.handle is not None)
    redraw(win)


def report(win) -> None:
    """After a solve with handles: what it says about them, in the status bar."""
    st = win.state
    r = st.result
    if st.solved and r is not None and r.handles:
        win.statusBar().showMessage(handles_note(r).strip(), 10000)
