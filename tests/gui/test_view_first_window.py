"""The view first and the smaller defects (issue 29 items 6 and 8), with real events: at
1280x720 the 3D view has two thirds of the window; the convergence plot is a tab behind the
Inspector, the timeline appears with the first key; docks can be hidden and the layout comes
back at the next start. The plane lock draws a guide; no solver figures of the last solve
stay on screen during a drag; a scale that moves nothing is no edit; the Inspector keeps
its scroll position when the selection changes.
"""

from __future__ import annotations

import numpy as np

from tests.gui.conftest import open_window, save_shot, wait_idle
from tests.gui.test_editor import click, drag, pickable_node, point, screen_positions
from tests.gui.test_tools_window import hover, layer_x, points_of, press_keys


def view_share(win) -> float:
    vp = win.viewport
    return vp.width() * vp.height() / (win.width() * win.height())


def test_the_view_has_two_thirds_of_a_1280x720_window_and_the_layout_is_kept(qtbot, themed_app):
    from PySide6.QtCore import Qt

    win = open_window(qtbot, size=(1280, 720))
    wait_idle(qtbot, win)
    qtbot.waitUntil(lambda: (win.width(), win.height()) == (1280, 720), timeout=2000)
    share = view_share(win)
    print(f"the view has {share:.1%} of the window")
    assert share >= 2 / 3
    assert win.tabifiedDockWidgets(win.inspector_dock) == [win.plot_dock]
    assert not win.inspector_dock.visibleRegion().isEmpty(), "the Inspector tab is in front"
    assert not win.timeline_dock.isVisible(), "no keys: no timeline yet"
    save_shot(win, "view_first_1280x720")
    # the first key shows the timeline
    from PySide6.QtTest import QTest

    from tests.gui.test_goal_window import activate

    activate(qtbot, win)
    QTest.keyClick(win.viewport, Qt.Key.Key_I)
    assert win.state.timeline.keys and win.timeline_dock.isVisible()
    save_shot(win, "view_first_keyed")
    # hide the Inspector from the View menu; the next start has the same layout
    win.inspector_dock.toggleViewAction().trigger()
    assert not win.inspector_dock.isVisible()
    win.undo_stack.setClean()
    win.close()
    again = open_window(qtbot, size=(1280, 720))
    wait_idle(qtbot, again)
    assert not again.inspector_dock.isVisible() and again.timeline_dock.isVisible()
    assert again.plot_dock.isVisible() or again.tabifiedDockWidgets(again.plot_dock)
    again.undo_stack.setClean()
    again.close()


def test_the_plane_lock_draws_the_planes_two_axes(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from isochor.app.view import style
    from tests.gui.test_goal_window import rgb

    win = sphere
    vp = win.viewport
    rows = layer_x(win)
    centre = np.array(win.state.nodes)[rows].mean(axis=0)
    hover(win, (vp.width() * 0.7, vp.height() * 0.3))
    press_keys(vp, "g")
    QTest.keyClick(vp, Qt.Key.Key_Z, Qt.KeyboardModifier.ShiftModifier)  # across z
    assert "across z" in win.statusBar().currentMessage()
    guide = vp.scene.actors["guide"]
    assert guide.GetVisibility()
    assert np.allclose(guide.GetProperty().GetColor(), rgb(style.GUIDE) / 255, atol=1e-6)
    ends = points_of(win, "guide")
    assert len(ends) == 4 and np.allclose(ends[:, 2], centre[2])  # in the plane
    u, v = ends[1] - ends[0], ends[3] - ends[2]
    assert abs(u[1]) < 1e-12 and abs(v[0]) < 1e-12 and u[0] > 0 and v[1] > 0  # along x, y
    save_shot(win, "plane_lock_guide")
    press_keys(vp, "\x1b")
    assert not guide.GetVisibility()


def test_no_figures_of_the_last_solve_stay_during_a_drag(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    vp = win.viewport
    labels = (win.readout.level_label, win.readout.solver_label, win.readout.time_label)
    row = pickable_node(win)
    drag(qtbot, win, row, offset=(-30, 20))
    wait_idle(qtbot, win)
    assert all(w.text() for w in labels), "the solved state's figures"
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    for i in range(1, 5):
        QTest.mouseMove(vp, point(start + np.array([40, -30]) * i / 4))
        qtbot.wait(5)
    assert win.doc.drag is not None and not win.is_solving()
    assert [w.text() for w in labels] == ["", "", ""], "nothing of the solve before the drag"
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (40, -30))
    )
    wait_idle(qtbot, win)
    assert win.state.converged and all(w.text() for w in labels), "the new result's figures"


def test_a_scale_that_moves_nothing_is_no_edit(qtbot, sphere):
    win = sphere
    vp = win.viewport
    row = pickable_node(win)
    click(win, row)
    before = win.state
    hover(win, (vp.width() * 0.7, vp.height() * 0.3))
    press_keys(vp, "s2\n")  # one node scaled about itself: it stays where it is
    assert win.undo_stack.count() == 0 and win.state is before
    assert not win.state.fixed[row], "nothing fixed"
    press_keys(vp, "r30\n")  # nor does a turn of one node about itself
    assert win.undo_stack.count() == 0 and not win.state.fixed[row]
    layer_x(win)
    press_keys(vp, "s1\n")  # a layer scaled by 1
    assert win.undo_stack.count() == 0 and not win.state.moved.any()
    press_keys(vp, "s2\n")  # ... by 2 is an edit
    assert win.undo_stack.count() == 1 and win.undo_stack.undoText() == "Scale 9 nodes"
    wait_idle(qtbot, win)


def test_the_inspector_keeps_its_scroll_position_when_the_selection_changes(qtbot, sphere):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = sphere
    win.resize(1280, 720)
    bar = win.inspector_scroll.verticalScrollBar()
    qtbot.waitUntil(lambda: bar.maximum() > 0, timeout=2000)
    bar.setValue(bar.maximum() // 2)
    keep = bar.value()
    rows = [pickable_node(win)]
    rows.append(pickable_node(win, exclude=rows))
    for r in rows:
        click(win, r)
        qtbot.wait(20)
        assert list(win.doc.selection.rows) == [r]
        assert bar.value() == keep
    QTest.mouseClick(
        win.viewport, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point((6, 60))
    )
    qtbot.wait(20)
    assert len(win.doc.selection.rows) == 0 and bar.value() == keep
    save_shot(win, "inspector_scroll_kept")
