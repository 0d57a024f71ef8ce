"""Surface handles and symmetric editing in the window (issue 12), driven with real mouse and
key events: a handle placed with Ctrl+click and dragged lands its point where it was dropped
with the volume kept; the Handle tool, removal and undo; a mirrored move gives a symmetric
lattice; a scenario with two handles on the cow solves in the window to the nodes the
headless solve finds.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from isochor.app.cli.main import run_solve
from tests.gui.conftest import open_window, save_shot, wait_idle
from tests.gui.test_editor import click, drag, point, screen_positions
from tests.gui.test_goal_window import rgb, undo_key
from tests.gui.test_tools_window import press_keys


def on_model(win, dx=25, dy=-20):
    """A widget pixel on the sphere near (dx, dy) off its centre, clear of nodes, handles
    and the gizmo."""
    from PySide6.QtCore import QPointF

    vp = win.viewport
    c = vp.camera_control.projection().project([0.0, 0.0, 0.0])[0][0]
    for r in range(0, 60, 4):
        for a in np.linspace(0, 2 * np.pi, 12, endpoint=False):
            xy = np.round(c + (dx, dy) + r * np.array([np.cos(a), np.sin(a)]))
            pos = QPointF(*xy)
            clear = (
                vp.camera_control.node_at(pos) < 0
                and vp.handles.at(vp.camera_control.projection(), *xy) < 0
            )
            if (
                clear
                and vp.gizmo.axis_at(vp.camera_control.projection(), *xy) is None
                and vp.camera_control.model_hit(pos)
            ):
                return xy
    raise AssertionError("no free spot on the model")


def mouse(win, kind, xy, button=None, mods=None):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    button = button or Qt.MouseButton.LeftButton
    mods = mods or Qt.KeyboardModifier.NoModifier
    getattr(QTest, kind)(win.viewport, button, mods, point(xy))


def drag_px(qtbot, win, start, offset, steps=8, mods=None):
    from PySide6.QtTest import QTest

    mouse(win, "mousePress", start, mods=mods)
    for i in range(1, steps + 1):
        QTest.mouseMove(win.viewport, point(np.asarray(start) + np.asarray(offset) * i / steps))
        qtbot.wait(5)
    mouse(win, "mouseRelease", np.asarray(start) + offset, mods=mods)


def handle_xy(win, i=0):
    return win.viewport.camera_control.projection().project(win.viewport.handles.targets[i])[0][0]


def test_place_and_drag_a_handle_and_undo(qtbot, sphere):
    from PySide6.QtCore import Qt

    from isochor.app.view import style

    win = sphere
    vp = win.viewport
    st = win.state
    size = st.surface.size
    rest_volume = st.surface.rest_volume
    nodes0 = np.array(st.nodes)

    # Ctrl+click on the model: a handle on the surface point under the cursor
    where = on_model(win)
    mouse(win, "mouseClick", where, mods=Qt.KeyboardModifier.ControlModifier)
    assert win.undo_stack.undoText() == "Add handle" and len(win.state.handles) == 1
    h = win.state.handles[0]
    full = st.surface.full
    assert np.min(np.linalg.norm(full.vertices - np.array(h.at), axis=1)) < 0.1 * size
    assert np.allclose(h.at, h.to, atol=1e-9), "placed where the point is"
    assert np.allclose(handle_xy(win), where, atol=1.0), "the marker is under the cursor"
    assert (vp.handles.target_colours()[0] == rgb(style.HANDLE)).all()
    assert vp.handles.actors["ring"].GetVisibility(), "the new handle is selected"
    assert "1 handle" in win.panel.handles.count.text()
    wait_idle(qtbot, win)

    # drag the marker: its target goes where it is dropped, the solve makes the point follow
    start = handle_xy(win)
    drop = start + (50, -35)
    drag_px(qtbot, win, start, (50, -35))
    assert win.undo_stack.undoText() == "Move handle" and win.undo_stack.count() == 2
    target = np.array(win.state.handles[0].to)
    assert np.allclose(vp.camera_control.projection().project(target)[0][0], drop, atol=1.0)
    assert np.linalg.norm(target - np.array(h.at)) > 0.1 * size
    wait_idle(qtbot, win)
    st = win.state
    assert st.converged and st.result.handles and st.result.handles[0].met
    reached = st.lattice.deform(np.array([h.at]), st.nodes)[0]
    assert np.linalg.norm(reached - target) < 1e-3 * size, "the point ends at the drop point"
    assert vp.model_volume / rest_volume == pytest.approx(1.0, abs=1e-3), "volume kept"
    assert np.allclose(vp.handles.points[0], reached), "the white dot is on the point"
    assert "The handle is met." in win.panel.solve_state.text()
    assert win.statusBar().currentMessage() == "The handle is met."
    assert "all met" in win.panel.handles.count.text()
    save_shot(win, "handles_dragged", show=win.panel.handles)

    undo_key(win)
    assert np.allclose(win.state.handles[0].to, h.to), "undo: the handle back"
    undo_key(win)
    assert win.state.handles == () and np.array_equal(win.state.nodes, nodes0)
    win.session.flush()
    assert not vp.handles.actors["targets"].GetVisibility()


def test_handle_tool_place_and_drag_at_once_then_remove(qtbot, sphere, monkeypatch):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    QTest.keyClick(vp, Qt.Key.Key_H)
    assert win.action_set.handle_tool.isChecked() and vp.handle_tool.active
    assert win.panel.handles.tool_box.isChecked()
    # a press on the model with the tool and a drag: one undo step that adds the handle
    start = on_model(win, -20, 15)
    drag_px(qtbot, win, start, (-40, 30))
    assert win.undo_stack.count() == 1 and win.undo_stack.undoText() == "Add handle"
    assert np.allclose(handle_xy(win), start + (-40, 30), atol=1.0)
    wait_idle(qtbot, win)
    assert win.state.converged
    # a plain click with the tool adds a second one; clicking the first selects it
    mouse(win, "mouseClick", on_model(win, 30, 30))
    assert len(win.state.handles) == 2 and win.doc.selection.handle == 1
    wait_idle(qtbot, win)
    mouse(win, "mouseClick", handle_xy(win, 0))
    assert win.doc.selection.handle == 0 and win.panel.handles.list.currentRow() == 0
    # Delete removes the selected handle
    QTest.keyClick(vp, Qt.Key.Key_Delete)
    assert len(win.state.handles) == 1 and win.undo_stack.undoText() == "Remove handle"
    wait_idle(qtbot, win)
    # the context menu of a handle offers "Remove handle"
    offered = []

    def run(menu, *args, **kwargs):
        actions = [a for a in menu.actions() if not a.isSeparator()]
        offered.extend(a.text() for a in actions)
        actions[0].trigger()

    monkeypatch.setattr(win, "exec_menu", run)
    mouse(win, "mouseClick", handle_xy(win, 0), button=Qt.MouseButton.RightButton)
    assert offered == ["Remove handle"] and win.state.handles == ()
    undo_key(win)
    assert len(win.state.handles) == 1
    QTest.keyClick(vp, Qt.Key.Key_H)
    assert not vp.handle_tool.active
    wait_idle(qtbot, win)


def test_a_mirrored_move_gives_a_symmetric_lattice(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    lat = win.state.lattice
    choice = win.panel.goal.symmetry_choice
    win.inspector_scroll.ensureWidgetVisible(choice)
    choice.setFocus()
    QTest.keyClick(choice, Qt.Key.Key_Down)  # Off -> X
    assert win.state.goal.symmetry == "x"
    assert win.undo_stack.undoText() == "Symmetry across x"
    assert vp.scene.actors["mirror"].GetVisibility(), "the mirror plane is drawn"
    mirror = win.state.mirror
    wait_idle(qtbot, win)

    xy, visible = screen_positions(win)
    side = [
        lat.index(0, j, k)
        for j in range(3)
        for k in range(3)
        if visible[lat.index(0, j, k)] and visible[lat.index(2, j, k)]
    ]
    row = max(side, key=lambda r: min(xy[r, 0], vp.width() - xy[r, 0]))
    partner = int(mirror.partner[row])
    before = np.array(win.state.nodes)
    drag(qtbot, win, row, offset=(-30, -40))
    assert win.undo_stack.undoText() == "Move 1 node, mirrored"
    start = win.session.last_solve_input[0]
    assert np.allclose(start[partner], mirror.point(start[row]), atol=1e-12)
    assert win.state.moved[row] and win.state.moved[partner]
    wait_idle(qtbot, win)
    st = win.state
    assert st.converged
    assert mirror.asymmetry(st.nodes) < 1e-9, "a symmetric result"
    assert vp.model_volume / st.surface.rest_volume == pytest.approx(1.0, abs=1e-3)
    save_shot(win, "symmetry_mirrored_move", show=choice)

    # a handle gets its mirror image, drawn dimmed (the solve adds it)
    from isochor.app.view import style

    mouse(win, "mouseClick", on_model(win, 0, 0), mods=Qt.KeyboardModifier.ControlModifier)
    assert len(win.state.handles) == 1 and len(vp.handles.targets) == 2
    h = win.state.handles[0]
    assert np.allclose(vp.handles.targets[1], mirror.point(h.to))
    colours = vp.handles.target_colours()
    assert (colours[0] == rgb(style.HANDLE)).all() and (colours[1] < colours[0]).all()
    wait_idle(qtbot, win)
    assert mirror.asymmetry(win.state.nodes) < 1e-9
    undo_key(win)
    wait_idle(qtbot, win)

    # a pin is mirrored too
    other = lat.index(0, 0, 0)
    win.doc.selection.select([other])
    QTest.keyClick(vp, Qt.Key.Key_P)
    assert win.state.pinned[other] and win.state.pinned[int(mirror.partner[other])]
    undo_key(win)
    undo_key(win)
    assert np.array_equal(win.state.nodes, before) and not win.state.moved.any()
    undo_key(win)
    assert win.state.goal.symmetry == "none" and choice.currentData() == "none"
    assert not vp.scene.actors["mirror"].GetVisibility()


def test_scale_gesture_under_symmetry_mirrors_onto_the_partners(qtbot, sphere):
    win = sphere
    vp = win.viewport
    lat = win.state.lattice
    win.panel.goal.symmetryChosen.emit("y")
    assert win.state.goal.symmetry == "y"
    wait_idle(qtbot, win)
    rows = [lat.index(i, 0, k) for i in range(3) for k in range(3)]  # the y-min layer
    click(win, rows[4])
    win.action_set.select_layer[1].trigger()
    assert sorted(win.doc.selection.rows) == sorted(rows)
    from PySide6.QtTest import QTest

    QTest.mouseMove(vp, point((vp.width() * 0.7, vp.height() * 0.3)))
    press_keys(vp, "sz0.5\n")
    assert win.undo_stack.undoText() == "Scale 9 nodes, mirrored"
    wait_idle(qtbot, win)
    st = win.state
    mirror = st.mirror
    assert st.moved[mirror.partner[rows]].all()
    assert mirror.asymmetry(st.nodes) < 1e-9


def test_two_handles_on_the_cow_solve_as_the_command_line_does(qtbot, themed_app, tmp_path):
    from isochor.core.api import Session
    from isochor.core.scenario.document import Scenario
    from tests.models import model

    cow = model("cow.obj")
    from isochor.core.io.meshio import load_mesh

    mesh = load_mesh(cow).mesh
    v = np.asarray(mesh.vertices)
    size = float((v.max(axis=0) - v.min(axis=0)).max())
    nose, tail = v[np.argmax(v[:, 0])], v[np.argmin(v[:, 0])]
    up = np.array([0.0, 0.08 * size, 0.0])
    doc = {
        "format": "isochor-scenario",
        "version": 3,
        "model": {"path": str(cow)},
        "lattice": {"nodes": [4, 3, 3]},
        "handles": [
            {"at": nose.tolist(), "to": (nose + up).tolist()},
            {"at": tail.tolist(), "to": (tail - up).tolist()},
        ],
    }
    path = tmp_path / "cow_handles.json"
    path.write_text(json.dumps(doc))

    win = open_window(qtbot)
    wait_idle(qtbot, win)
    assert win.files.open_path(path)
    assert len(win.state.handles) == 2 and not win.state.solved
    wait_idle(qtbot, win, timeout=120_000)
    st = win.state
    assert st.solved and st.converged

    sc = Scenario.read(path)
    session = Session(sc)
    problem = session.problem
    headless = run_solve(session)  # the command line's own solve
    assert headless.converged
    assert np.allclose(st.nodes, headless.nodes, atol=1e-9 * problem.surface.size, rtol=0)
    for h, r in zip(sc.handles, headless.handles):
        assert r.miss < 1e-3 and np.allclose(r.to, h.to)
    assert len(win.viewport.handles.targets) == 2
    save_shot(win, "handles_cow", show=win.panel.handles)
    win.undo_stack.setClean()
    win.close()
