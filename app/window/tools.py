"""The window's tools on the node selection: grab, rotate and scale (G, R, S) wired from the
view's gestures to the session, and the selection helpers (layer, row, face). Their actions
are :class:`~isochor.app.window.actions.ActionSet`'. GUI thread only; the rules are the
document's (:mod:`isochor.app.editor.selection`) and the gesture maths
:mod:`isochor.app.editor.transform`'s.
"""

from __future__ import annotations

SELECT_FIRST = "Select nodes first: G moves, R rotates, S scales the selection."

#: Help > Controls
CONTROLS_HTML = """
<b>Mouse</b><br>
Click a node: select it · Shift-click: add or remove it<br>
Shift-drag on empty space (or Box select mode): select the nodes in a box<br>
Drag a selected node, or an arrow of the gizmo: move the selection<br>
Ctrl+click the model (or the Handle tool, H): place a handle · drag a handle: pull the
model there · Delete: remove the selected handle<br>
Left-drag on empty space: rotate · middle: pan · wheel or right-drag: zoom<br>
Right click: pin menu (on a handle: remove it)<br><br>
<b>Grab, rotate, scale</b><br>
G / R / S with nodes selected, then move the mouse · X / Y / Z: lock to that axis ·
Shift+X / Y / Z: the plane across it · type a value (S Z 0.5) · Enter or click: confirm ·
Esc or right click: cancel<br><br>
<b>While dragging</b><br>
X / Y / Z: lock to that axis · Shift+X / Y / Z: lock to the plane across it<br>
the same key again unlocks · Esc: cancel<br><br>
<b>Timeline</b><br>
I: key the working pose at the current frame · Alt+I: remove the key there<br>
In the view or on the scrubber: Left / Right: a frame · Up / Down: the next / previous
key · Shift+Left / Right: the start / end · Space: play the solved frames<br>
On a key frame its edit is the working edit; between keys the solved frame is shown<br><br>
<b>Keys</b><br>
P: pin or unpin the selection (Edit menu: pin on one axis only) · F: frame the selection<br>
Edit > Select: a layer, row or face of the lattice · Ctrl+I: invert the selection<br>
Home, 1, 3, 7 (Ctrl: opposite): views · 5: orthographic<br>
B: box select · V: preserve volume · L: live solve · Ctrl+A: select all<br>
Ctrl+Z / Ctrl+Shift+Z: undo / redo
"""


class NodeTools:
    """The node tools of one window (they hold no state of their own: the gesture is the
    view's, the drag the session's)."""

    def __init__(self, win) -> None:
        self.win = win

    def connect_signals(self) -> None:
        """The view's grab, rotate and scale gestures to the session (the gizmo's arrows are
        drags, wired like node drags)."""
        win = self.win
        s, vp = win.session, win.viewport
        vp.transformStarted.connect(self._transform_started)
        vp.transformMoved.connect(s.drag_transform)
        vp.hintChanged.connect(self.show_hint)

    def _transform_started(self, verb: str) -> None:
        win = self.win
        win.frames.keep_camera()
        if win.doc.drag is not None:  # the mode of a running gesture changed (G, R, S again)
            win.doc.drag.rename(verb)
            return
        if win.session.begin_drag(verb):
            win.viewport.scene.set_folds(None)  # they belong to the nodes before the gesture

    def show_hint(self, text: str) -> None:
        """What a running gesture does: on the view and in the status bar ("" clears both)."""
        win = self.win
        win.viewport.show_info(text)
        if text:
            win.statusBar().showMessage(text)
        else:
            win.statusBar().clearMessage()

    def start_transform(self, mode: str) -> bool:
        """G, R or S: start the gesture at the mouse, or say why not."""
        win = self.win
        if len(win.doc.selection.rows) == 0:
            win.statusBar().showMessage(SELECT_FIRST, 4000)
            return False
        if not win.viewport.start_transform(mode):
            win.statusBar().showMessage("Show the lattice to transform its nodes.", 4000)
            return False
        return True

    def _selected_or_say(self) -> bool:
        win = self.win
        if len(win.doc.selection.rows) == 0:
            win.statusBar().showMessage("Select a node first.", 3000)
            return False
        return True

    def select_layer(self, axis: int) -> None:
        win = self.win
        if self._selected_or_say():
            win.doc.selection.layer(axis)

    def select_line(self, axis: int) -> None:
        win = self.win
        if self._selected_or_say():
            win.doc.selection.row(axis)

    def select_face(self) -> None:
        """The lattice face holding the selection (the one facing the camera, for an edge or
        a corner node)."""
        win = self.win
        if not self._selected_or_say():
            return
        vp = win.viewport
        centre = vp.nodes[win.doc.selection.rows].mean(axis=0)
        name = win.doc.selection.face(toward=vp.camera_control.view_vector(centre))
        if name:
            win.statusBar().showMessage(f"Selected the {name} face of the lattice.", 3000)
        else:
            win.statusBar().showMessage("The selection is not on one face of the lattice.", 4000)
