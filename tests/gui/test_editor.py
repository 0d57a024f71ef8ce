"""The editor window, driven like a user would: real mouse events on the viewport."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from tests.gui.conftest import distinct_colours, wait_idle


# -- helpers ------------------------------------------------------------------------------
def screen_positions(win):
    vp = win.viewport
    xy, _, visible = vp.camera_control.projection().project(vp.nodes)
    return xy, visible


def pickable_node(win, want_free=True, exclude=()):
    """A node well inside the view and clear of the others, so a click there picks it."""
    from isochor.app.view.picking import PICK_RADIUS

    vp = win.viewport
    xy, visible = screen_positions(win)
    st = win.state
    best, best_score = None, -1.0
    for r in range(len(xy)):
        if r in exclude or not visible[r] or bool(st.fixed[r]) == want_free:
            continue
        x, y = xy[r]
        margin = min(x, y, vp.width() - x, vp.height() - y)
        if margin < 80:
            continue
        others = np.delete(np.arange(len(xy)), r)
        clearance = np.hypot(*(xy[others] - xy[r]).T).min()
        if clearance < 0.75 * PICK_RADIUS:  # the nearest node wins a click
            continue
        score = clearance + 0.1 * margin
        if score > best_score:
            best, best_score = r, score
    assert best is not None, "no node can be picked cleanly in this view"
    return best


def point(xy):
    from PySide6.QtCore import QPoint

    return QPoint(int(round(xy[0])), int(round(xy[1])))


def drag(qtbot, win, row, offset=(70, -45), steps=8, modifier=None):
    """Press on node ``row``, move in ``steps`` steps by ``offset`` pixels, release."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    vp = win.viewport
    mod = modifier or Qt.KeyboardModifier.NoModifier
    start = screen_positions(win)[0][row]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, mod, point(start))
    for i in range(1, steps + 1):
        QTest.mouseMove(vp, point(start + np.array(offset) * i / steps))
        qtbot.wait(5)
    QTest.mouseRelease(vp, Qt.MouseButton.LeftButton, mod, point(start + np.array(offset)))


def draw_before_the_end(monkeypatch, win):
    """Each solve the worker starts waits, after its first progress record, until the
    window has drawn a frame of a record (at most 30 s): then a solve cannot end before an
    intermediate frame is drawn, whatever the machine's load does to the frame timer."""
    import threading

    from isochor.core.solve import multilevel

    drawn = threading.Event()
    win.session.frameReady.connect(lambda _nodes, record: record is None or drawn.set())
    solve = multilevel.solve

    def paced(*args, **kwargs):
        records = solve(*args, **kwargs)
        try:
            try:
                first = next(records)
            except StopIteration as stop:
                return stop.value
            drawn.clear()
            yield first
            drawn.wait(30)
            return (yield from records)
        finally:
            records.close()

    monkeypatch.setattr(multilevel, "solve", paced)  # what Problem.solve calls


def click(win, row, modifier=None):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    mod = modifier or Qt.KeyboardModifier.NoModifier
    QTest.mouseClick(
        win.viewport, Qt.MouseButton.LeftButton, mod, point(screen_positions(win)[0][row])
    )


# -- tests --------------------------------------------------------------------------------
def test_window_opens_on_the_default_example_and_renders(window):
    win = window
    assert win.state.problem.scenario.model == {"builtin": "torus"}
    assert win.state.solved and win.state.converged
    assert win.frames.redraws >= 1
    view = win.viewport.grabFramebuffer()
    assert view.width() > 100 and view.height() > 100
    assert distinct_colours(view) > 50  # shaded model, coloured nodes, gradient
    whole = win.grab().toImage()
    assert distinct_colours(whole) > 50


def test_the_view_draws_the_models_own_triangles_in_its_draw_order(window):
    """The drawn polydata holds exactly the model's triangles, each once, only reordered
    for the renderer; picking and shading keep the mesh's own order."""
    model = window.viewport.scene.model
    drawn = np.asarray(model.full.poly.faces).reshape(-1, 4)
    assert np.all(drawn[:, 0] == 3)
    own = np.asarray(model.faces())
    assert len(drawn) == len(own) == window.state.surface.full.n_faces
    assert not np.array_equal(drawn[:, 1:], own)  # reordered (the torus is made in rings)
    assert np.array_equal(np.sort(drawn[:, 1:], axis=0), np.sort(own, axis=0))
    as_rows = {tuple(f) for f in drawn[:, 1:]}
    assert as_rows == {tuple(f) for f in own}  # the same triangles, same corner order


