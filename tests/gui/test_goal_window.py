"""What a solve holds, in the window: the far-side anchor and the held nodes, folds marked on
the model, the constraint switches as undoable edits, pins on one axis, each body's volume.

Driven with real mouse and key events; what is drawn is read back from the actors' own
arrays (the colours VTK renders) and from the rendered frame.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.gui.conftest import open_window, save_shot, wait_idle
from tests.gui.test_editor import click, drag, pickable_node, point, screen_positions


# -- helpers ------------------------------------------------------------------------------
def rgb(color: str) -> np.ndarray:
    from isochor.app.view.style import hex_to_rgb

    return np.array(hex_to_rgb(color), dtype=np.uint8)


def drawn(win, actor: str, name: str) -> np.ndarray:
    """A point array of what an actor's mapper draws."""
    import pyvista as pv

    mapper = win.viewport.scene.actors[actor].GetMapper()
    return np.array(pv.wrap(mapper.GetInput()).point_data[name])


def node_colours(win) -> np.ndarray:
    return drawn(win, "nodes", "rgb")


def pixels(win) -> np.ndarray:
    """(h, w, 3) uint8: the 3D view as rendered now."""
    from PySide6.QtGui import QImage

    img = win.viewport.grabFramebuffer().convertToFormat(QImage.Format.Format_RGB888)
    w, h, line = img.width(), img.height(), img.bytesPerLine()
    buf = np.frombuffer(img.constBits(), dtype=np.uint8, count=line * h)
    return buf.reshape(h, line)[:, : 3 * w].reshape(h, w, 3).copy()


def type_into(spin, text: str) -> None:
    """Click into a spin box, replace its number by ``text`` and press Enter."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    QTest.mouseClick(spin, Qt.MouseButton.LeftButton)
    QTest.keyClick(spin, Qt.Key.Key_A, Qt.KeyboardModifier.ControlModifier)
    QTest.keyClicks(spin, text)
    QTest.keyClick(spin, Qt.Key.Key_Return)


def click_box(win, box) -> None:
    """Click a check box on its indicator (the box spans the panel; its text does not)."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    win.inspector_scroll.ensureWidgetVisible(box)
    QTest.mouseClick(
        box, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, QPoint(8, box.height() // 2)
    )


def activate(qtbot, win) -> None:
    """The window's shortcuts (Ctrl+Z) work in the active window only."""
    win.activateWindow()
    qtbot.waitUntil(lambda: win.isActiveWindow(), timeout=2000)


def undo_key(win, redo: bool = False) -> None:
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    mods = Qt.KeyboardModifier.ControlModifier
    if redo:
        mods |= Qt.KeyboardModifier.ShiftModifier
    QTest.keyClick(win.viewport, Qt.Key.Key_Z, mods)


def sphere_window(qtbot):
    from isochor.app.editor.document import Document
    from isochor.core.scenario.document import Scenario
    from isochor.core.scenario.problem import build

    spec = {"model": {"builtin": "sphere", "n_levels": 4}, "lattice": {"nodes": [3, 3, 3]}}
    win = open_window(qtbot, Document(build(Scenario.from_dict(spec))))
    wait_idle(qtbot, win)
    activate(qtbot, win)
    return win


# -- (a) the far side holds ---------------------------------------------------------------
def test_a_one_node_drag_holds_the_far_face_until_hold_far_side_is_unticked(qtbot, themed_app):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from isochor.app.view import style

    win = sphere_window(qtbot)
    vp = win.viewport
    lat = win.state.lattice
    rest = lat.rest_nodes
    assert not win.state.fixed.any() and not win.readout.held_mask.any()
    assert not win.panel.goal.held_note.isVisible()
    row = pickable_node(win, want_free=True)

    # during the drag: what its solve will hold is drawn already
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    for i in range(1, 9):
        QTest.mouseMove(vp, point(start + np.array([70, -45]) * i / 8))
        qtbot.wait(5)
    qtbot.waitUntil(lambda: win.readout.held_face != "", timeout=3000)
    during = np.flatnonzero(win.readout.held_mask)
    assert len(during) == 9 and row not in during
    assert (node_colours(win)[during] == rgb(style.HELD)).all()
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (70, -45))
    )
    wait_idle(qtbot, win)

    st = win.state
    r = st.result
    assert st.converged and st.moved[row]
    held = np.array(r.held)
    assert len(held) == 9 and r.held_face and held.tolist() == during.tolist()
    axis, side = "xyz".index(r.held_face[0]), r.held_face.endswith("max")
    ijk = np.array([lat.ijk(i) for i in range(lat.n_nodes)])
    assert (ijk[held, axis] == (lat.shape[axis] - 1 if side else 0)).all(), "one lattice face"
    assert np.array_equal(st.nodes[held], rest[held]), "the held face did not move"
    others = np.setdiff1d(np.flatnonzero(~st.fixed), held)
    assert np.abs(st.nodes[others] - rest[others]).max() > 1e-3 * st.surface.size
    # drawn in the held style, and said in words
    colours = node_colours(win)
    assert (colours[held] == rgb(style.HELD)).all()
    assert not (colours[others] == rgb(style.HELD)).all(axis=1).any()
    note = win.panel.goal.held_note
    assert note.isVisible()
    assert f"Holding the {r.held_face} face (9 nodes) so the model does not drift" in note.text()
    assert "untick Hold far side" in note.text()
    # the rendered frame: the visible held nodes are green, the free ones blue
    image = pixels(win)
    xy, _, visible = vp.camera_control.projection().project(vp.nodes)
    green = [
        int(row_)
        for row_ in held
        if visible[row_]
        and (lambda p: p[1] > p[0] + 40 and p[1] > p[2])(
            image[int(round(xy[row_, 1])), int(round(xy[row_, 0]))].astype(int)
        )
    ]
    assert len(green) >= 3, f"held nodes drawn green on screen: {green}"
    save_shot(win, "goal_held_far_side", show=win.panel.goal.held_note)

    # untick Hold far side: one undo step, and the far face moves with the next drag
    click_box(win, win.panel.goal.anchor_box)
    assert win.state.goal.anchor == "none"
    assert win.undo_stack.undoText() == "Hold far side off"
    assert not win.action_set.anchor.isChecked()
    wait_idle(qtbot, win)
    drag(qtbot, win, row, offset=(40, -30))
    wait_idle(qtbot, win)
    st = win.state
    assert st.converged and st.result.held == () and st.result.held_face == ""
    assert np.abs(st.nodes[held] - rest[held]).max() > 1e-3 * st.surface.size, "it moves"
    assert not win.panel.goal.held_note.isVisible()
    assert not (node_colours(win) == rgb(style.HELD)).all(axis=1).any()
    save_shot(win, "goal_far_side_off", show=win.panel.goal.anchor_box)
    win.undo_stack.setClean()
    win.close()


