"""More of the editor: box selection, axis locks, Esc, live solving, plain FFD, the lattice,
the target volume, files, the close prompt and solver failures."""

from __future__ import annotations

import numpy as np
import pytest

from tests.gui.conftest import wait_idle
from tests.gui.test_editor import click, drag, pickable_node, point, screen_positions


def test_shift_drag_box_selects_the_nodes_inside(qtbot, window):
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    win = window
    vp = win.viewport
    xy, visible = screen_positions(win)
    # a box around the left half of the view, starting on empty space; the nodes inside
    # are those left of the box's own right edge (a node can sit on the median itself)
    x0, x1 = 5, int(np.median(xy[:, 0])) - 1
    left = xy[:, 0] <= x1
    y0, y1 = 5, vp.height() - 5
    start = QPoint(x0, y0)
    assert vp.camera_control.node_at(start) == -1
    shift = Qt.KeyboardModifier.ShiftModifier
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, shift, start)
    QTest.mouseMove(vp, QPoint((x0 + x1) // 2, (y0 + y1) // 2))
    QTest.mouseMove(vp, QPoint(x1, y1))
    QTest.mouseRelease(vp, Qt.MouseButton.LeftButton, shift, QPoint(x1, y1))
    expected = np.flatnonzero(left & visible & (xy[:, 1] >= y0) & (xy[:, 1] <= y1))
    assert len(expected) >= 2
    assert np.array_equal(vp.selection, expected)
    assert not win.is_solving() and win.undo_stack.count() == 0, "selecting is no edit"
    assert "nodes selected" in win.panel.sel_title.text()

    # a click on empty space clears it; Shift-click toggles single nodes
    QTest.mouseClick(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, start)
    assert len(vp.selection) == 0
    a = pickable_node(win, want_free=True)
    b = pickable_node(win, want_free=False)
    click(win, a)
    click(win, b, shift)
    assert set(vp.selection) == {a, b}
    click(win, a, shift)
    assert list(vp.selection) == [b]


def test_axis_lock_and_escape_during_a_drag(qtbot, window):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    vp = win.viewport
    row = pickable_node(win, want_free=True)
    before = np.array(win.state.nodes)
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    QTest.mouseMove(vp, point(start + (10, -10)))
    assert vp.dragging
    QTest.keyClick(vp, Qt.Key.Key_Z)  # lock to the world z axis
    for i in range(1, 6):
        QTest.mouseMove(vp, point(start + (10 + 8 * i, -10 - 12 * i)))
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (50, -70))
    )
    moved = win.session.last_solve_input[0][row] - before[row]
    assert abs(moved[2]) > 1e-3 * win.state.surface.size
    assert np.allclose(moved[:2], 0, atol=1e-12), "locked to z"
    wait_idle(qtbot, win)

    # Shift+Z: the plane across z (z stays)
    before = np.array(win.state.nodes)
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    QTest.mouseMove(vp, point(start + (5, 5)))
    QTest.keyClick(vp, Qt.Key.Key_Z, Qt.KeyboardModifier.ShiftModifier)
    for i in range(1, 6):
        QTest.mouseMove(vp, point(start + (5 + 10 * i, 5 + 6 * i)))
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (55, 35))
    )
    moved = win.session.last_solve_input[0][row] - before[row]
    assert abs(moved[2]) < 1e-9 and np.abs(moved[:2]).max() > 1e-3
    wait_idle(qtbot, win)

    # Esc cancels: everything back, no undo step, no solve
    count = win.undo_stack.count()
    before = np.array(win.state.nodes)
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    for i in range(1, 6):
        QTest.mouseMove(vp, point(start + (12 * i, 9 * i)))
    qtbot.waitUntil(lambda: not np.array_equal(win.viewport.nodes, before), timeout=2000)
    QTest.keyClick(vp, Qt.Key.Key_Escape)
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (60, 45))
    )
    wait_idle(qtbot, win)
    assert win.undo_stack.count() == count
    assert np.array_equal(win.state.nodes, before)
    assert np.array_equal(win.viewport.nodes, before)


def test_live_drag_solves_while_the_mouse_moves(qtbot, window):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    win.action_set.live.setChecked(True)
    assert win.panel.live_box.isChecked()
    vp = win.viewport
    row = pickable_node(win, want_free=True)
    gen0 = win.worker.generation
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    for i in range(1, 13):
        QTest.mouseMove(vp, point(start + (6 * i, -4 * i)))
        qtbot.wait(60)
    during = win.worker.generation - gen0
    assert during >= 2, "the preview solve restarts as the mouse moves"
    assert win.undo_stack.count() == 0
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (72, -48))
    )
    assert win.undo_stack.count() == 1
    wait_idle(qtbot, win)
    assert win.state.solved and win.state.converged and win.state.moved[row]


