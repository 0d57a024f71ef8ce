"""The transform tools in the window (issue 12): G, R and S on the node selection with axis
locks and typed values, the translate gizmo, framing the selection, the orthographic
camera, the selection helpers and box selection of what is visible, and what makes the
lattice legible (node shapes by role, node size by density, the Inspector at 1280x720).

Driven with real mouse and key events on the view; what is drawn is read back from the
actors' own arrays.
"""

from __future__ import annotations

import numpy as np
import pytest

from isochor.app.editor import goalrules
from tests.gui.conftest import open_window, save_shot, wait_idle
from tests.gui.test_editor import click, pickable_node, point, screen_positions
from tests.gui.test_goal_window import drawn, rgb, undo_key

KEYS = {
    ".": "Key_Period",
    "-": "Key_Minus",
    "\n": "Key_Return",
    "\b": "Key_Backspace",
    "\x1b": "Key_Escape",
}


def press_keys(widget, text: str) -> None:
    """Type ``text`` on ``widget`` key by key ("\\n" is Enter, "\\x1b" Esc)."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    for ch in text:
        name = KEYS.get(ch, f"Key_{ch.upper()}")
        QTest.keyClick(widget, getattr(Qt.Key, name))


def points_of(win, actor: str) -> np.ndarray:
    """The points an actor's mapper draws."""
    import pyvista as pv

    mapper = win.viewport.scene.actors[actor].GetMapper()
    return np.array(pv.wrap(mapper.GetInput()).points)


def hover(win, xy) -> None:
    from PySide6.QtTest import QTest

    QTest.mouseMove(win.viewport, point(xy))


def layer_x(win, i: int = 2) -> np.ndarray:
    """Select the lattice layer i = ``i`` with a click on one of its nodes and the Edit
    menu's Select > Layer Across X."""
    lat = win.state.lattice
    xy, visible = screen_positions(win)
    rows = [lat.index(i, j, k) for j in range(3) for k in range(3)]
    row = max((r for r in rows if visible[r]), key=lambda r: -abs(xy[r, 0] - 400))
    click(win, row)
    assert list(win.doc.selection.rows) == [row]
    win.action_set.select_layer[0].trigger()
    assert sorted(win.doc.selection.rows) == sorted(rows)
    return np.array(sorted(rows))


# -- G, R, S with typed values ----------------------------------------------------------------
def test_scale_a_layer_by_a_typed_factor_along_z_and_undo(qtbot, sphere):
    win = sphere
    vp = win.viewport
    rows = layer_x(win)
    before = np.array(win.state.nodes)
    centre = before[rows].mean(axis=0)
    hover(win, (vp.width() * 0.7, vp.height() * 0.3))
    press_keys(vp, "sz0.5")
    assert vp.transform_tool.running and win.doc.drag is not None
    message = win.statusBar().currentMessage()
    assert message == "Scale 0.5 along z — type a value, X/Y/Z lock, Enter confirms, Esc cancels"
    # the guide line is drawn in z's colour through the centre
    guide = win.viewport.scene.actors["guide"]
    assert guide.GetVisibility()
    assert np.allclose(guide.GetProperty().GetColor(), rgb(style_axis("z")) / 255, atol=1e-6)
    ends = points_of(win, "guide")
    assert np.allclose(ends[:, :2], centre[:2]) and ends[1, 2] > ends[0, 2]
    save_shot(win, "tools_scale_typed")
    press_keys(vp, "\n")
    assert not vp.transform_tool.running and win.undo_stack.count() == 1
    assert win.undo_stack.undoText() == "Scale 9 nodes"
    start = win.session.last_solve_input[0]
    expect = before[rows].copy()
    expect[:, 2] = centre[2] + 0.5 * (expect[:, 2] - centre[2])
    assert np.allclose(start[rows], expect, atol=1e-12), "scaled by 0.5 along z about the centre"
    others = np.setdiff1d(np.arange(len(before)), rows)
    assert np.array_equal(start[others], before[others])
    wait_idle(qtbot, win)
    st = win.state
    assert st.converged and st.moved[rows].all() and np.allclose(st.nodes[rows], expect)
    assert vp.model_volume / st.surface.rest_volume == pytest.approx(1.0, abs=1e-3)

    undo_key(win)
    assert np.array_equal(win.state.nodes, before) and not win.state.moved.any()
    win.session.flush()
    assert np.allclose(vp.nodes, before)


