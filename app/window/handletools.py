"""The window's surface handles and symmetry: the view's handle gestures wired to the
session, the markers redrawn with every frame, the Inspector's Handles group, the symmetry
choice, and the handle report of a solve in the status line (the Handle tool's actions are
:class:`~isochor.app.window.actions.ActionSet`'). GUI thread only; the rules are the
document's (:mod:`isochor.app.editor.handlerules`, :mod:`isochor.app.editor.goalrules`).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtWidgets import QMenu

from ...core.errors import IsochorError
from ..editor import goalrules, handlerules
from ..editor.handlerules import HandleDrag
from ..editor.state import handles_note
from .panel import bind


class HandleTools:
    """The handles and the symmetry of one window (they hold no state of their own: the
    handles are the document's, the Handle tool's switch the view's)."""

    def __init__(self, win) -> None:
        self.win = win

    def connect_signals(self) -> None:
        win = self.win
        s, vp, box = win.session, win.viewport, win.panel.handles
        vp.handleSelected.connect(lambda i: win.doc.selection.select_handle(i))
        vp.handlePlaced.connect(self.place)
        vp.handleDragStarted.connect(self._drag_started)
        vp.handleMenuRequested.connect(lambda i, pos: win.exec_menu(self.handle_menu(i), pos))
        s.selectionChanged.connect(self.show)
        s.solveDone.connect(lambda *_: self.report())
        bind(win.action_set.handle_tool, box.tool_box)
        box.handleChosen.connect(lambda i: win.doc.selection.select_handle(i if i >= 0 else None))
        box.removeClicked.connect(self.remove_handle)
        win.panel.goal.symmetryChosen.connect(self.set_symmetry)

    def place(self, face: int, weights) -> None:
        """A click on the model: a handle on that point (one undo step), selected."""
        win = self.win
        doc = win.doc
        if win.commit_edit(handlerules.edit_add_handle(doc.base(), doc.rest_point(face, weights))):
            doc.selection.select_handle(len(doc.state.handles) - 1)
            win.statusBar().showMessage(
                "Handle placed: drag it to pull the model there (X/Y/Z lock an axis).", 5000
            )

    def _drag_started(self, index: int, face: int, weights) -> None:
        win = self.win
        win.frames.keep_camera()
        doc = win.doc
        at = None if index >= 0 else doc.rest_point(face, weights)
        if win.session.begin_handle_drag(index if index >= 0 else None, at=at):
            win.statusBar().clearMessage()
            win.viewport.scene.set_folds(None)
            win.viewport.show_info(win.session.drag_text())

    def remove_handle(self) -> None:
        win = self.win
        if win.doc.selection.handle is None:
            win.statusBar().showMessage("Select a handle first (click its orange marker).", 3000)
            return
        win.commit_edit(handlerules.edit_remove_handle(win.doc.base()))

    def handle_menu(self, index: int) -> QMenu:
        """The right-click menu of handle ``index``."""
        win = self.win
        win.doc.selection.select_handle(index)
        menu = QMenu(win)
        menu.addAction(
            "Remove handle",
            lambda: win.commit_edit(handlerules.edit_remove_handle(win.doc.base(), index)),
        )
        return menu

    def set_symmetry(self, value: str) -> None:
        """The symmetry choice: one undo step; the status line says what was mirrored."""
        win = self.win
        try:
            edit = goalrules.edit_symmetry(win.doc.base(), value)
        except IsochorError as exc:
            win.error("Cannot mirror this lattice", str(exc))
            self.show()
            return
        if win.commit_edit(edit):
            tail = "" if value == "none" else ": edits on one side are mirrored to the other."
            win.statusBar().showMessage(f"{edit.text}{tail}", 6000)

    # -- drawing --------------------------------------------------------------------------------
    def redraw(self, nodes: np.ndarray | None = None, render: bool = True) -> None:
        """The handle markers for the nodes on screen (during a handle drag, its targets);
        ``render=False`` leaves the render to the caller (a frame renders once, after this)."""
        win = self.win
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

    def show(self, render: bool = True) -> None:
        """The Handles group, the symmetry choice and the markers, for the current state;
        ``render=False`` leaves the render to the frame that follows."""
        win = self.win
        st = win.state
        r = st.result if st.solved else None
        results = r.handles if r is not None and len(r.handles) == len(st.handles) else None
        win.panel.handles.show_handles(st.handles, results, win.doc.selection.handle)
        win.panel.goal.show_symmetry(st.goal.symmetry)
        if win.viewport.scene.built:
            win.viewport.scene.set_mirror(st.mirror)
        win.action_set.remove_handle.setEnabled(win.doc.selection.handle is not None)
        self.redraw(render=render)

    def report(self) -> None:
        """After a solve with handles: what it says about them, in the status bar."""
        win = self.win
        st = win.state
        r = st.result
        if st.solved and r is not None and r.handles:
            win.statusBar().showMessage(handles_note(r).strip(), 10000)
