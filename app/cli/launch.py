"""``run_editor``: start the editor, or take a screenshot of it and exit.

``main`` is the ``isochor-editor`` gui-script.

This module imports only the standard library at import time, so the command line can
call :func:`run_editor` on a machine without a display (or without Qt) and get one line
of explanation and a non-zero exit code instead of a Qt abort.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ...core import blas

# the editor's start (the isochor-editor script): one BLAS thread, as the command line
blas.at_start()

#: Exit codes.
OK, FAILED = 0, 1
NO_DISPLAY = FAILED  # like the command line's other environment errors

NO_DISPLAY_MESSAGE = (
    "isochor: no display available (neither DISPLAY nor WAYLAND_DISPLAY is set); "
    "the editor needs one - use `isochor solve SCENARIO` to solve without a window"
)


#: the editor's libraries: the ``gui`` extra (``pip install 'isochor[gui]'``)
GUI_MODULES = ("PySide6", "pyvista", "pyvistaqt")


def missing_gui() -> str | None:
    """The one line to show when the editor's libraries are not installed (a lean
    ``pip install isochor``), or None. Looked up, not imported: it costs nothing."""
    from importlib.util import find_spec

    missing = [name for name in GUI_MODULES if find_spec(name) is None]
    if not missing:
        return None
    return (
        f"isochor: the editor needs {', '.join(missing)}: pip install 'isochor[gui]' "
        "(`isochor solve SCENARIO` solves without a window)"
    )


def display_problem() -> str | None:
    """Why no window can be opened here, or None when a display is available."""
    if not sys.platform.startswith("linux"):
        return None
    wayland = os.environ.get("WAYLAND_DISPLAY")
    x11 = os.environ.get("DISPLAY")
    if not wayland and not x11:
        return NO_DISPLAY_MESSAGE
    if x11 and not wayland and not _x_display_opens(x11):
        return (
            f"isochor: cannot connect to the X display {x11!r}; "
            "use `isochor solve SCENARIO` to solve without a window"
        )
    return None


def _x_display_opens(name: str) -> bool:
    """Try to open the X display with libX11, as Qt would (Qt aborts when it cannot).

    When libX11 itself cannot be loaded, say yes and let Qt decide."""
    import ctypes
    import ctypes.util

    lib = ctypes.util.find_library("X11")
    try:
        x11 = ctypes.CDLL(lib or "libX11.so.6")
    except OSError:
        return True
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    handle = x11.XOpenDisplay(name.encode())
    if not handle:
        return False
    x11.XCloseDisplay(handle)
    return True


#: seconds a screenshot waits for the solve at most, unless told otherwise
SCREENSHOT_TIMEOUT = 300.0


def main() -> int:
    """The ``isochor-editor`` gui-script: the editor on the file named, if any."""
    path = sys.argv[1] if len(sys.argv) > 1 else None
    return run_editor(path)


def run_editor(
    path: str | None, screenshot: str | None = None, timeout: float | None = None
) -> int:
    """Open the editor on ``path`` (a model or scenario; None: the default example).

    A big file (:func:`isochor.app.window.loading.in_background`) is read after the window
    appears, on the default example, with its progress in the status bar and Cancel; a
    small one, or any in screenshot mode, is read before the window is made.

    With ``screenshot``, solve the document's scenario to the end with the normal
    progressive redraw (at most ``timeout`` seconds, default :data:`SCREENSHOT_TIMEOUT`),
    save a PNG of the whole window there and return 0.

    Returns the process exit code: 0, or 1 with one line on standard error (the gui
    extra is not installed, no display, the GUI libraries fail to load, or in screenshot
    mode a file or the solve failed). The interactive editor does not return: when its
    window has closed the process ends at once with the application's exit code
    (:func:`isochor.app.cli.console.leave_now`).
    """
    problem = missing_gui() or display_problem()
    if problem is not None:
        print(problem, file=sys.stderr)
        return NO_DISPLAY
    try:
        import pyvistaqt  # noqa: F401 (the editor cannot start without it)
        from PySide6.QtWidgets import QApplication
    except ImportError as exc:
        print(
            f"isochor: the editor needs PySide6 and pyvistaqt ({exc}); "
            "use `isochor solve SCENARIO` to solve without a window",
            file=sys.stderr,
        )
        return FAILED

    from ...core.errors import IsochorError
    from ...core.io.atomic import check_outputs
    from ..editor.document import Document
    from ..view import style

    app = QApplication.instance() or QApplication([sys.argv[0] if sys.argv else "isochor"])
    app.setApplicationName("Isochor")
    app.setOrganizationName("Isochor")
    style.apply_dark_theme(app)

    from ..window.loading import in_background
    from ..window.mainwindow import MainWindow  # imports VTK: after the checks

    opening_error = None
    # A big file opens in the window, in the background, with its progress shown; in
    # screenshot mode (and for a small file) it is read before the window appears.
    later = path is not None and not screenshot and in_background(path)
    if path is None or later:
        doc = Document.example()
    else:
        try:
            doc = Document.open(path)
        except IsochorError as exc:
            if screenshot:
                print(f"isochor: {exc}", file=sys.stderr)
                return FAILED
            opening_error = str(exc)  # open the window anyway, on the example, and say why
            doc = Document.example()
    if screenshot:  # never over the file opened or its model (checked before any work)
        try:
            check_outputs([(screenshot, "--screenshot")], _inputs(path, doc))
        except IsochorError as exc:
            print(f"isochor: {exc}", file=sys.stderr)
            return FAILED
    window = MainWindow(doc)
    if screenshot:
        limit = SCREENSHOT_TIMEOUT if timeout is None else timeout
        return take_screenshot(app, window, screenshot, limit)
    window.show()
    from PySide6.QtCore import QTimer

    QTimer.singleShot(0, window.autosave.offer)  # what a crash or a kill left, if anything
    if later:
        window.files.open_path(path)
    if opening_error is not None:
        window.error("Cannot open the file", opening_error)
    code = app.exec()
    window.shutdown()
    from .console import leave_now

    leave_now(int(code))
    return int(code)  # (not reached)


def _inputs(path: str | None, doc) -> list[tuple[str, str]]:
    inputs = [(path, "the file it shows")] if path else []
    return inputs + doc.state.problem.scenario.inputs()


def take_screenshot(app, window, out: str | Path, timeout: float = SCREENSHOT_TIMEOUT) -> int:
    """Show ``window``, let its solve run to the end, save a PNG of it; the exit code.

    The picture is taken when the session is idle (the solve ended, or there was nothing to
    solve) and its last frame is drawn, or after ``timeout`` seconds, whichever comes first.
    A solve that failed or did not end in time exits 1 (the picture is still written).
    """
    from PySide6.QtCore import QEventLoop, QTimer

    from ...core.errors import IsochorError

    window.set_headless_errors()
    # A local loop, not app.exec()/app.quit(): quitting the application would make every
    # later event loop in this process return at once (it matters to tests).
    loop = QEventLoop()
    window.resize(1400, 880)
    outcome = {"code": OK, "shot": False}

    def shoot(code: int = OK) -> None:
        if outcome["shot"]:
            return
        outcome["shot"] = True
        outcome["code"] = code
        try:
            window.session.flush()  # draw the final nodes now
            app.processEvents()
            save_window_png(window, out)
        except IsochorError as exc:
            print(f"isochor: {exc}", file=sys.stderr)
            outcome["code"] = FAILED
        window.undo_stack.setClean()
        window.close()
        loop.quit()

    def idle() -> None:
        failed = window.state.result is not None and not window.state.result.converged
        QTimer.singleShot(250, lambda: shoot(FAILED if failed else OK))

    def too_late() -> None:
        if not outcome["shot"]:
            print(
                f"isochor: the solve did not end within {timeout:g} s; the picture shows "
                "where it was",
                file=sys.stderr,
            )
            shoot(FAILED)

    window.idle.connect(idle)
    QTimer.singleShot(int(timeout * 1000), too_late)
    window.show()
    loop.exec()
    window.shutdown()
    return outcome["code"]


def save_window_png(window, out: str | Path) -> None:
    """Grab the whole window and write it as PNG, atomically (:mod:`isochor.core.io.atomic`).

    Raises :class:`IsochorError` naming ``out`` when it cannot be written."""
    from PySide6.QtCore import QBuffer, QByteArray, QIODevice

    from ...core.errors import IsochorError
    from ...core.io.atomic import atomic_write_bytes

    data = QByteArray()
    buffer = QBuffer(data)
    buffer.open(QIODevice.OpenModeFlag.WriteOnly)
    if not window.grab().toImage().save(buffer, "PNG"):
        raise IsochorError(f"{out}: the picture could not be encoded as PNG")
    buffer.close()
    atomic_write_bytes(out, bytes(data))