def test_preserve_off_is_plain_ffd(qtbot, window):
    win = window
    solved = np.array(win.state.nodes)
    win.action_set.preserve.setChecked(False)
    assert not win.panel.preserve_box.isChecked()
    wait_idle(qtbot, win)
    rest = win.state.lattice.rest_nodes
    fixed = win.state.fixed
    shown = win.viewport.nodes
    assert np.allclose(shown[~fixed], rest[~fixed]) and np.allclose(shown[fixed], solved[fixed])
    vol_plain = win.viewport.model_volume / win.state.surface.rest_volume
    assert vol_plain < 0.9, "the squashed torus loses volume without the constraint"

    row = pickable_node(win, want_free=True)
    drag(qtbot, win, row, offset=(40, -30))
    assert not win.is_solving(), "no solve with the constraint off"
    assert win.state.moved[row] and not win.state.solved
    win.action_set.preserve.setChecked(True)
    assert win.is_solving(), "turning the constraint on solves the edit"
    wait_idle(qtbot, win)
    assert win.state.solved and win.state.converged


def test_target_volume_and_lattice_rebuild_are_undoable(qtbot, window):
    win = window
    nodes0 = np.array(win.state.nodes)
    win.panel.target.setValue(80.0)
    assert win.state.goal.target_ratio == pytest.approx(0.8)
    wait_idle(qtbot, win)
    assert win.state.converged
    assert win.viewport.model_volume / win.state.surface.rest_volume == pytest.approx(0.8, abs=1e-3)
    assert "target 80 %" in win.readout.volume_label.text()

    cell_before_rebuild = win.doc.cell
    for spin, n in zip(win.panel.shape, (4, 3, 2)):
        spin.setValue(n)
    win.panel.rebuild.click()
    assert win.state.lattice.shape == (4, 3, 2)
    assert len(win.viewport.nodes) == 24
    assert not win.state.fixed.any()
    wait_idle(qtbot, win)
    assert win.state.goal.target_ratio == pytest.approx(0.8)
    assert win.viewport.model_volume / win.state.surface.rest_volume == pytest.approx(0.8, abs=1e-3)

    win.undo_stack.undo()  # the rebuild
    assert win.doc.cell is cell_before_rebuild
    assert win.state.lattice.shape == (3, 3, 3) and len(win.viewport.nodes) == 27
    assert [s.value() for s in win.panel.shape] == [3, 3, 3]
    win.undo_stack.undo()  # the target
    assert win.state.goal.target_ratio == 1.0 and np.array_equal(win.state.nodes, nodes0)
    assert win.panel.target.value() == 100.0
    win.undo_stack.redo()
    win.undo_stack.redo()
    assert win.state.lattice.shape == (4, 3, 2)


def test_save_reopen_and_export(qtbot, window, tmp_path):
    from isochor.core.scenario.document import Scenario

    win = window
    row = pickable_node(win, want_free=True)
    drag(qtbot, win, row)
    wait_idle(qtbot, win)
    assert "*" in win.windowTitle()
    path = tmp_path / "edit.json"
    assert win.files.save_to(path)
    assert "*" not in win.windowTitle() and win.undo_stack.isClean()
    sc = Scenario.read(path)
    assert len(sc.moves) == 19  # the example's 18 and the dragged node
    assert sc.model == {"builtin": "torus"}

    out = tmp_path / "deformed.ply"
    pytest.importorskip("isochor.core.io.meshio")
    from isochor.core.io.meshio import load_mesh
    from isochor.core.volume import signed_volume

    assert win.files.export(out)
    mesh = load_mesh(out).mesh
    assert mesh.n_faces == win.state.surface.full.n_faces
    v = signed_volume(mesh.vertices, mesh.faces)
    assert v / win.state.surface.rest_volume == pytest.approx(1.0, abs=1e-3)

    nodes = np.array(win.state.nodes)
    assert win.files.open_path(path)
    assert win.undo_stack.count() == 0 and win.doc.path == path.resolve()
    assert np.allclose(win.state.nodes[win.state.moved], nodes[win.state.moved])
    wait_idle(qtbot, win)
    assert win.state.converged


def test_unsaved_changes_prompt_on_close(qtbot, window, monkeypatch):
    from PySide6.QtWidgets import QMessageBox

    win = window
    win.set_pins([0], True)
    assert not win.undo_stack.isClean()
    answers = [QMessageBox.StandardButton.Cancel]
    asked = []

    def question(*args, **kwargs):
        asked.append(args[1] if len(args) > 1 else "")
        return answers.pop(0)

    monkeypatch.setattr(QMessageBox, "question", staticmethod(question))
    win.close()
    assert asked and win.isVisible(), "Cancel keeps the window"
    answers.append(QMessageBox.StandardButton.Discard)
    win.close()
    assert len(asked) == 2 and not win.isVisible()