# -- (b) folds ----------------------------------------------------------------------------
def test_a_folded_result_is_marked_on_the_model_and_undo_clears_it(qtbot, window):

    from isochor.app.view import style
    from isochor.app.window.readout import TONES

    win = window
    activate(qtbot, win)
    lat = win.state.lattice
    model = drawn(win, "model", "colors")
    assert (model == rgb(style.MODEL)).all(), "nothing folded at first"
    mapper = win.viewport.scene.actors["model"].GetMapper()
    assert mapper.GetScalarVisibility(), "the model is drawn with its per-vertex colours"

    def red_pixels():
        p = pixels(win).astype(int)
        return int(((p[..., 0] > 170) & (p[..., 1] < 90) & (p[..., 2] > 35)).sum())

    assert red_pixels() < 50

    # push the top centre node far below the torus: the lattice turns inside out
    top = lat.index(1, 1, 2)
    win.doc.selection.select([top])
    z = win.viewport.nodes[top, 2] - 1.5 * lat.size
    type_into(win.panel.coord[2], f"{z:.4f}")
    assert win.undo_stack.undoText() == "Move 1 node"
    win.doc.selection.select(
        []
    )  # the selection's gizmo has a red arrow: only the folds are red now
    wait_idle(qtbot, win, timeout=120_000)

    r = win.state.result
    assert r.folded and not r.converged
    assert win.readout.state_label.text().endswith("Folded")
    assert TONES["bad"] in win.readout.state_label.text()
    sentence = win.panel.solve_state.text()
    assert "Folded:" in sentence and "of the model is inside out" in sentence
    assert "undo, pin fewer nodes or move less" in sentence and TONES["bad"] in sentence
    model = drawn(win, "model", "colors")
    red = (model == rgb(style.FOLDED)).all(axis=1)
    assert red.sum() > 0 and np.array_equal(red, r.folds.vertices), "the folded vertices"
    assert (model[~red] == rgb(style.MODEL)).all()
    assert red_pixels() > 2000, "the folded part is red on screen"
    save_shot(win, "goal_folded", show=win.panel.solve_state)

    undo_key(win)
    wait_idle(qtbot, win)
    assert win.state.converged and not win.state.result.folded
    assert win.readout.state_label.text().endswith("Converged")
    assert (drawn(win, "model", "colors") == rgb(style.MODEL)).all(), "undo cleared the marks"
    assert red_pixels() < 50


