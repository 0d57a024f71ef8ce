"""Export tells the truth (issue 29 item 3): File > Export while a solve runs waits for it,
with a progress dialog and Cancel, and writes the result, never the mesh in the middle of
the solve; Cancel writes nothing and says so."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from isochor.core.defaults import TOL_VOLUME
from tests.gui.test_editor import drag, pickable_node


def slow_solves(monkeypatch) -> None:
    """Every solve sleeps 40 ms a step: a solve still runs when Export is chosen."""
    from isochor.core.solve import multilevel

    solve = multilevel.solve

    def slow(*args, **kwargs):
        records = solve(*args, **kwargs)
        try:
            while True:
                try:
                    record = next(records)
                except StopIteration as stop:
                    return stop.value
                time.sleep(0.04)
                yield record
        finally:
            records.close()

    monkeypatch.setattr(multilevel, "solve", slow)


def choose_export(monkeypatch, win, path) -> None:
    """File > Export, the file dialog answered with ``path``."""
    from PySide6.QtWidgets import QFileDialog

    monkeypatch.setattr(
        QFileDialog, "getSaveFileName", lambda *a, **k: (str(path), "Wavefront OBJ (*.obj)")
    )
    win.action_set.export.trigger()


def test_export_during_a_solve_waits_for_the_result_or_is_cancelled(
    qtbot, sphere, monkeypatch, tmp_path
):
    from PySide6.QtCore import Qt, QTimer
    from PySide6.QtGui import QPainter
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication, QProgressDialog, QPushButton

    import isochor
    from tests.gui.conftest import wait_idle

    win = sphere
    slow_solves(monkeypatch)
    v0 = win.state.surface.rest_volume
    drag(qtbot, win, pickable_node(win), offset=(60, -40))
    assert win.is_solving()
    seen = []

    def look():
        box = QApplication.activeModalWidget()
        if isinstance(box, QProgressDialog):
            seen.append((box.labelText(), win.is_solving()))
            if os.environ.get("ISOCHOR_SHOTS"):
                shot = win.grab()
                painter = QPainter(shot)
                painter.drawPixmap(box.mapTo(win, box.rect().topLeft()), box.grab())
                painter.end()
                shot.save(os.path.join(os.environ["ISOCHOR_SHOTS"], "export_waits.png"))
        else:
            QTimer.singleShot(20, look)

    QTimer.singleShot(20, look)
    out = tmp_path / "during.obj"
    choose_export(monkeypatch, win, out)
    assert seen and seen[0] == ("Waiting for the solve to finish before exporting…", True)
    assert not win.is_solving() and win.state.converged
    message = win.statusBar().currentMessage()
    assert message.startswith(f"Exported {out}.") and "Not solved" not in message
    written = isochor.Session(out).problem.surface.rest_volume
    assert written / v0 == pytest.approx(1.0, abs=2 * TOL_VOLUME)
    exported = isochor.Session(out).problem.surface.full.vertices
    expect = win.doc.deformed_mesh(win.state.nodes).vertices
    assert np.abs(exported - expect).max() < 1e-5 * win.state.surface.size  # the result
    wait_idle(qtbot, win)

    # Cancel: nothing written, and the status bar says so
    drag(qtbot, win, pickable_node(win), offset=(-50, 30))
    assert win.is_solving()

    def cancel():
        box = QApplication.activeModalWidget()
        if isinstance(box, QProgressDialog):
            seen.append(("cancel", win.is_solving()))
            button = box.findChild(QPushButton)
            QTest.mouseClick(button, Qt.MouseButton.LeftButton)
        else:
            QTimer.singleShot(20, cancel)

    QTimer.singleShot(20, cancel)
    cancelled = tmp_path / "cancelled.obj"
    choose_export(monkeypatch, win, cancelled)
    assert seen[-1] == ("cancel", True), seen
    assert not cancelled.exists()
    assert win.statusBar().currentMessage().startswith("Export cancelled")
    wait_idle(qtbot, win)
