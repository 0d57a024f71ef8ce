"""Big models stay responsive (issues 27 and 29): a big model's lattice is rebuilt on a thread
while the window answers, a model opened in the background arrives with the view's arrays
computed on the loading thread, closed models are drawn without their back faces (the same
picture), a moving camera draws the proxy and the full mesh comes back after a pause (drawn
in passes, the same pixels; a press between two passes cancels them), and the editor's
process ends as soon as its window has closed. Behaviour only: the times are
the benchmark's (benchmarks/window.py, benchmarks/opening.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import numpy as np
import pytest

from tests.gui.conftest import open_window, wait_idle


def _record_threads(monkeypatch):
    """Which threads computed the view's arrays (DisplayPrep.of)."""
    from isochor.app.view import meshprep

    seen: list[str] = []
    make = meshprep.DisplayPrep.of.__func__

    def of(cls, surface, nodes):
        seen.append(threading.current_thread().name)
        return make(cls, surface, nodes)

    monkeypatch.setattr(meshprep.DisplayPrep, "of", classmethod(of))
    return seen


@pytest.fixture
def held_rebuild(monkeypatch):
    """Every lattice rebuild runs on its thread (whatever the model's size) and waits there
    for ``release`` before it computes anything."""
    from isochor.app.window import rebuild

    release = threading.Event()
    prepare = rebuild.prepare_rebuild

    def held(base, shape, basis=None, outside=None):
        assert release.wait(30)
        return prepare(base, shape, basis, outside)

    monkeypatch.setattr(rebuild, "BACKGROUND_FACES", 0)
    monkeypatch.setattr(rebuild, "prepare_rebuild", held)
    yield release
    release.set()


def _click_rebuild(qtbot, win, shape) -> None:
    """Set the Inspector's node counts and press its Rebuild button, as a user does."""
    from PySide6.QtCore import Qt

    panel = win.panel
    for box, n in zip(panel.shape, shape, strict=True):
        box.setValue(n)
    win.inspector_scroll.ensureWidgetVisible(panel.rebuild)
    qtbot.mouseClick(panel.rebuild, Qt.MouseButton.LeftButton)


def test_a_big_lattice_rebuild_runs_on_a_thread_while_the_window_answers(
    qtbot, window, held_rebuild, monkeypatch
):
    win = window
    seen = _record_threads(monkeypatch)
    shape0 = tuple(win.state.lattice.shape)
    steps0 = win.undo_stack.count()
    _click_rebuild(qtbot, win, (4, 3, 3))
    rebuild = win.lattice_rebuild
    assert rebuild.busy() and rebuild.threads and rebuild.threads[-1].is_alive()
    # the window answers while the thread works: a timer ticks, the old lattice is drawn
    ticks = []
    from PySide6.QtCore import QTimer

    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(10)
    qtbot.waitUntil(lambda: len(ticks) >= 5, timeout=5_000)
    timer.stop()
    assert tuple(win.state.lattice.shape) == shape0 and win.undo_stack.count() == steps0
    assert "Rebuilding the lattice" in win.statusBar().currentMessage()
    held_rebuild.set()
    qtbot.waitUntil(lambda: tuple(win.state.lattice.shape) == (4, 3, 3), timeout=30_000)
    wait_idle(qtbot, win)
    assert win.undo_stack.count() == steps0 + 1  # one undo step, as before
    assert len(win.viewport.nodes) == 4 * 3 * 3  # the view draws the new lattice
    # the view's arrays were computed on the rebuild's thread, not again on the GUI thread
    assert seen and all(name.startswith("isochor-lattice-") for name in seen), seen
    win.undo_stack.undo()
    wait_idle(qtbot, win)
    assert tuple(win.state.lattice.shape) == shape0