# -- (c) the switches ---------------------------------------------------------------------
def test_the_constraint_switches_are_undoable_edits(qtbot, window):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    activate(qtbot, win)
    g = win.panel.goal
    assert g.anchor_box.isChecked() and g.fold_box.isChecked() and not g.centroid_box.isChecked()
    assert not g.volume_choice.isEnabled(), "the torus is one body"
    assert not win.action_set.per_body.isEnabled()
    for box in (g.anchor_box, g.centroid_box, g.fold_box, g.volume_choice):
        assert box.toolTip() and box.focusPolicy() & Qt.FocusPolicy.TabFocus

    click_box(win, g.centroid_box)
    assert win.state.goal.keep_centroid and win.action_set.centroid.isChecked()
    assert win.undo_stack.undoText() == "Keep centre of mass"
    assert win.is_solving(), "a new goal is solved"
    wait_idle(qtbot, win)
    assert win.state.converged and win.state.result.centroid_shift is not None
    assert "Centre of mass moved" in g.stats.text() and g.stats.isVisible()

    # the keyboard: Space on the focused Fold guard box
    g.fold_box.setFocus()
    QTest.keyClick(g.fold_box, Qt.Key.Key_Space)
    assert not win.state.goal.fold_guard and not win.action_set.fold_guard.isChecked()
    assert win.undo_stack.undoText() == "Fold guard off"
    # the Solve menu's action does the same as the box
    win.action_set.anchor.trigger()
    assert win.state.goal.anchor == "none" and not g.anchor_box.isChecked()
    assert win.undo_stack.undoText() == "Hold far side off"
    wait_idle(qtbot, win)

    for _ in range(3):
        undo_key(win)
    st = win.state
    assert (st.goal.anchor, st.goal.fold_guard, st.goal.keep_centroid) == ("far-side", True, False)
    assert g.anchor_box.isChecked() and g.fold_box.isChecked() and not g.centroid_box.isChecked()
    assert win.action_set.anchor.isChecked() and not win.action_set.centroid.isChecked()
    assert st.converged and not g.stats.isVisible(), "back on the example's solved state"
    undo_key(win, redo=True)
    assert win.state.goal.keep_centroid and g.centroid_box.isChecked()
    wait_idle(qtbot, win)


# -- (d) a pin on one axis ----------------------------------------------------------------
def test_a_node_pinned_on_z_keeps_its_z_and_moves_in_x_and_y(qtbot, window, monkeypatch):
    from isochor.app.view import style

    win = window
    row = pickable_node(win, want_free=True)
    click(win, row)
    assert list(win.doc.selection.rows) == [row]
    x_box, y_box, z_box = win.panel.axis_boxes
    click_box(win, z_box)
    st = win.state
    assert st.pin_axes[row].tolist() == [False, False, True] and st.axis_pinned[row]
    assert win.undo_stack.undoText() == "Pin 1 node on z"
    assert z_box.isChecked() and not x_box.isChecked() and not y_box.isChecked()
    assert not win.panel.pin_box.isChecked(), "not pinned on every axis"
    assert "pinned on z only" in win.panel.sel_role.text()
    assert (node_colours(win)[row] == rgb(style.AXIS_PINNED)).all()
    assert not (node_colours(win)[row] == rgb(style.PINNED)).all()
    wait_idle(qtbot, win)

    before = np.array(win.state.nodes[row])
    type_into(win.panel.target, "80")
    assert win.state.goal.target_ratio == pytest.approx(0.8)
    wait_idle(qtbot, win)
    st = win.state
    assert st.converged
    after = st.nodes[row]
    assert after[2] == before[2], "z is pinned"
    assert np.abs(after[:2] - before[:2]).max() > 1e-3 * st.surface.size, "x and y are free"
    assert (node_colours(win)[row] == rgb(style.AXIS_PINNED)).all()
    save_shot(win, "goal_pin_on_z", show=win.panel.sel_role)

    # the context menu offers the same, for the node under the cursor
    other = pickable_node(win, want_free=True, exclude={row})
    offered = []

    def run(menu, *args, **kwargs):
        actions = [a for a in menu.actions() if not a.isSeparator()]
        offered.extend(a.text() for a in actions)
        next(a for a in actions if a.text() == "Pin on X Only").trigger()

    monkeypatch.setattr(win, "exec_menu", run)
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    QTest.mouseClick(
        win.viewport,
        Qt.MouseButton.RightButton,
        Qt.KeyboardModifier.NoModifier,
        point(screen_positions(win)[0][other]),
    )
    assert {"Pin on X Only", "Pin on Y Only", "Pin on Z Only"} <= set(offered)
    assert win.state.pin_axes[other].tolist() == [True, False, False]
    assert win.undo_stack.undoText() == "Pin 1 node on x"
    wait_idle(qtbot, win)


