"""The window bugs found when the editor was tried as an artist would, each with its test:
screenshots that hung, statistics of another state left on screen, a stale status, poor
framing, the lattice capped at 8, a traceback on Discard, the wheel editing a field."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from tests.gui.conftest import open_window, run_cli, wait_idle


def _sphere_obj(path, stretch=(1.0, 1.0, 1.0)):
    from isochor.core.io.meshio import save_mesh
    from isochor.core.mesh import TriMesh
    from isochor.core.scenario.shapes import sphere_levels

    m = sphere_levels(4)[-1]
    save_mesh(path, TriMesh(m.vertices * np.asarray(stretch), m.faces))
    return path


def test_screenshot_of_a_model_and_of_a_scenario_at_rest_exits(tmp_path):
    """Both used to hang forever: nothing to solve, so no solve ever 'ended'."""
    from isochor.core.scenario.document import Scenario

    model = _sphere_obj(tmp_path / "ball.obj", stretch=(2.0, 1.0, 1.0))
    at_rest = tmp_path / "rest.json"
    Scenario.from_dict(
        {"model": {"path": "ball.obj"}, "lattice": {"nodes": [3, 3, 3]}}, tmp_path
    ).write(at_rest)
    for source in (model, at_rest):
        out = tmp_path / f"{source.stem}.png"
        proc, seconds = run_cli(["edit", str(source), "--screenshot", str(out)])
        assert proc.returncode == 0, proc.stderr
        assert out.stat().st_size > 10_000
        assert seconds < 60, f"{source.name}: {seconds:.1f} s"
        assert "Traceback" not in proc.stderr


def test_screenshot_timeout_takes_the_picture_and_says_so(tmp_path):
    out = tmp_path / "late.png"
    proc, _ = run_cli(
        ["edit", str(_sphere_obj(tmp_path / "b.obj")), "--screenshot", str(out), "--timeout", "0"]
    )
    # the model is at rest, so idle and the zero timeout race: either is a clean exit
    assert proc.returncode in (0, 1) and out.exists()
    assert proc.stderr.count("\n") <= 1 and "Traceback" not in proc.stderr


def test_a_screenshot_never_replaces_what_it_shows(tmp_path):
    """``--screenshot`` is an output like ``solve --out``: refused, before the window
    opens, when it names the scenario, the model or a folder; a link writes its target."""
    from isochor.core.scenario.document import Scenario

    _sphere_obj(tmp_path / "ball.obj")
    scene = tmp_path / "scene.json"
    Scenario.from_dict({"model": {"path": "ball.obj"}}, tmp_path).write(scene)
    before = {p.name: p.read_bytes() for p in (scene, tmp_path / "ball.obj")}
    for source, out, words in (
        (scene, scene, "would overwrite the file it shows"),
        (scene, tmp_path / "ball.obj", "would overwrite the model"),
        (tmp_path / "ball.obj", tmp_path / "ball.obj", "would overwrite the file it shows"),
        (scene, tmp_path, "is a folder"),
    ):
        proc, _ = run_cli(["edit", str(source), "--screenshot", str(out)])
        assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
        assert words in proc.stderr
    assert {p.name: p.read_bytes() for p in (scene, tmp_path / "ball.obj")} == before
    os.symlink("shots/real.png", tmp_path / "link.png")
    (tmp_path / "shots").mkdir()
    proc, _ = run_cli(["edit", str(scene), "--screenshot", str(tmp_path / "link.png")])
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "link.png").is_symlink()
    assert (tmp_path / "shots" / "real.png").read_bytes().startswith(b"\x89PNG")
    assert sorted(p.name for p in (tmp_path / "shots").iterdir()) == ["real.png"]


def _labels(win):
    return (
        win.readout.level_label.text(),
        win.readout.solver_label.text(),
        win.panel.solve_state.text(),
    )


def test_a_result_summary_stays_with_the_state_it_solved(qtbot, window, tmp_path):
    win = window
    assert win.state.result is not None and win.state.result.converged
    level, solver, panel = _labels(win)
    assert level.startswith("Solved") and "full mesh" in solver and "Converged" in panel

    # rebuild: the new lattice is at rest; no statistics of the example's solve remain
    win.rebuild_lattice((2, 2, 2))
    wait_idle(qtbot, win)
    level, solver, panel = _labels(win)
    assert (level, solver) == ("", "") and "At rest" in panel
    assert "free nodes" not in panel

    # undo: back on the solved example, its own statistics come back with it
    win.undo_stack.undo()
    wait_idle(qtbot, win)
    assert _labels(win)[0].startswith("Solved")

    # preserve off: plain FFD, no solver statistics
    win.action_set.preserve.setChecked(False)
    level, solver, panel = _labels(win)
    assert (level, solver) == ("", "") and "plain free-form" in panel
    assert win.readout.state_label.text().endswith("Plain FFD")
    win.action_set.preserve.setChecked(True)
    wait_idle(qtbot, win)

    # open another document: its own (at rest) state, nothing of the example
    assert win.files.open_path(_sphere_obj(tmp_path / "egg.obj", (1.0, 1.5, 1.0)))
    wait_idle(qtbot, win)
    level, solver, panel = _labels(win)
    assert (level, solver) == ("", "") and "At rest" in panel
    assert win.panel.sel_title.text() == "No node selected"


def test_status_says_solving_stopped_and_dragging(qtbot, window):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from tests.gui.test_editor import pickable_node, point, screen_positions

    win = window
    seen = []
    win.session.statusChanged.connect(lambda: seen.append(win.session.status()[0]))
    win.doc.selection.select([pickable_node(win)])
    win.type_position(0, float(win.viewport.nodes[win.doc.selection.rows[0], 0]) + 0.2)
    assert win.is_solving()
    assert (
        win.readout.state_label.text().endswith("Solving…")
        and "Solving" in win.panel.solve_state.text()
    )
    win.action_set.stop.trigger()
    assert not win.is_solving()
    assert win.readout.state_label.text().endswith("Stopped"), win.readout.state_label.text()
    assert "Converged" not in win.panel.solve_state.text()
    wait_idle(qtbot, win)

    row = pickable_node(win)
    start = screen_positions(win)[0][row]
    QTest.mousePress(
        win.viewport, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start)
    )
    QTest.mouseMove(win.viewport, point(start + np.array([25, -15])))
    qtbot.wait(20)
    assert win.readout.state_label.text().endswith("Dragging"), (
        "the chip changes when a drag starts"
    )
    QTest.mouseRelease(
        win.viewport,
        Qt.MouseButton.LeftButton,
        Qt.KeyboardModifier.NoModifier,
        point(start + np.array([25, -15])),
    )
    assert win.readout.state_label.text().endswith("Solving…")
    wait_idle(qtbot, win)
    assert win.readout.state_label.text().endswith("Converged")
    assert {"Solving…", "Stopped", "Dragging", "Converged"} <= set(seen)


def test_a_model_opened_from_a_file_fills_the_view(qtbot, themed_app, tmp_path):
    from isochor.app.editor.document import Document

    doc = Document.open(_sphere_obj(tmp_path / "long.obj", (3.0, 1.0, 1.0)))
    win = open_window(qtbot, doc, size=(1200, 800))
    wait_idle(qtbot, win)
    vp = win.viewport
    lo, hi = vp.scene.bounds()
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    xy, _, visible = vp.camera_control.projection().project(corners)
    assert visible.all()
    span = (xy.max(axis=0) - xy.min(axis=0)) / np.array([vp.width(), vp.height()])
    assert span.max() > 0.5, f"the model spans only {span} of the view"
    assert (xy >= -1).all() and (xy[:, 0] <= vp.width() + 1).all()


def test_the_lattice_panel_offers_ten_nodes_per_axis(qtbot, window):
    win = window
    for box in win.panel.shape:
        assert box.maximum() == 10
        box.setValue(10)
    win.panel.rebuild.click()
    assert win.state.lattice.shape == (10, 10, 10)
    assert win.undo_stack.undoText() == "Rebuild lattice 10x10x10"


def test_the_wheel_over_a_field_does_not_edit_the_document(qtbot, window):
    from PySide6.QtCore import QPoint, QPointF, Qt
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtWidgets import QApplication

    win = window
    win.activateWindow()
    qtbot.waitUntil(win.isActiveWindow, timeout=2000)
    target = win.panel.target
    win.viewport.setFocus()
    assert not target.hasFocus()
    before, steps = target.value(), win.undo_stack.count()
    centre = QPointF(target.width() / 2, target.height() / 2)
    wheel = QWheelEvent(
        centre,
        QPointF(target.mapToGlobal(centre.toPoint())),
        QPoint(0, 0),
        QPoint(0, 120),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.NoModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(target, wheel)
    assert target.value() == before and win.undo_stack.count() == steps
    assert not win.is_solving()
    target.setFocus()  # after a click into the field the wheel edits it, as it should
    qtbot.waitUntil(target.hasFocus, timeout=2000)
    QApplication.sendEvent(target, wheel)
    assert target.value() != before


def test_quitting_with_discard_prints_no_traceback(tmp_path):
    code = """
import sys
from PySide6.QtWidgets import QApplication, QMessageBox
app = QApplication([])
from isochor.app.window.mainwindow import MainWindow
win = MainWindow()
win.show()
for _ in range(20):
    app.processEvents()
win.set_pins([0], True)
QMessageBox.question = staticmethod(lambda *a, **k: QMessageBox.StandardButton.Discard)
win.action_set.quit.trigger()
for _ in range(20):
    app.processEvents()
print("closed", win.isVisible())
del win
app.quit()
"""
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ),
    )
    assert proc.returncode == 0, proc.stderr
    assert "closed False" in proc.stdout
    assert "Traceback" not in proc.stderr and "deleted" not in proc.stderr, proc.stderr


@pytest.mark.parametrize("name", ["torus-compression", "club-bend"])
def test_open_example_opens_the_shipped_scenario_as_a_new_document(qtbot, window, name):
    from isochor import assets

    win = window
    assert win.files.open_example(assets.example_files()[name])
    assert win.doc.path is None, "Save asks where: the example is a template"
    assert win.doc.title == f"{name}.json"
    wait_idle(qtbot, win)
    assert win.state.converged and win.state.moved.any()