def test_a_solver_failure_shows_the_message_and_keeps_the_edit(qtbot, window, monkeypatch):
    from PySide6.QtWidgets import QMessageBox

    import isochor.core.solve.multilevel
    from isochor.core.errors import IsochorError

    win = window
    shown = []
    monkeypatch.setattr(
        QMessageBox,
        "critical",
        staticmethod(lambda parent, title, text, *a, **k: shown.append(text)),
    )

    def broken(*args, **kwargs):
        raise IsochorError("The free nodes cannot change the model's volume.")
        yield  # pragma: no cover

    monkeypatch.setattr(isochor.core.solve.multilevel, "solve", broken)  # Problem.solve's
    row = pickable_node(win, want_free=True)
    drag(qtbot, win, row)
    edit = np.array(win.state.nodes)
    wait_idle(qtbot, win)
    assert shown == ["The free nodes cannot change the model's volume."]
    assert np.array_equal(win.state.nodes, edit) and win.state.moved[row]
    assert not win.state.converged
    assert win.undo_stack.count() == 1


def test_shortcut_keys_reach_the_actions(qtbot, window):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    win.activateWindow()
    qtbot.waitUntil(lambda: win.isActiveWindow(), timeout=2000)
    row = pickable_node(win, want_free=True)
    click(win, row)
    QTest.keyClick(win.viewport, Qt.Key.Key_P)
    assert win.state.pinned[row], "P pins the selection"
    wait_idle(qtbot, win)
    QTest.keyClick(win.viewport, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    assert not win.state.pinned[row], "Ctrl+Z undoes"
    QTest.keyClick(
        win.viewport,
        Qt.Key.Key_Z,
        Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier,
    )
    assert win.state.pinned[row], "Ctrl+Shift+Z redoes"
    # typing digits in a number field is typing, not the "7: top view" shortcut
    win.panel.target.setFocus()
    win.panel.target.lineEdit().selectAll()
    QTest.keyClicks(win.panel.target, "70")
    QTest.keyClick(win.panel.target, Qt.Key.Key_Return)
    assert win.state.goal.target_ratio == pytest.approx(0.7)


def test_context_menu_pins_the_node_under_the_cursor(qtbot, window, monkeypatch):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    row = pickable_node(win, want_free=True)
    offered = []

    def run_first(menu, *args, **kwargs):
        actions = [a for a in menu.actions() if not a.isSeparator()]
        offered.extend(a.text() for a in actions)
        actions[0].trigger()

    monkeypatch.setattr(win, "exec_menu", run_first)  # instead of the blocking popup
    QTest.mouseClick(
        win.viewport,
        Qt.MouseButton.RightButton,
        Qt.KeyboardModifier.NoModifier,
        point(screen_positions(win)[0][row]),
    )
    assert offered and offered[0] == "Pin 1 node"
    assert list(win.viewport.selection) == [row]
    assert win.state.pinned[row]
    assert win.undo_stack.undoText() == "Pin 1 node"


def test_dragging_one_of_several_selected_nodes_moves_them_all(qtbot, window):
    from PySide6.QtCore import Qt

    win = window
    a = pickable_node(win, want_free=True)
    b = pickable_node(win, want_free=True, exclude={a})
    click(win, a)
    click(win, b, Qt.KeyboardModifier.ShiftModifier)
    before = np.array(win.state.nodes)
    drag(qtbot, win, a, offset=(30, 40))
    start = win.session.last_solve_input[0]
    da, db = start[a] - before[a], start[b] - before[b]
    assert np.abs(da).max() > 1e-3 and np.allclose(da, db)
    assert win.state.moved[a] and win.state.moved[b]
    assert win.undo_stack.undoText() == "Move 2 nodes"
    wait_idle(qtbot, win)
    assert win.state.converged, "the two-node move solves"
    assert np.array_equal(win.state.nodes[[a, b]], start[[a, b]]), "both stay where dropped"


def test_isochor_edit_screenshot_from_the_command_line(tmp_path):

    from PySide6.QtGui import QImage

    from isochor.core.scenario.examples import example_scenario
    from tests.gui.conftest import distinct_colours, run_cli

    scenario = tmp_path / "stretch.json"
    example_scenario("torus-stretch").write(scenario)
    out = tmp_path / "shot.png"
    proc, _ = run_cli(["edit", str(scenario), "--screenshot", str(out)], timeout=300)
    assert proc.returncode == 0, proc.stderr
    img = QImage(str(out))
    assert not img.isNull() and distinct_colours(img) > 100

    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    proc, _ = run_cli(["edit", str(bad), "--screenshot", str(out)], timeout=300)
    assert proc.returncode == 1
    assert proc.stderr.count("\n") == 1 and "not valid JSON" in proc.stderr