# -- (e) two bodies -----------------------------------------------------------------------
def _two_spheres(path):
    from isochor.core.io.meshio import save_mesh
    from isochor.core.mesh import TriMesh
    from isochor.core.scenario.shapes import sphere_levels

    m = sphere_levels(4)[-1]
    small = m.vertices * 0.6 + [2.2, 0.0, 0.0]
    save_mesh(
        path,
        TriMesh(
            np.concatenate([m.vertices, small]), np.concatenate([m.faces, m.faces + len(small)])
        ),
    )
    return path


def test_two_bodies_show_their_volumes_and_each_body_keeps_its_own(qtbot, window, tmp_path):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    activate(qtbot, win)
    assert win.files.open_path(_two_spheres(tmp_path / "two.obj"))
    wait_idle(qtbot, win)
    g = win.panel.goal
    assert win.state.surface.bodies.count == 2
    assert g.volume_choice.isEnabled() and win.action_set.per_body.isEnabled()
    assert g.volume_choice.currentText() == "Total"

    # squash the small sphere's end of the lattice: in total, the bodies trade volume
    lat = win.state.lattice
    end = lat.index(lat.shape[0] - 1, 1, 1)
    win.doc.selection.select([end])
    type_into(win.panel.coord[0], f"{win.viewport.nodes[end, 0] - 0.8:.4f}")
    wait_idle(qtbot, win)
    bodies = win.state.result.bodies
    assert len(bodies) == 2 and win.state.converged
    shares = [100 * b.final / b.original for b in bodies]
    assert max(abs(s - 100) for s in shares) > 0.5
    text = g.stats.text()
    assert g.stats.isVisible()
    assert text.startswith("Volume of each body:")
    assert f"body 1 {shares[0]:.2f} %" in text and f"body 2 {shares[1]:.2f} %" in text

    # the wheel passing over the choice while scrolling the Inspector changes nothing
    from PySide6.QtCore import QPoint, QPointF
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtWidgets import QApplication

    win.viewport.setFocus()
    steps = win.undo_stack.count()
    centre = QPointF(g.volume_choice.width() / 2, g.volume_choice.height() / 2)
    for delta in (120, -120):
        wheel = QWheelEvent(
            centre,
            QPointF(g.volume_choice.mapToGlobal(centre.toPoint())),
            QPoint(0, 0),
            QPoint(0, delta),
            Qt.MouseButton.NoButton,
            Qt.KeyboardModifier.NoModifier,
            Qt.ScrollPhase.NoScrollPhase,
            False,
        )
        QApplication.sendEvent(g.volume_choice, wheel)
    assert win.state.goal.preserve == "total" and win.undo_stack.count() == steps

    # Each body, chosen with the keyboard
    g.volume_choice.setFocus()
    QTest.keyClick(g.volume_choice, Qt.Key.Key_Down)
    assert win.state.goal.preserve == "per-body" and win.action_set.per_body.isChecked()
    assert win.undo_stack.undoText() == "Preserve each body"
    wait_idle(qtbot, win)
    st = win.state
    assert st.converged
    shares = [100 * b.final / b.original for b in st.result.bodies]
    assert all(abs(s - 100) < 0.1 for s in shares), shares
    text = g.stats.text()
    assert f"body 1 {shares[0]:.2f} %" in text and f"body 2 {shares[1]:.2f} %" in text
    save_shot(win, "goal_each_body", show=g.stats)
    undo_key(win)
    assert win.state.goal.preserve == "total" and g.volume_choice.currentText() == "Total"
    wait_idle(qtbot, win)
