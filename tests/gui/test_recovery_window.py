"""Never lose work (issue 29 item 2): the real editor process is started on a model, edited
with real key events, killed with SIGKILL; the next start offers to recover the work, and
recovers it; a clean quit removes the recovery file."""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np

from tests.gui.conftest import save_shot
from tests.models import model

#: the child: the editor as `isochor-editor MODEL` starts it (run_editor), plus a timer that
#: selects the top layer of the lattice (a test hook) and types G Y -0.3 Enter, then S 0.8
#: Enter, on the view, and says READY (with the nodes) once the recovery file is written
CHILD = textwrap.dedent(
    """
    import sys, json
    from PySide6.QtCore import QTimer, Qt
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication
    from isochor.app.cli.launch import run_editor
    from isochor.app.editor import recovery

    app = QApplication(["isochor"])
    steps = iter(["select", "gy-0.3\\n", "wait", "s0.8\\n", "wait", "ready"])

    def window():
        return next(w for w in app.topLevelWidgets() if type(w).__name__ == "MainWindow")

    def tick():
        win = window()
        if win.is_solving():
            return
        step = next(steps, None)
        if step is None:
            return
        vp = win.viewport
        if step == "select":
            lat = win.state.lattice
            top = [r for r in range(lat.n_nodes) if lat.ijk(r)[1] == lat.shape[1] - 1]
            win.doc.selection.select(top)
            win.activateWindow()  # the view's keys are the active window's
            vp.setFocus()
        elif step == "wait":
            pass
        elif step == "ready":
            if not (win.autosave.written and recovery.own_file().is_file()):
                globals()["steps"] = iter(["ready"])  # not written yet: look again
                return
            print("READY", json.dumps(win.state.nodes.tolist()), flush=True)
        else:
            QTest.mouseMove(vp, vp.rect().center())
            for ch in step:
                key = {"-": "Key_Minus", ".": "Key_Period", "\\n": "Key_Return"}.get(
                    ch, f"Key_{ch.upper()}"
                )
                QTest.keyClick(vp, getattr(Qt.Key, key))

    timer = QTimer()
    timer.timeout.connect(tick)
    timer.start(300)
    sys.exit(run_editor(sys.argv[1]))
    """
)


def test_work_survives_a_sigkill_and_is_recovered_at_the_next_start(qtbot, themed_app, tmp_path):
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication, QMessageBox

    from isochor.app.editor import recovery
    from isochor.app.editor.document import Document
    from tests.gui.conftest import open_window

    path = model("torus_knot_quads.obj")
    env = dict(os.environ)  # the test run's own XDG_STATE_HOME (tests/gui/conftest.py)
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        lines: queue.Queue = queue.Queue()
        threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
        deadline = time.monotonic() + 120
        line = ""
        while time.monotonic() < deadline and not line.startswith("READY"):
            try:
                line = lines.get(timeout=1.0)
            except queue.Empty:
                if proc.poll() is not None:
                    break
        assert line.startswith("READY"), f"the child said {line!r} (exit {proc.poll()})"
        edited = np.array(json.loads(line.split(" ", 1)[1]))
        (left,) = recovery.files_of(proc.pid)
        assert left.is_file()
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    assert proc.returncode == -signal.SIGKILL
    assert recovery.left_behind() == [left], "the killed editor's file is offered"

    # the next start: the window as run_editor makes it, then the offer (a real dialog)
    win = open_window(qtbot, Document.example(), size=(1280, 720))
    seen = []

    def answer():
        box = QApplication.activeModalWidget()
        if not isinstance(box, QMessageBox):
            QTimer.singleShot(50, answer)
            return
        seen.append(box.text())
        if os.environ.get("ISOCHOR_SHOTS"):
            box.grab().save(os.path.join(os.environ["ISOCHOR_SHOTS"], "recovery_dialog.png"))
        next(b for b in box.buttons() if b.text() == "Recover").click()

    QTimer.singleShot(50, answer)
    assert win.autosave.offer()
    assert seen and "torus_knot_quads.obj had unsaved changes" in seen[0]
    st = win.state
    assert st.problem.scenario.model_path().resolve() == path.resolve()
    assert st.moved.sum() > 0 and np.allclose(st.nodes[st.moved], edited[st.moved], atol=1e-9)
    assert not win.undo_stack.isClean() and " * " in win.windowTitle()
    assert not left.exists(), "the recovered file is gone"
    qtbot.waitUntil(lambda: recovery.own_file().is_file(), timeout=10_000)  # still unsaved
    save_shot(win, "recovered")
    # a clean quit (the changes let go) removes this window's file
    win.undo_stack.setClean()
    assert not recovery.own_file().exists()
    win.close()
    assert recovery.left_behind() == []
