"""Opening a file in the background (issue 9): while a model loads, the window keeps
answering and shows the progress; the model then replaces the document and its first solve
starts at once; a cancel or a failure keeps the document the window had, as it was."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from isochor.app.editor import noderules
from tests.gui.conftest import MODELS, wait_idle

ARMADILLO = MODELS / "armadillo_loop1_346k.ply"
needs_armadillo = pytest.mark.skipif(
    not ARMADILLO.is_file(),
    reason=f"the shared models are absent ({ARMADILLO}: ../shared beside the repository)",
)


def _small_model():
    from isochor import assets

    return assets.model_files()["club"]


class Ticks:
    """A 10 ms timer counting its ticks while the window loads, and the stages it saw."""

    def __init__(self, win) -> None:
        from PySide6.QtCore import QTimer

        self.win, self.count, self.stages, self.bar_seen = win, 0, set(), False
        self.timer = QTimer()
        self.timer.setInterval(10)
        self.timer.timeout.connect(self._tick)
        self.timer.start()

    def _tick(self) -> None:
        files = self.win.files
        if files.loading():
            self.count += 1
            self.stages.add(files.loader.bar.stage)
            self.bar_seen |= files.loader.bar.isVisible()

    def stop(self) -> None:
        self.timer.stop()


def _snapshot(win):
    return win.doc, win.doc.title, np.array(win.state.nodes), win.undo_stack.count()


def _unchanged(win, snap) -> None:
    doc, title, nodes, count = snap
    assert win.doc is doc and win.doc.title == title
    assert np.array_equal(win.state.nodes, nodes)
    assert win.undo_stack.count() == count
    assert not win.files.loading() and not win.files.loader.bar.isVisible()


def _edited(qtbot, win) -> None:
    """One undoable move of node 0, solved; the stack marked clean (no prompt to open)."""
    win.doc.selection.select([0])
    st = win.state
    win.commit_edit(
        noderules.edit_position(win.doc.base(), 0, float(st.nodes[0, 0]) - 0.1 * st.surface.size)
    )
    wait_idle(qtbot, win)
    win.undo_stack.setClean()


def _first_record_after_an_edit(qtbot, win, timeout=60_000) -> None:
    st = win.state
    win.doc.selection.select([0])
    with qtbot.waitSignal(win.session.recordAccepted, timeout=timeout):
        win.commit_edit(
            noderules.edit_position(
                win.doc.base(), 0, float(st.nodes[0, 0]) - 0.1 * st.surface.size
            )
        )


def _opened(qtbot, win, name, timeout) -> None:
    qtbot.waitUntil(lambda: not win.files.loading(), timeout=timeout)
    assert win.doc.title == name and win.windowTitle().startswith(name)
    assert win.undo_stack.count() == 0
    assert not win.files.loader.bar.isVisible()
    surface = win.state.surface
    # prepared by the loading thread: the controller's preparation finds it all cached
    assert {"springs", "interior", "fold_check"} <= set(vars(surface))


@pytest.fixture
def slow_read(monkeypatch):
    """Loads wait for ``release`` before they read anything."""
    from isochor.app.window import loading

    release = threading.Event()
    read = loading.read_document

    def held(*args, **kwargs):
        assert release.wait(30)
        return read(*args, **kwargs)

    monkeypatch.setattr(loading, "read_document", held)
    yield release
    release.set()


@pytest.fixture
def shown(monkeypatch):
    """The messages of the error dialogs, instead of the dialogs."""
    from PySide6.QtWidgets import QMessageBox

    messages = []
    monkeypatch.setattr(
        QMessageBox, "critical", staticmethod(lambda parent, title, text, *a: messages.append(text))
    )
    return messages


def test_a_model_opens_in_the_background_while_the_window_answers(qtbot, window):
    win = window
    path = _small_model()
    ticks = Ticks(win)
    assert win.files.open_path(path, background=True)
    assert win.files.loading() and win.files.loader.bar.isVisible()
    assert win.doc.title != path.name, "the old document stays until the new one is ready"
    _opened(qtbot, win, path.name, timeout=30_000)
    ticks.stop()
    assert ticks.count >= 3 and ticks.bar_seen
    _first_record_after_an_edit(qtbot, win)


@pytest.mark.parametrize("how", ["button", "escape"])
def test_a_cancelled_load_keeps_the_document_and_drops_the_late_result(
    qtbot, window, slow_read, how
):
    from PySide6.QtCore import Qt

    win = window
    _edited(qtbot, win)
    snap = _snapshot(win)
    assert win.files.open_path(_small_model(), background=True)
    loader = win.files.loader
    assert loader.bar.isVisible()
    if how == "button":
        loader.bar.cancel.click()
    else:
        qtbot.keyClick(win.viewport, Qt.Key.Key_Escape)
    _unchanged(win, snap)
    slow_read.set()  # the thread now reads, and delivers to no one
    qtbot.waitUntil(lambda: loader.discarded >= 1, timeout=30_000)
    qtbot.wait(50)
    _unchanged(win, snap)
    win.undo_stack.undo()  # the history is the old document's
    assert win.undo_stack.index() == snap[3] - 1


def test_a_document_edited_during_the_load_is_kept_when_the_user_says_so(
    qtbot, window, slow_read, monkeypatch
):
    from PySide6.QtWidgets import QMessageBox

    win = window
    asked = []
    monkeypatch.setattr(
        QMessageBox,
        "question",
        staticmethod(lambda *a, **k: asked.append(a) or QMessageBox.StandardButton.Cancel),
    )
    assert win.files.open_path(_small_model(), background=True)
    win.doc.selection.select([0])  # an edit while the model loads
    win.commit_edit(noderules.edit_position(win.doc.base(), 0, float(win.state.nodes[0, 0]) + 0.1))
    wait_idle(qtbot, win)
    snap = _snapshot(win)
    slow_read.set()
    qtbot.waitUntil(lambda: not win.files.loading(), timeout=30_000)
    assert len(asked) == 1
    _unchanged(win, snap)


def _truncated_ply(path, keep=0.6):
    """A PLY of the club cut off after ``keep`` of its bytes."""
    from isochor.core.io.meshio import load_mesh, mesh_bytes

    data = mesh_bytes(load_mesh(_small_model()).mesh, ".ply")
    path.write_bytes(data[: int(len(data) * keep)])
    return path


def test_a_file_that_fails_to_load_keeps_the_document_and_says_why(qtbot, window, shown, tmp_path):
    win = window
    snap = _snapshot(win)
    bad = _truncated_ply(tmp_path / "cut.ply")
    assert win.files.open_path(bad, background=True)
    qtbot.waitUntil(lambda: not win.files.loading(), timeout=30_000)
    assert len(shown) == 1 and "cut.ply" in shown[0] and "\n" not in shown[0]
    _unchanged(win, snap)


@needs_armadillo
def test_the_armadillo_opens_through_file_open_without_freezing(qtbot, window, monkeypatch):
    from isochor.app.window import files, loading

    win = window
    assert loading.in_background(ARMADILLO)
    monkeypatch.setattr(
        files.QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(ARMADILLO), ""))
    )
    ticks = Ticks(win)
    redraws = win.frames.redraws
    win.action_set.open.trigger()  # File > Open
    assert win.files.loading() and win.files.loader.bar.isVisible()
    _opened(qtbot, win, ARMADILLO.name, timeout=180_000)
    ticks.stop()
    # a window frozen for the load would tick once or twice in all
    assert ticks.count >= 50 and ticks.bar_seen
    assert {f"Reading {ARMADILLO.name}…", "Preparing the solver…"} <= ticks.stages
    assert win.state.surface.full.n_faces > 300_000
    qtbot.waitUntil(lambda: win.frames.redraws > redraws, timeout=10_000)  # it is drawn
    _first_record_after_an_edit(qtbot, win)


@needs_armadillo
def test_a_new_open_while_a_cancelled_armadillo_still_loads(qtbot, window, shown, tmp_path):
    win = window
    snap = _snapshot(win)
    assert win.files.open_path(ARMADILLO)  # big: in the background
    loader = win.files.loader
    first = loader.threads[-1]
    qtbot.wait(300)
    loader.bar.cancel.click()
    _unchanged(win, snap)
    # the cancelled reader's child is stopped; a new open starts before its thread ends
    path = _small_model()
    assert win.files.open_path(path, background=True)
    _opened(qtbot, win, path.name, timeout=60_000)
    qtbot.waitUntil(lambda: not first.is_alive(), timeout=60_000)
    qtbot.wait(50)
    assert loader.discarded >= 1 and win.doc.title == path.name and not shown


@needs_armadillo
def test_a_truncated_armadillo_fails_in_the_background(qtbot, window, shown, tmp_path):
    win = window
    snap = _snapshot(win)
    bad = tmp_path / "armadillo_cut.ply"
    with open(ARMADILLO, "rb") as f:
        bad.write_bytes(f.read(2_000_000))
    assert win.files.open_path(bad)
    assert win.files.loading()
    qtbot.waitUntil(lambda: not win.files.loading(), timeout=60_000)
    assert len(shown) == 1 and "armadillo_cut.ply" in shown[0] and "\n" not in shown[0]
    _unchanged(win, snap)