def style_axis(axis: str) -> str:
    from isochor.app.view import style

    return style.AXIS_COLOURS[axis]


def test_rotate_and_grab_by_typed_values_and_escape(qtbot, sphere):
    win = sphere
    vp = win.viewport
    lat = win.state.lattice
    rows = layer_x(win)
    before = np.array(win.state.nodes)
    centre = before[rows].mean(axis=0)
    hover(win, (vp.width() * 0.7, vp.height() * 0.3))

    # R X 90: a quarter turn about the x axis through the centre (y -> z, z -> -y)
    press_keys(vp, "rx90")
    assert win.statusBar().currentMessage().startswith("Rotate 90° about x — type a value")
    press_keys(vp, "\n")
    assert win.undo_stack.undoText() == "Rotate 9 nodes"
    start = win.session.last_solve_input[0]
    rel = before[rows] - centre
    expect = centre + np.c_[rel[:, 0], -rel[:, 2], rel[:, 1]]
    assert np.allclose(start[rows], expect, atol=1e-12)
    wait_idle(qtbot, win)

    # G Y 0.2 (typed "-" flips the sign, Backspace erases): moves by -0.2 along y
    now = np.array(win.state.nodes)
    press_keys(vp, "gy0.25\b-")
    assert win.statusBar().currentMessage().startswith("Move -0.2 along y — type a value")
    press_keys(vp, "\n")
    assert win.undo_stack.undoText() == "Move 9 nodes" and win.undo_stack.count() == 2
    start = win.session.last_solve_input[0]
    assert np.allclose(start[rows] - now[rows], [0.0, -0.2, 0.0], atol=1e-12)
    wait_idle(qtbot, win)

    # Esc cancels: back where it was, no undo step, no solve
    now = np.array(win.state.nodes)
    press_keys(vp, "s3")
    win.session.flush()
    assert not np.allclose(vp.nodes[rows], now[rows]), "the view shows the gesture"
    press_keys(vp, "\x1b")
    assert not vp.transform_tool.running and win.undo_stack.count() == 2 and not win.is_solving()
    assert np.array_equal(win.state.nodes, now)
    win.session.flush()
    assert np.allclose(vp.nodes, now)
    assert win.statusBar().currentMessage() == ""
    # G, R or S again switches the gesture: the undo step is the last mode's
    press_keys(vp, "gsz2\n")
    assert win.undo_stack.undoText() == "Scale 9 nodes" and win.undo_stack.count() == 3
    rel = now[rows] - now[rows].mean(axis=0)
    got = win.session.last_solve_input[0][rows] - now[rows].mean(axis=0)
    assert np.allclose(got, rel * [1, 1, 2], atol=1e-12)
    undo_key(win)
    # digits during a gesture are typed, not the "1: front view" shortcut
    cam = np.array(vp.camera.position)
    press_keys(vp, "g1\x1b")
    assert np.allclose(vp.camera.position, cam)
    undo_key(win)
    undo_key(win)
    assert np.array_equal(win.state.nodes, before)
    assert lat.n_nodes == len(before)