def test_a_rebuild_overtaken_by_an_edit_is_dropped_and_closing_does_not_wait(
    qtbot, themed_app, held_rebuild
):
    from isochor.app.editor import goalrules

    win = open_window(qtbot)
    wait_idle(qtbot, win)
    shape0 = tuple(win.state.lattice.shape)
    win.rebuild_lattice((4, 4, 4))
    thread = win.lattice_rebuild.threads[-1]
    win.commit_edit(goalrules.edit_target(win.doc.base(), 90.0))  # an edit meanwhile
    wait_idle(qtbot, win)
    held_rebuild.set()
    qtbot.waitUntil(lambda: not thread.is_alive(), timeout=30_000)
    qtbot.wait(50)  # (its queued report)
    assert tuple(win.state.lattice.shape) == shape0, "the edit made meanwhile wins"
    assert "not rebuilt" in win.statusBar().currentMessage()

    held_rebuild.clear()
    win.rebuild_lattice((4, 4, 4))
    thread = win.lattice_rebuild.threads[-1]
    win.undo_stack.setClean()
    win.close()  # returns with the thread still held: it is not waited for
    assert thread.is_alive() and win.closed
    held_rebuild.set()
    thread.join(30)


def test_a_model_opened_in_the_background_brings_the_views_arrays(qtbot, window, monkeypatch):
    from isochor import assets

    win = window
    seen = _record_threads(monkeypatch)
    path = assets.model_files()["club"]
    assert win.files.open_path(path, background=True)
    qtbot.waitUntil(
        lambda: not win.files.loading() and "club" in win.doc.title.lower(), timeout=60_000
    )
    wait_idle(qtbot, win)
    assert seen == [seen[0]] and seen[0].startswith("isochor-open-"), seen
    assert win.viewport.scene.model.full.n_faces == win.state.surface.full.n_faces


def test_a_closed_model_is_culled_and_looks_the_same(qtbot, window):
    """The example's torus is closed: its back faces are culled, and the picture from
    outside is the same pixel for pixel with and without culling."""
    win = window
    vp = win.viewport
    model = vp.scene.model
    assert model.full.closed and model.cull
    assert model.full.actor.GetProperty().GetBackfaceCulling()

    def picture() -> np.ndarray:
        vp.render()
        return np.asarray(vp.screenshot(return_img=True)).copy()

    culled = picture()
    model.set_culling(False)
    assert not model.full.actor.GetProperty().GetBackfaceCulling()
    drawn = picture()
    model.set_culling(True)
    assert culled.shape == drawn.shape
    # the same picture but for the silhouette: a back face seen edge-on there may cover a
    # pixel's sample point that no front face covers (rasterisation, not shading); such
    # pixels lie on the outline, a few among the model's hundred thousand
    differ = np.abs(culled.astype(int) - drawn.astype(int)).max(axis=2) > 1
    model_pixels = (np.abs(drawn.astype(int) - drawn[0, 0].astype(int)).max(axis=2) > 1).sum()
    assert differ.sum() <= 1e-4 * model_pixels + 2, (differ.sum(), model_pixels)


@pytest.fixture
def big_torus(qtbot, themed_app, tmp_path):
    """The window on a torus of 65536 triangles (a model with a proxy), made at run time."""
    import trimesh

    from isochor.app.editor.document import Document
    from isochor.core.scenario.shapes import torus_levels

    mesh = torus_levels(7)[-1]
    path = tmp_path / "torus65k.ply"
    trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=False).export(path)
    doc = Document.open(path)
    win = open_window(qtbot, doc, size=(1000, 700))
    wait_idle(qtbot, win)
    assert win.viewport.scene.model.proxy is not None
    yield win
    win.undo_stack.setClean()
    win.close()


