"""The window's tools on the node selection: grab, rotate and scale (G, R, S), the selection
helpers (layer, row, face, inverse), framing the selection and the orthographic camera.
:func:`build` makes their actions (``win.act_*``) and :func:`connect` wires the view's
gestures to the session. GUI thread only; the rules are the document's
(:mod:`isochor.app.editor.selection`) and the gesture maths :mod:`isochor.app.editor.transform`'s.
"""

from __future__ import annotations

from PySide6.QtGui import QKeySequence

from ..editor.transform import VERBS

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


def connect(win) -> None:
    """The view's grab, rotate and scale gestures to the session (the gizmo's arrows are
    drags, wired like node drags)."""
    s, vp = win.session, win.viewport
    vp.transformStarted.connect(lambda verb: _transform_started(win, verb))
    vp.transformMoved.connect(s.drag_transform)
    vp.hintChanged.connect(lambda text: show_hint(win, text))


def _transform_started(win, verb: str) -> None:
    win._frame_after_solve = False
    if win.doc.drag is not None:  # the mode of a running gesture changed (G, R, S again)
        win.doc.drag.verb = verb
        return
    if win.session.begin_drag(verb):
        win.viewport.scene.set_folds(None)  # they belong to the nodes before the gesture


def show_hint(win, text: str) -> None:
    """What a running gesture does: on the view and in the status bar ("" clears both)."""
    win.viewport.show_info(text)
    if text:
        win.statusBar().showMessage(text)
    else:
        win.statusBar().clearMessage()


def start_transform(win, mode: str) -> bool:
    """G, R or S: start the gesture at the mouse, or say why not."""
    if len(win.doc.selection.rows) == 0:
        win.statusBar().showMessage(SELECT_FIRST, 4000)
        return False
    if not win.viewport.start_transform(mode):
        win.statusBar().showMessage("Show the lattice to transform its nodes.", 4000)
        return False
    return True


def _selected_or_say(win) -> bool:
    if len(win.doc.selection.rows) == 0:
        win.statusBar().showMessage("Select a node first.", 3000)
        return False
    return True


def select_layer(win, axis: int) -> None:
    if _selected_or_say(win):
        win.doc.selection.layer(axis)


def select_line(win, axis: int) -> None:
    if _selected_or_say(win):
        win.doc.selection.row(axis)


def select_face(win) -> None:
    """The lattice face holding the selection (the one facing the camera, for an edge or
    a corner node)."""
    if not _selected_or_say(win):
        return
    vp = win.viewport
    centre = vp.nodes[win.doc.selection.rows].mean(axis=0)
    name = win.doc.selection.face(toward=vp._view_vector(centre))
    if name:
        win.statusBar().showMessage(f"Selected the {name} face of the lattice.", 3000)
    else:
        win.statusBar().showMessage("The selection is not on one face of the lattice.", 4000)


def build(win, action) -> None:
    """Create the tools' actions as ``win.act_*`` with ``action(text, slot, shortcut, ...)``
    (:func:`isochor.app.window.actions._action`)."""
    K = QKeySequence  # noqa: N806
    vp = win.viewport
    win.act_transform = {
        mode: action(
            f"{VERBS[mode] if mode != 'grab' else 'Grab'}",
            lambda _=False, m=mode: start_transform(win, m),
            K(key),
            tip=f"{tip} the selected nodes about their centre with the mouse; X/Y/Z lock an "
            "axis, type a value, Enter confirms, Esc cancels",
        )
        for mode, key, tip in (
            ("grab", "G", "Move"),
            ("rotate", "R", "Rotate"),
            ("scale", "S", "Scale"),
        )
    }
    win.act_select_layer = [
        action(
            f"Layer Across {a.upper()}",
            lambda _=False, i=i: select_layer(win, i),
            tip=f"Select every node with the same {'ijk'[i]} as a selected node",
        )
        for i, a in enumerate("xyz")
    ]
    win.act_select_line = [
        action(
            f"Row Along {a.upper()}",
            lambda _=False, i=i: select_line(win, i),
            tip=f"Select the lattice rows along {a} through the selected nodes",
        )
        for i, a in enumerate("xyz")
    ]
    win.act_select_face = action(
        "Face of the Lattice",
        lambda: select_face(win),
        tip="Select the lattice face that holds the selected nodes",
    )
    win.act_invert = action("&Invert Selection", lambda: win.doc.selection.inverse(), K("Ctrl+I"))
    win.act_visible_only = action(
        "Select &Visible Only",
        lambda on: setattr(vp, "visible_only", bool(on)),
        checkable=True,
        tip="Box selection skips the nodes the model hides from the camera",
    )
    win.act_ortho = action(
        "&Orthographic",
        vp.set_orthographic,
        K("5"),
        checkable=True,
        tip="Parallel projection (on) or perspective (off)",
    )


def add_to_edit_menu(win, menu) -> None:
    """The Transform and Select submenus."""
    m = menu.addMenu("&Transform")
    for a in win.act_transform.values():
        m.addAction(a)
    m = menu.addMenu("Se&lect")
    for a in (*win.act_select_layer, None, *win.act_select_line, None, win.act_select_face):
        m.addSeparator() if a is None else m.addAction(a)
    m.addSeparator()
    m.addAction(win.act_invert)
    m.addAction(win.act_visible_only)
