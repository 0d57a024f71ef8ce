"""GUI tests: the real window driven with pytest-qt under a virtual X display.

pytest-xvfb starts Xvfb for the session when it is installed; without it, a DISPLAY or
WAYLAND_DISPLAY must already be set. Every test here is skipped, with the reason, when
PySide6 or pyvistaqt cannot be imported or no display can be had.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

MODELS = Path(__file__).resolve().parents[3] / "shared" / "models"

try:
    import PySide6  # noqa: F401
    import pytestqt  # noqa: F401
    import pyvistaqt  # noqa: F401

    _IMPORT_PROBLEM = None
except ImportError as exc:  # pragma: no cover - depends on the environment
    _IMPORT_PROBLEM = f"GUI libraries missing: {exc}"


def _display_problem() -> str | None:
    if _IMPORT_PROBLEM:
        return _IMPORT_PROBLEM
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        return "no display: install Xvfb and pytest-xvfb, or run under xvfb-run"
    return None


def pytest_collection_modifyitems(config, items):
    reason = _display_problem()
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.gui)
            if reason:
                item.add_marker(pytest.mark.skip(reason=reason))


@pytest.fixture(autouse=True, scope="session")
def _isolated_user_state(tmp_path_factory):
    """The editor's recovery files and remembered layout go to a folder of the test run's
    own, never the user's (XDG_STATE_HOME, XDG_CONFIG_HOME)."""
    keep = {k: os.environ.get(k) for k in ("XDG_STATE_HOME", "XDG_CONFIG_HOME")}
    os.environ["XDG_STATE_HOME"] = str(tmp_path_factory.mktemp("state"))
    os.environ["XDG_CONFIG_HOME"] = str(tmp_path_factory.mktemp("config"))
    yield
    for k, v in keep.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


@pytest.fixture(autouse=True)
def _default_layout():
    """Each window test starts from the default layout: what an earlier test's window kept
    (the window saves its layout when it closes) is forgotten."""
    if _IMPORT_PROBLEM:  # the test is skipped: no Qt to ask
        yield
        return
    from isochor.app.window.layout import settings

    settings().clear()
    yield
    settings().clear()


@pytest.fixture(autouse=True)
def _no_unexpected_dialogs(monkeypatch):
    """A message box no test asked for fails the test instead of waiting for a click that
    never comes: a modal QMessageBox under Xvfb blocks the test's event loop until CI's
    time runs out (a fresh-clone run once hung in test_two_quick_drags on a solver error's
    box). Tests that expect a box patch the same functions themselves, over these."""
    if _IMPORT_PROBLEM:
        yield
        return
    from PySide6.QtWidgets import QMessageBox

    shown = []

    def unexpected(kind):
        def show(parent, title, text="", *args, **kwargs):
            shown.append(f"{kind}: {title}: {text}")
            return QMessageBox.StandardButton.Cancel

        return staticmethod(show)

    for kind in ("critical", "warning", "information", "question", "about"):
        monkeypatch.setattr(QMessageBox, kind, unexpected(kind))
    yield
    assert not shown, f"the window showed a message box no test expected: {shown}"


@pytest.fixture(scope="session")
def themed_app(qapp):
    from isochor.app.view import style

    style.apply_dark_theme(qapp)
    return qapp


def wait_idle(qtbot, win, timeout=60_000):
    """Wait until the window's solve ended and its last frame was drawn."""
    qtbot.waitUntil(lambda: not win.is_solving(), timeout=timeout)
    qtbot.waitUntil(lambda: not win.session.frame_pending, timeout=5_000)


def open_window(qtbot, doc=None, size=(1100, 760)):
    from isochor.app.window.mainwindow import MainWindow

    win = MainWindow(doc)
    qtbot.addWidget(win, before_close_func=lambda w: w.undo_stack.setClean())
    win.resize(*size)
    win.show()
    qtbot.waitExposed(win)
    return win


@pytest.fixture
def window(qtbot, themed_app):
    """The editor on its default example, with the opening solve finished."""
    win = open_window(qtbot)
    wait_idle(qtbot, win)
    yield win
    win.undo_stack.setClean()
    win.close()


def distinct_colours(qimage) -> int:
    """How many distinct RGB colours an image has."""
    from PySide6.QtGui import QImage

    img = qimage.convertToFormat(QImage.Format.Format_RGB32)
    w, h = img.width(), img.height()
    buf = np.frombuffer(img.constBits(), dtype=np.uint32, count=img.bytesPerLine() * h // 4)
    buf = buf.reshape(h, img.bytesPerLine() // 4)[:, :w]
    return len(np.unique(buf & 0xFFFFFF))


def run_cli(args, timeout=120):
    """``isochor ARGS`` in a child process (this interpreter, this display): the finished
    process and how many seconds it took."""
    import subprocess
    import time

    code = f"import sys; from isochor.app.cli.main import main; sys.exit(main({list(args)!r}))"
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=dict(os.environ),
        check=False,
    )
    return proc, time.perf_counter() - t0


def save_shot(win, name: str, show=None) -> None:
    """A PNG of the whole window in $ISOCHOR_SHOTS (when set), to look at by eye; ``show``:
    a widget of the Inspector to scroll into view first."""
    folder = os.environ.get("ISOCHOR_SHOTS")
    if not folder:
        return
    from PySide6.QtTest import QTest

    from isochor.app.cli.launch import save_window_png

    Path(folder).mkdir(parents=True, exist_ok=True)
    if show is not None:
        win.inspector_scroll.ensureWidgetVisible(show)
    win.session.flush()
    QTest.qWait(150)  # the layouts of what the last state changed settle
    save_window_png(win, Path(folder) / f"{name}.png")


#: a small scene the tool tests open (the built-in sphere, 4 levels, a 3x3x3 lattice)
SPHERE = {"model": {"builtin": "sphere", "n_levels": 4}, "lattice": {"nodes": [3, 3, 3]}}


@pytest.fixture
def sphere(qtbot, themed_app):
    """The window on :data:`SPHERE`, solved, active; closed afterwards without a prompt."""
    from isochor.app.editor.document import Document
    from isochor.core.scenario.document import Scenario
    from isochor.core.scenario.problem import build
    from tests.gui.test_goal_window import activate

    win = open_window(qtbot, Document(build(Scenario.from_dict(SPHERE))))
    wait_idle(qtbot, win)
    activate(qtbot, win)
    yield win
    win.undo_stack.setClean()
    win.close()