def test_turning_the_camera_draws_the_proxy_then_the_full_mesh_after_a_pause(qtbot, big_torus):
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    from isochor.app.view.modeldraw import IDLE_MS

    win = big_torus
    vp = win.viewport
    frames = vp.model_frames
    qtbot.waitUntil(frames.showing_full, timeout=10_000)
    corner = QPoint(15, vp.height() - 15)  # empty space: a camera turn
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
    QTest.mousePress(vp, left, none, corner)
    assert frames.drawn_model().startswith("proxy"), "the camera's renders are a proxy's"
    for dx in range(10, 90, 10):
        QTest.mouseMove(vp, corner + QPoint(dx, -dx // 2))
        qtbot.wait(IDLE_MS // 5)  # moves keep the proxy: no pause yet
        assert frames.drawn_model().startswith("proxy")
    QTest.mouseRelease(vp, left, none, corner + QPoint(80, -40))
    assert not frames.showing_full()
    qtbot.waitUntil(frames.showing_full, timeout=10_000)  # after the pause
    assert frames.drawn_model().startswith("full mesh")
    # the wheel zooms on the proxy too
    from PySide6.QtCore import QPointF
    from PySide6.QtGui import QWheelEvent

    pos = QPointF(vp.width() / 2, vp.height() / 2)
    wheel = QWheelEvent(
        pos,
        vp.mapToGlobal(pos),
        QPoint(),
        QPoint(0, 120),
        Qt.MouseButton.NoButton,
        none,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    from PySide6.QtWidgets import QApplication

    QApplication.sendEvent(vp, wheel)
    assert frames.drawn_model().startswith("proxy")
    qtbot.waitUntil(frames.showing_full, timeout=10_000)


def _shown_pixels(vp) -> np.ndarray:
    """What the view shows now, read from VTK's display framebuffer (rendering nothing)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

    rw = vp.ren_win
    w, h = rw.GetSize()
    data = vtkUnsignedCharArray()
    rw.GetPixelData(0, 0, w - 1, h - 1, 1, data, 0)
    return vtk_to_numpy(data).reshape(h, w, 3).copy()


def _turn_camera(qtbot, vp) -> None:
    """A short camera turn on empty space, as a user's (the proxy drawn while it moves)."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    corner = QPoint(15, vp.height() - 15)
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
    QTest.mousePress(vp, left, none, corner)
    for dx in (10, 20, 30):
        QTest.mouseMove(vp, corner + QPoint(dx, -dx // 2))
        qtbot.wait(10)
    QTest.mouseRelease(vp, left, none, corner + QPoint(30, -15))


def test_the_full_mesh_comes_back_drawn_in_passes_with_the_same_pixels(qtbot, big_torus):
    """After a pause the full mesh is drawn in passes (one piece of its triangles each) and
    shown by a paint that draws only the rest: the picture is a normal render's, pixel for
    pixel, and the proxy's before it is not."""
    vp = big_torus.viewport
    frames, model = vp.model_frames, vp.scene.model
    composer = model.composer
    model.full.remove_pieces(vp)
    model.full.add_pieces(vp, faces=8192)  # (8 pieces of the 65536 triangles)
    assert len(model.full.pieces) == 8
    _turn_camera(qtbot, vp)
    assert frames.drawn_model().startswith("proxy")
    proxy = _shown_pixels(vp)
    shown, passes = composer.shown, composer.passes_drawn
    qtbot.waitUntil(frames.showing_full, timeout=10_000)
    assert frames.drawn_model().startswith("full mesh")
    assert composer.shown == shown + 1, "the frame the passes drew was shown"
    assert composer.passes_drawn - passes >= 1 + 8, "the background pass and every piece"
    composed = _shown_pixels(vp)
    vp.repaint()  # a normal render of the same scene
    qtbot.wait(50)
    assert composer.shown == shown + 1
    normal = _shown_pixels(vp)
    assert composed.shape == normal.shape
    differ = (np.abs(composed.astype(int) - normal.astype(int)).max(axis=2) > 0).sum()
    assert differ == 0, f"{differ} pixels differ from a normal render"
    assert (np.abs(proxy.astype(int) - normal.astype(int)).max(axis=2) > 0).sum() > 100


def test_a_press_while_the_full_mesh_is_drawn_in_passes_cancels_them(qtbot, big_torus):
    """A camera press landing between two passes draws the proxy at once; the passes' frame
    is never shown, and the full mesh comes back after the next pause."""
    from PySide6.QtCore import QPoint, Qt, QTimer
    from PySide6.QtTest import QTest

    vp = big_torus.viewport
    frames, model = vp.model_frames, vp.scene.model
    composer = model.composer
    model.full.remove_pieces(vp)
    model.full.add_pieces(vp, faces=4096)  # (16 pieces)
    corner = QPoint(15, vp.height() - 15)
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
    pressed = {}

    def press() -> None:
        pressed["passes"] = composer.passes_drawn
        pressed["full"] = frames.showing_full()
        QTest.mousePress(vp, left, none, corner)
        pressed["drawn"] = frames.drawn_model()
        paints = vp.paints
        vp.repaint()  # the press's paint, now
        pressed["painted"] = vp.paints - paints
        pressed["shown"] = composer.shown

    def rendered(*_args) -> None:  # after the second pass: press in the next turn
        if composer.passes_drawn - passes == 2 and not pressed and "armed" not in pressed:
            pressed["armed"] = True
            QTimer.singleShot(0, press)

    _turn_camera(qtbot, vp)
    shown, passes = composer.shown, composer.passes_drawn
    tag = vp.ren_win.AddObserver("EndEvent", rendered)
    try:
        qtbot.waitUntil(lambda: "drawn" in pressed, timeout=10_000)
    finally:
        vp.ren_win.RemoveObserver(tag)
    assert not pressed["full"], "the press came while the passes ran"
    assert pressed["passes"] - passes < 1 + len(model.full.pieces)
    assert pressed["drawn"].startswith("proxy"), pressed["drawn"]
    assert pressed["painted"] == 1
    assert pressed["shown"] == shown, "the cancelled passes' frame is not shown"
    QTest.mouseRelease(vp, left, none, corner)
    qtbot.waitUntil(frames.showing_full, timeout=10_000)
    assert composer.shown == shown + 1, "the full mesh drawn in passes once, after the pause"


def test_a_click_on_a_node_of_a_big_model_brings_the_full_mesh_back_in_passes(
    qtbot, big_torus, monkeypatch
):
    """A press on a node draws the proxy (a drag may follow); its release without a drag
    does not render the full mesh whole at once: it comes back after the pause, drawn in
    passes, at the same nodes (nothing deformed or shaded again)."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from isochor.app.view import modelview
    from tests.gui.test_editor import pickable_node, point, screen_positions

    monkeypatch.setattr(modelview, "AT_ONCE_FACES", 0)  # (the torus as if it were bigger)
    win = big_torus
    vp = win.viewport
    frames, composer = vp.model_frames, vp.scene.model.composer
    qtbot.waitUntil(frames.showing_full, timeout=10_000)
    row = pickable_node(win, want_free=True)
    at = point(screen_positions(win)[0][row])
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
    shown, volume = composer.shown, vp.model_volume
    QTest.mousePress(vp, left, none, at)
    assert frames.drawn_model().startswith("proxy"), "a drag may follow: the proxy"
    QTest.mouseRelease(vp, left, none, at)
    assert frames.drawn_model().startswith("proxy"), "not the full mesh whole at once"
    assert not frames.showing_full()
    qtbot.waitUntil(frames.showing_full, timeout=10_000)
    assert frames.drawn_model().startswith("full mesh")
    assert composer.shown == shown + 1, "drawn in passes"
    assert vp.model_volume == volume and not vp.scene.volume_estimated
    assert list(win.doc.selection.rows) == [row], "the click selected the node"


QUIT_CHILD = r"""
import sys
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from isochor.app.cli import launch
from isochor.app.window.mainwindow import MainWindow

app = QApplication([sys.argv[0]])

def poll():
    wins = [w for w in app.topLevelWidgets() if isinstance(w, MainWindow) and w.isVisible()]
    if wins and not wins[0].is_solving():
        timer.stop()
        print("closing", flush=False)  # left in the buffer: the exit must flush it
        wins[0].undo_stack.setClean()
        wins[0].close()

timer = QTimer()
timer.timeout.connect(poll)
timer.start(50)
launch.run_editor(None)
print("returned")  # never: the editor's process ends when its window has closed
"""


def test_the_editor_process_ends_when_its_window_closes(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    done = subprocess.run(
        [sys.executable, "-c", QUIT_CHILD],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["closing"]


def test_a_proxy_whose_paints_overrun_the_budget_gives_way_to_a_coarser_level(
    qtbot, big_torus, monkeypatch
):
    """The proxy's size follows what its paints cost: within the budget it stays; over it,
    the next coarser pyramid level is drawn while things move (never below the floor), a
    rebuilt scene starts from that level, and the full mesh still comes back after a pause.
    The budget is set so that every paint is within it, then every paint over it: the
    measured paint times decide, and no time is asserted."""
    from isochor.app.view import modelview

    win = big_torus
    vp = win.viewport
    frames, model = vp.model_frames, vp.scene.model
    levels = [m.n_faces for m in win.state.surface.levels]
    assert model.proxy.n_faces == 16384 and levels[model.proxy_k] == 16384
    monkeypatch.setattr(modelview, "PROXY_BUDGET", 1e9)
    for _ in range(3):
        _turn_camera(qtbot, vp)
        qtbot.waitUntil(frames.showing_full, timeout=10_000)
    assert model.proxy.n_faces == 16384 and model.proxy_cap is None
    finer = model.proxy.actor
    monkeypatch.setattr(modelview, "PROXY_BUDGET", 0.0)
    paints = vp.paints
    for _ in range(6):
        _turn_camera(qtbot, vp)
        assert frames.drawn_model().startswith("proxy")
        qtbot.waitUntil(frames.showing_full, timeout=10_000)
    assert vp.paints - paints >= modelview.PROXY_SAMPLES
    # 16384 -> 4096, and not to 1024 (below the floor)
    assert model.proxy.n_faces == 4096 and levels[model.proxy_k] == 4096
    assert model.proxy_cap == 4096 and modelview.PROXY_FLOOR > 1024
    assert not vp.renderer.HasViewProp(finer), "the finer proxy left the scene"
    _turn_camera(qtbot, vp)
    assert frames.drawn_model() == f"proxy (level {model.proxy_k + 1}, 4096 triangles)"
    assert vp.scene.model.proxy.actor.GetMapper().GetInput().GetNumberOfCells() == 4096
    # the coarser proxy draws the same model: its picture nearly covers the finer one's
    # (the torus in the same place), unlike the empty background
    shown = _shown_pixels(vp)
    background = shown[2, 2]
    covered = (np.abs(shown.astype(int) - background.astype(int)).max(axis=2) > 30).sum()
    assert covered > 0.05 * shown.shape[0] * shown.shape[1]
    qtbot.waitUntil(frames.showing_full, timeout=10_000)
    assert frames.drawn_model().startswith("full mesh")
    win.rebuild_lattice((4, 4, 4))  # a new scene: the proxy starts at the level found
    qtbot.waitUntil(lambda: tuple(win.state.lattice.shape) == (4, 4, 4), timeout=30_000)
    model = vp.scene.model
    assert model.proxy.n_faces == 4096
    assert vp.renderer.HasViewProp(model.proxy.actor) and not vp.renderer.HasViewProp(finer)
    assert vp.renderer.HasViewProp(model.full.actor)


def test_a_dense_rebuild_of_a_big_model_is_computed_off_the_gui_thread_and_shown_as_proxy(
    qtbot, big_torus, held_rebuild, monkeypatch
):
    """Rebuilding to Blender's dense lattice (16x16x16 B-spline) on a model with a proxy: the
    basis, springs and view arrays are computed on the rebuild's thread while the event loop
    keeps turning; committed, the new scene is painted at its proxy first and the full mesh
    comes back after the pause, drawn in passes."""
    from PySide6.QtCore import QTimer

    from isochor.app.view import modelview

    # (a full mesh of this torus's size is drawn at once after a frame; the armadillo's is not)
    monkeypatch.setattr(modelview, "AT_ONCE_FACES", 1000)
    win = big_torus
    vp = win.viewport
    seen = _record_threads(monkeypatch)
    gui = threading.current_thread().name
    win.lattice_rebuild.start((16, 16, 16), "bspline")
    thread = win.lattice_rebuild.threads[-1]
    assert thread.is_alive() and thread.name.startswith("isochor-lattice-")
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(thread.is_alive()))
    timer.start(5)
    qtbot.waitUntil(lambda: len(ticks) >= 5, timeout=5_000)
    held_rebuild.set()
    qtbot.waitUntil(lambda: tuple(win.state.lattice.shape) == (16, 16, 16), timeout=60_000)
    timer.stop()
    assert all(ticks[:5]), "the event loop turned while the thread worked"
    assert seen and gui not in seen and all(n.startswith("isochor-lattice-") for n in seen)
    assert win.state.lattice.basis == ("bspline",) * 3 and len(vp.nodes) == 16**3
    assert vp.model_frames.drawn_model().startswith("proxy"), "the first paint: the proxy"
    composer = vp.scene.model.composer
    shown = composer.shown
    qtbot.waitUntil(vp.model_frames.showing_full, timeout=20_000)
    assert vp.model_frames.drawn_model().startswith("full mesh") and composer.shown > shown
