"""The lattice box's basis choice (issue 26): Blender's B-spline lattice in the editor."""

from __future__ import annotations

import numpy as np

from tests.gui.conftest import wait_idle
from tests.gui.test_editor import drag, pickable_node
from tests.gui.test_goal_window import click_box


def test_the_lattice_box_rebuilds_a_bspline_lattice_and_a_drag_keeps_the_volume(qtbot, window):
    win = window
    panel = win.panel
    assert panel.basis_name() == "bernstein"
    assert panel.shape[0].maximum() == 10
    panel.basis.setCurrentIndex(panel.basis.findData("bspline"))
    assert panel.shape[0].maximum() == 64 and panel.shape[0].minimum() == 1
    for spin, n in zip(panel.shape, (4, 3, 5)):
        spin.setValue(n)
    panel.rebuild.click()
    lattice = win.state.lattice
    assert lattice.shape == (4, 3, 5) and lattice.basis == ("bspline",) * 3
    assert len(win.viewport.nodes) == 60
    assert "B-spline" in win.undo_stack.undoText() or "bspline" in win.undo_stack.undoText()
    wait_idle(qtbot, win)
    row = pickable_node(win, want_free=True)
    drag(qtbot, win, row, offset=(25, -15))
    wait_idle(qtbot, win)
    assert win.state.converged
    ratio = win.viewport.model_volume / win.state.surface.rest_volume
    assert abs(ratio - 1.0) < 2e-3
    assert not np.allclose(win.state.nodes, lattice.rest_nodes)
    win.grab().save("/tmp/isochor_bspline_window.png")

    win.undo_stack.undo()  # the drag
    win.undo_stack.undo()  # the rebuild
    assert win.state.lattice.basis == ("bernstein",) * 3
    assert panel.basis_name() == "bernstein" and panel.shape[0].maximum() == 10


def test_the_outside_option_is_offered_for_a_local_basis_and_rebuilds_undoably(qtbot, window):
    from PySide6.QtCore import Qt

    win = window
    panel = win.panel
    box = panel.outside_box
    assert not box.isEnabled()  # Bernstein: no Outside option
    click_box(win, box)
    assert not box.isChecked() and not panel.outside()
    panel.basis.setCurrentIndex(panel.basis.findData("bspline"))
    assert box.isEnabled()
    click_box(win, box)
    assert box.isChecked() and panel.outside()
    for spin, n in zip(panel.shape, (4, 4, 4)):
        spin.setValue(n)
    win.inspector_scroll.ensureWidgetVisible(panel.rebuild)
    qtbot.mouseClick(panel.rebuild, Qt.MouseButton.LeftButton)
    assert win.state.lattice.outside and win.state.lattice.basis == ("bspline",) * 3
    assert "outside" in win.undo_stack.undoText()
    assert win.state.problem.scenario.to_dict()["lattice"]["outside"] is True
    # the same shape and basis with Outside turned off is a rebuild of its own
    click_box(win, box)
    win.inspector_scroll.ensureWidgetVisible(panel.rebuild)
    qtbot.mouseClick(panel.rebuild, Qt.MouseButton.LeftButton)
    assert not win.state.lattice.outside
    win.undo_stack.undo()
    assert win.state.lattice.outside and box.isChecked()
    win.undo_stack.undo()
    assert not win.state.lattice.outside and not box.isChecked() and not box.isEnabled()