def test_screenshot_option_writes_a_non_blank_png(themed_app, tmp_path):
    from PySide6.QtGui import QImage

    from isochor.app.cli.launch import run_editor

    out = tmp_path / "shot.png"
    assert run_editor(None, str(out)) == 0
    img = QImage(str(out))
    assert not img.isNull() and img.width() >= 800 and img.height() >= 500
    assert distinct_colours(img) > 100


def test_no_display_prints_one_line_and_exits_non_zero(monkeypatch, capsys):
    import sys

    from isochor.app.cli.launch import run_editor

    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code = run_editor(None, None)
    err = capsys.readouterr().err
    assert code != 0
    assert len(err.strip().splitlines()) == 1
    assert "isochor solve" in err


def test_drag_moves_node_solves_progressively_and_undoes(qtbot, window, monkeypatch):
    win = window
    draw_before_the_end(monkeypatch, win)
    row = pickable_node(win, want_free=True)
    before = np.array(win.state.nodes)
    before_fixed = win.state.fixed.copy()
    redraws0 = win.frames.redraws

    drag(qtbot, win, row)
    assert win.is_solving(), "releasing a drag starts a solve"
    gen = win.worker.generation
    start_nodes = win.session.last_solve_input[0]
    assert not np.allclose(start_nodes[row], before[row]), "the dragged node moved"
    assert win.state.moved[row]
    wait_idle(qtbot, win)

    after = np.array(win.state.nodes)
    # progressive: at least one intermediate record drawn during the solve, then the end
    assert win.session.frames_by_generation.get(gen, 0) >= 1, "no intermediate frame drawn"
    assert win.frames.redraws - redraws0 >= 3, "the drag, an intermediate and the final frame"
    assert np.array_equal(after[row], start_nodes[row]), "a moved node is fixed"
    moved_free = np.abs(after - before).max(axis=1)[~before_fixed]
    assert moved_free.max() > 1e-4, "the free nodes followed"
    res = win.session.last_result
    assert res.converged
    assert abs(res.rel_volume_error) <= win.state.problem.scenario.tol_volume
    assert win.undo_stack.count() == 1

    win.undo_stack.undo()
    assert not win.is_solving(), "the state before the drag was already solved"
    assert np.array_equal(win.state.nodes, before)
    assert np.array_equal(win.state.fixed, before_fixed)
    wait_idle(qtbot, win)
    assert np.array_equal(win.viewport.nodes, before), "the view shows the undone state"

    win.undo_stack.redo()
    assert np.array_equal(win.state.nodes, after)
    assert win.state.moved[row]
    wait_idle(qtbot, win)
    assert np.array_equal(win.viewport.nodes, after)


def test_pin_and_unpin_change_what_the_solver_moves(qtbot, window):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    win = window
    a = pickable_node(win, want_free=True)
    click(win, a)
    assert list(win.viewport.selection) == [a]
    win.activateWindow()
    qtbot.waitUntil(lambda: win.isActiveWindow(), timeout=2000)
    QTest.keyClick(win.viewport, Qt.Key.Key_P)
    assert win.state.pinned[a] and win.state.fixed[a], "the P key pins the selection"
    wait_idle(qtbot, win)
    pinned_at = np.array(win.state.nodes[a])

    seen = []
    win.worker.progress.connect(lambda g, rec: seen.append((g, np.array(rec.nodes[a]))))
    b = pickable_node(win, want_free=True, exclude={a})
    drag(qtbot, win, b, offset=(-60, 50))
    gen = win.worker.generation
    wait_idle(qtbot, win)
    ours = [p for g, p in seen if g == gen]
    assert len(ours) >= 2
    assert all(np.array_equal(p, pinned_at) for p in ours), "a pinned node never moves"
    assert np.array_equal(win.state.nodes[a], pinned_at)

    # unpin through the panel check box (the same edit as P or the context menu)
    click(win, a)
    assert win.panel.pin_box.isChecked()
    win.panel.pin_box.click()
    assert not win.state.fixed[a]
    assert win.is_solving(), "a pin change starts a solve"
    wait_idle(qtbot, win)
    assert np.abs(win.state.nodes[a] - pinned_at).max() > 1e-6, "now the solver moves it"
    assert win.undo_stack.count() == 3  # pin, drag, unpin