def test_mouse_driven_scale_and_rotate_confirm_with_a_click(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    rows = layer_x(win)
    before = np.array(win.state.nodes)
    centre = before[rows].mean(axis=0)
    c = vp.camera_control.projection().project(centre)[0][0]
    start = c + (60.0, 0.0)
    hover(win, start)
    press_keys(vp, "s")
    for i in range(1, 7):
        hover(win, c + (60.0 + 10 * i, 0.0))  # twice as far from the centre
    message = win.statusBar().currentMessage()  # "Scale 2 — ..." (whole pixels: about 2)
    assert message.startswith("Scale ") and float(message.split()[1]) == pytest.approx(2, abs=0.02)
    end = c + (120.0, 0.0)
    QTest.mouseClick(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(end))
    assert not vp.transform_tool.running and win.undo_stack.undoText() == "Scale 9 nodes"
    # the factor is the ratio of the mouse's distances from the centre (whole pixels)
    factor = np.hypot(*(np.round(end) - c)) / np.hypot(*(np.round(start) - c))
    assert factor == pytest.approx(2.0, abs=0.02)
    got = win.session.last_solve_input[0][rows]
    assert np.allclose(got, centre + factor * (before[rows] - centre), atol=1e-9)
    wait_idle(qtbot, win)

    # R with the mouse a quarter turn around the centre; a right click cancels
    now = np.array(win.state.nodes)
    c = vp.camera_control.projection().project(now[rows].mean(axis=0))[0][0]
    hover(win, c + (80.0, 0.0))
    press_keys(vp, "r")
    for a in np.linspace(0, np.pi / 2, 8)[1:]:
        hover(win, c + 80.0 * np.array([np.cos(a), -np.sin(a)]))
    message = win.statusBar().currentMessage()
    assert message.startswith("Rotate ") and "° about the line of sight" in message
    assert float(message.split()[1].rstrip("°")) == pytest.approx(90.0, abs=1.5)
    # the nodes turn on screen the way the mouse turned: counter-clockwise, a quarter
    win.session.flush()
    proj = vp.camera_control.projection()
    far = max(rows, key=lambda r: np.hypot(*(proj.project(now[r])[0][0] - c)))
    a0 = proj.project(now[far])[0][0] - c
    a1 = proj.project(vp.nodes[far])[0][0] - c
    turned = np.degrees(np.arctan2(-a1[1], a1[0]) - np.arctan2(-a0[1], a0[0])) % 360
    assert turned == pytest.approx(90.0, abs=3.0)
    assert not np.allclose(vp.nodes[rows], now[rows])
    QTest.mouseClick(vp, Qt.MouseButton.RightButton, Qt.KeyboardModifier.NoModifier, point(c))
    assert not vp.transform_tool.running and win.undo_stack.count() == 1
    assert np.array_equal(win.state.nodes, now)


# -- the gizmo ----------------------------------------------------------------------------
def test_the_gizmo_arrow_moves_the_selection_along_its_axis(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    gizmo = vp.gizmo
    assert not gizmo.visible, "no gizmo without a selection"
    row = pickable_node(win, want_free=True)
    click(win, row)
    assert gizmo.visible and np.allclose(gizmo.centre, vp.nodes[row])
    for axis, actor in gizmo.actors.items():
        assert actor.GetVisibility()
        assert np.allclose(actor.GetProperty().GetColor(), rgb(style_axis(axis)) / 255)
    # press on the x arrow's shaft, drag sideways
    proj = vp.camera_control.projection()
    a, b = proj.project(np.array([gizmo.centre + [0.65 * gizmo.length, 0, 0], gizmo.tip("x")]))[0]
    before = np.array(win.state.nodes)
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(a))
    direction = (b - a) / np.linalg.norm(b - a)
    for i in range(1, 7):
        QTest.mouseMove(vp, point(a + direction * 12 * i + (0, 9 * i)))
        qtbot.wait(5)
    guide = vp.scene.actors["guide"]
    assert guide.GetVisibility(), "the x guide is drawn during the arrow's drag"
    assert np.allclose(guide.GetProperty().GetColor(), rgb(style_axis("x")) / 255)
    QTest.mouseRelease(
        vp,
        Qt.MouseButton.LeftButton,
        Qt.KeyboardModifier.NoModifier,
        point(a + direction * 72 + (0, 54)),
    )
    assert win.undo_stack.undoText() == "Move 1 node"
    moved = win.session.last_solve_input[0][row] - before[row]
    assert moved[0] > 0.05 * win.state.surface.size and np.allclose(moved[1:], 0, atol=1e-12)
    assert not guide.GetVisibility()
    wait_idle(qtbot, win)
    assert np.allclose(gizmo.centre, vp.nodes[row]), "the gizmo follows the node"


# -- camera ---------------------------------------------------------------------------------
def test_f_frames_the_selection_and_5_toggles_orthographic(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    lat = win.state.lattice
    corner = lat.index(2, 0, 2)
    win.doc.selection.select([corner])
    distance = vp.camera.distance
    QTest.keyClick(vp, Qt.Key.Key_F)
    xy = vp.camera_control.projection().project(vp.nodes[corner])[0][0]
    assert np.hypot(*(xy - (vp.width() / 2, vp.height() / 2))) < 3, "the node is in the middle"
    assert vp.camera.distance < 0.7 * distance, "and closer"
    win.doc.selection.select([])
    QTest.keyClick(vp, Qt.Key.Key_F)  # nothing selected: the whole model
    xy, _, visible = vp.camera_control.projection().project(vp.nodes)
    assert visible.all() and (xy >= 0).all() and (xy[:, 0] <= vp.width()).all()
    assert (xy[:, 1] <= vp.height()).all()

    assert not vp.camera_control.orthographic and not win.action_set.ortho.isChecked()
    assert win.action_set.ortho in win.menuBar().actions()[3].menu().actions(), "in the View menu"
    QTest.keyClick(vp, Qt.Key.Key_5)
    assert vp.camera_control.orthographic and win.action_set.ortho.isChecked()
    assert vp.renderer.GetActiveCamera().GetParallelProjection()
    row = pickable_node(win, want_free=True)
    click(win, row)
    assert list(win.doc.selection.rows) == [row], "picking works in the orthographic view"
    save_shot(win, "tools_orthographic")
    QTest.keyClick(vp, Qt.Key.Key_5)
    assert not vp.camera_control.orthographic


# -- selection helpers ----------------------------------------------------------------------
def test_select_row_face_invert_and_visible_only_box(qtbot, sphere):
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    lat = win.state.lattice
    win.doc.selection.select([lat.index(2, 0, 1)])
    win.action_set.select_line[1].trigger()  # Row Along Y
    assert sorted(win.doc.selection.rows) == [lat.index(2, j, 1) for j in range(3)]
    win.action_set.select_face.trigger()
    assert sorted(win.doc.selection.rows) == [
        lat.index(2, j, k) for j in range(3) for k in range(3)
    ]
    assert "x max face" in win.statusBar().currentMessage()
    win.doc.selection.select([lat.index(1, 1, 1)])
    win.action_set.select_face.trigger()  # the centre node is on no face
    assert list(win.doc.selection.rows) == [lat.index(1, 1, 1)]
    assert "not on one face" in win.statusBar().currentMessage()
    QTest.keyClick(vp, Qt.Key.Key_I, Qt.KeyboardModifier.ControlModifier)
    assert len(win.doc.selection.rows) == 26 and lat.index(1, 1, 1) not in win.doc.selection.rows

    # a box around everything: all 27; with "Select visible only", not those the sphere hides
    def box():
        shift = Qt.KeyboardModifier.ShiftModifier
        QTest.mousePress(vp, Qt.MouseButton.LeftButton, shift, QPoint(2, 2))
        QTest.mouseMove(vp, QPoint(vp.width() // 2, vp.height() // 2))
        QTest.mouseMove(vp, QPoint(vp.width() - 3, vp.height() - 3))
        QTest.mouseRelease(
            vp, Qt.MouseButton.LeftButton, shift, QPoint(vp.width() - 3, vp.height() - 3)
        )

    win.doc.selection.select([])
    box()
    assert len(win.doc.selection.rows) == 27
    win.action_set.visible_only.setChecked(True)
    win.doc.selection.select([])
    box()
    seen = set(win.doc.selection.rows.tolist())
    assert lat.index(1, 1, 1) not in seen, "the centre node is inside the sphere"
    # the nodes nearest the camera are in front of the sphere; the farthest behind it
    to_camera = np.linalg.norm(vp.nodes - np.array(vp.camera.position), axis=1)
    assert int(np.argmin(to_camera)) in seen and int(np.argmax(to_camera)) not in seen
    assert 10 <= len(seen) < 26


# -- legibility ---------------------------------------------------------------------------
def test_roles_have_shapes_and_the_legend_says_so(qtbot, sphere):
    from isochor.app.view import glyphs, style

    win = sphere
    lat = win.state.lattice
    a, b, c = lat.index(0, 0, 0), lat.index(2, 2, 2), lat.index(0, 2, 0)
    win.set_pins([a], True)
    win.commit_edit(goalrules.edit_pin_axes(win.doc.base(), [c], "z"))
    win.doc.selection.select([b])
    win.type_position(0, float(win.viewport.nodes[b, 0]) + 0.2)
    wait_idle(qtbot, win)
    shapes = win.viewport.scene.node_shapes()
    assert shapes[a] == glyphs.CUBE and shapes[b] == glyphs.RINGED and shapes[c] == glyphs.DIAMOND
    free = np.flatnonzero(~win.state.fixed)
    assert (shapes[free] == glyphs.SPHERE).all()
    colours = drawn(win, "nodes", "rgb")
    assert (colours[a] == rgb(style.PINNED)).all() and (colours[b] == rgb(style.MOVED)).all()
    legend = win.viewport.colour_legend.text()
    for shape in ("cube", "ringed", "diamond"):
        assert style.SHAPES[shape] in legend
    save_shot(win, "tools_node_shapes")


def test_node_size_follows_lattice_density(qtbot, sphere):
    win = sphere
    size3 = win.viewport.scene.node_size / win.state.lattice.size
    win.rebuild_lattice((8, 8, 8))
    wait_idle(qtbot, win)
    size8 = win.viewport.scene.node_size / win.state.lattice.size
    assert size8 < 0.7 * size3
    # an 8x8x8 lattice leaves the model visible: the nodes cover a small part of the view
    spacing = win.state.lattice.size / 7
    assert win.viewport.scene.node_size < 0.2 * spacing
    save_shot(win, "tools_dense_lattice")


def test_the_inspector_fits_a_1280x720_window(qtbot, themed_app):
    from PySide6.QtWidgets import QAbstractButton, QAbstractSpinBox, QComboBox

    win = open_window(qtbot, size=(1280, 720))
    wait_idle(qtbot, win)
    qtbot.waitUntil(lambda: (win.width(), win.height()) == (1280, 720), timeout=2000)
    scroll = win.inspector_scroll
    assert not scroll.horizontalScrollBar().isVisible()
    viewport_width = scroll.viewport().width()
    assert win.panel.width() <= viewport_width
    controls = (
        win.panel.findChildren(QAbstractButton)
        + win.panel.findChildren(QAbstractSpinBox)
        + win.panel.findChildren(QComboBox)
    )
    assert len(controls) > 20
    for w in controls:
        if not w.isVisibleTo(win.panel):
            continue
        left = w.mapTo(win.panel, w.rect().topLeft()).x()
        assert left >= 0 and left + w.width() <= viewport_width, w
        assert w.width() >= w.minimumSizeHint().width(), f"{w} is cut"
    assert win.viewport.width() >= 640, "the view keeps most of the window"
    save_shot(win, "tools_inspector_1280x720")
    win.undo_stack.setClean()
    win.close()