def test_two_quick_drags_end_on_the_headless_solve_of_the_last(qtbot, window):
    from isochor.core.solve.generators import run_to_end
    from isochor.core.solve.multilevel import solve

    win = window
    r1 = pickable_node(win, want_free=True)
    r2 = pickable_node(win, want_free=True, exclude={r1})
    drag(qtbot, win, r1, offset=(50, -30), steps=4)
    g1 = win.worker.generation
    assert win.is_solving()
    drag(qtbot, win, r2, offset=(-40, 40), steps=4)
    g2 = win.worker.generation
    assert g2 > g1
    wait_idle(qtbot, win)

    log = list(win.session.accepted_log)
    first_g2 = next(i for i, (g, _) in enumerate(log) if g == g2)
    assert all(g != g1 for g, _ in log[first_g2:]), "nothing of drag 1 after drag 2"
    gens = [g for g, _ in log]
    assert gens == sorted(gens)
    assert log[-1] == (g2, "finished")

    nodes, fixed, goal = win.session.last_solve_input
    assert fixed.shape == (len(nodes), 3) and fixed[r1].all() and fixed[r2].all()
    assert goal == win.state.goal
    st = win.state
    headless = run_to_end(solve(st.surface, nodes, fixed, goal=goal, options=st.problem.options))
    assert np.allclose(win.state.nodes, headless.nodes, rtol=0, atol=1e-9 * st.surface.size)
    assert win.undo_stack.count() == 2


def test_opening_a_refused_model_shows_the_error_and_keeps_the_document(qtbot, window, monkeypatch):
    from PySide6.QtWidgets import QMessageBox

    from tests.gui.conftest import MODELS

    pytest.importorskip("isochor.core.io.meshio")
    soup = MODELS / "soup.stl"  # loose triangles: no solid to keep
    if not soup.exists():
        pytest.skip(f"{soup} is not there")
    win = window
    shown = []
    monkeypatch.setattr(
        QMessageBox,
        "critical",
        staticmethod(lambda parent, title, text, *a, **k: shown.append(text)),
    )
    doc, nodes = win.doc, np.array(win.state.nodes)
    assert win.files.open_path(soup) is False
    assert len(shown) == 1 and "soup" in shown[0].lower()
    assert "Error" not in shown[0].split(":")[0], "the core's message, not a traceback"
    assert win.doc is doc and np.array_equal(win.state.nodes, nodes)
    assert win.state.problem.scenario.model == {"builtin": "torus"}


def test_closing_mid_solve_of_the_armadillo_stops_the_solve(qtbot, themed_app, monkeypatch):
    """Closing the window while it solves stops the solve: its thread ends after the step
    it is in and emits nothing after the window has closed. (How long closing takes: the
    benchmark's window row "closing it while it solves".)"""
    from PySide6.QtCore import Qt

    from isochor.app.editor.document import Document
    from isochor.core.goal.constraints import Level
    from tests.gui.conftest import MODELS, open_window

    pytest.importorskip("isochor.core.io.meshio")
    path = MODELS / "armadillo_loop1_346k.ply"
    if not path.exists():
        pytest.skip(f"{path} is not there")
    win = open_window(qtbot, Document.open(path))
    assert win.state.surface.full.n_faces > 300_000
    wait_idle(qtbot, win)
    # the solver's thread is held in its first evaluation until the window has closed:
    # the first solve of this model can end in about 60 ms, before a test could close on it
    started, release = threading.Event(), threading.Event()
    evaluate = Level.volume_and_gradient

    def held(level, nodes):
        if threading.current_thread() is not threading.main_thread() and not started.is_set():
            started.set()
            release.wait(30)
        return evaluate(level, nodes)

    monkeypatch.setattr(Level, "volume_and_gradient", held)
    win.doc.selection.select([0])
    node = np.array(win.state.nodes[0])
    win.type_position(0, node[0] - 0.3 * win.state.surface.size)
    assert win.is_solving()
    qtbot.waitUntil(started.is_set, timeout=60_000)
    assert win.is_solving(), "still solving when the window closes"
    win.undo_stack.setClean()
    closed, after_close = [], []

    def emitted(*args):  # called on the solver's thread, as it emits
        if closed:
            after_close.append(args)

    for signal in (win.worker.progress, win.worker.finished, win.worker.failed):
        signal.connect(emitted, Qt.ConnectionType.DirectConnection)
    accepted = len(win.session.accepted_log)
    win.close()
    closed.append(True)
    release.set()
    assert win.worker.shutdown(timeout=60), "the solver's thread runs on after the close"
    qtbot.wait(300)  # what it queued before the close reaches the closed window now
    assert not after_close, f"the stopped solve emitted {len(after_close)} time(s) after closing"
    assert len(win.session.accepted_log) == accepted, "the closed window took a record"
