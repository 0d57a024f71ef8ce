"""Opening a document in the background: the loading thread, its progress in the status bar,
and Cancel.

Reading a big model, cleaning it, building its level pyramid and preparing the solver
(:meth:`~isochor.core.solve.multilevel.EmbeddedSurface.prepare`) takes seconds. :class:`Loader`
does it on a thread, so the window keeps drawing and answering and the document on screen
stays as it was until the new one is ready. The thread only calls the core, through the
Qt-free :func:`read_document`, and hands the finished :class:`~isochor.app.editor.document.Document`
(or the message of its failure) to the GUI thread by a queued signal, with the view's arrays
computed too (:class:`~isochor.app.view.meshprep.DisplayPrep`); only the GUI thread touches
widgets, VTK and pyvista.

Every load has a generation id. Cancel (the bar's button, or Esc in the window) returns at
once: a thread cannot be killed, so it runs to its end in the background and what it
delivers then is dropped by its id. A new open may start meanwhile (the pyramid's
simplifier is shared: the new load waits for the old one there).

The core reports no progress inside a stage, so the bar is a busy bar with the stage's
name ("Reading armadillo.ply…", "Preparing the solver…") and the seconds since the start.
Small files open on the GUI thread instead (:func:`in_background` says which): they take
a fraction of a second, and the caller gets the document at once.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QEvent, QObject, QRectF, Qt, QTimer, Signal
from PySide6.QtGui import QPainter, QPalette
from PySide6.QtWidgets import QApplication, QHBoxLayout, QLabel, QToolButton, QWidget

from ...core.errors import IsochorError
from ...core.io.formats import is_scenario
from ...core.scenario.document import Scenario
from ...core.scenario.problem import ModelLoader
from ..editor.document import Document
from ..session.reader import ChildReader
from ..view.meshprep import DisplayPrep

#: a model file of at least this many bytes opens in the background (about 25k triangles
#: as an OBJ, 50k as a binary PLY: where opening on the GUI thread starts to show)
BACKGROUND_BYTES = 1_000_000
#: how often the busy bar moves and the seconds are brought up to date: seldom, because
#: every repaint recomposes the window (see :class:`BusyStrip`)
TICK_MS = 250


def in_background(path: str | Path) -> bool:
    """Whether opening ``path`` is worth a thread: the model file (a scenario's model) is
    big, or its size cannot be told from its file (a ``.gltf``'s buffers may be other
    files). False when the file cannot be read: the synchronous path says why."""
    path = Path(path).expanduser()
    try:
        if is_scenario(path):
            scenario = Scenario.read(path)
            if "path" not in scenario.model:  # a built-in shape: made, not read
                return False
            path = scenario.model_path()
        if path.suffix.lower() == ".gltf":
            return path.is_file()
        return path.stat().st_size >= BACKGROUND_BYTES
    except (IsochorError, OSError, ValueError, TypeError, KeyError):
        return False


def read_document(
    path: str | Path,
    *,
    template: bool = False,
    stage: Callable[[str], None] | None = None,
    loader: ModelLoader | None = None,
) -> Document:
    """The document of ``path`` with everything its first solve needs computed: what the
    loading thread runs (Qt-free; ``stage`` is told each stage's name as it starts,
    ``loader`` reads the model file: a :class:`~isochor.app.session.reader.ChildReader`)."""
    doc = Document.open(path, template=template, stage=stage, loader=loader)
    if stage is not None:
        stage("Preparing the solver…")
    doc.surface.prepare(doc.problem.options)
    return doc


def failure_message(path: str | Path, exc: Exception) -> str:
    """The one line shown when opening ``path`` raised ``exc``."""
    if isinstance(exc, IsochorError):
        return str(exc)
    return f"{Path(path).name}: {type(exc).__name__}: {exc}"


class BusyStrip(QWidget):
    """An indeterminate bar: a block that slides to and fro, one step a tick.

    Not Qt's busy QProgressBar, which animates at its own high rate: in a window with an
    OpenGL view every repaint recomposes the whole window, and with a software renderer
    that animation alone took half a core from the loading it shows."""

    STEPS = 12  #: ticks from one end to the other

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setFixedSize(120, 12)
        self.phase = 0

    def step(self) -> None:
        self.phase = (self.phase + 1) % (2 * self.STEPS)
        self.update()

    def paintEvent(self, _ev) -> None:
        pal = self.palette()
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        p.setPen(Qt.PenStyle.NoPen)
        r = QRectF(self.rect()).adjusted(0.5, 0.5, -0.5, -0.5)
        p.setBrush(pal.color(QPalette.ColorRole.Base))
        p.drawRoundedRect(r, 3, 3)
        at = self.phase if self.phase <= self.STEPS else 2 * self.STEPS - self.phase
        width = r.width() * 0.3
        x = r.left() + (r.width() - width) * at / self.STEPS
        p.setBrush(pal.color(QPalette.ColorRole.Highlight))
        p.drawRoundedRect(QRectF(x, r.top(), width, r.height()), 3, 3)
        p.end()


class LoadingBar(QWidget):
    """What the status bar shows while a file loads: the stage, the seconds, a busy bar
    and Cancel."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("loading")
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 4, 0)
        row.setSpacing(6)
        self.label = QLabel()
        self.bar = BusyStrip()
        self.cancel = QToolButton()
        self.cancel.setText("Cancel")
        self.cancel.setToolTip("Stop opening the file and keep this one (Esc)")
        self.cancel.setAutoRaise(True)
        # no taller than the status bar's own line: showing the bar must not resize the
        # window's view (which would draw the scene again)
        self.setFixedHeight(16)
        self.cancel.setMaximumHeight(16)
        row.addWidget(self.label)
        row.addWidget(self.bar)
        row.addWidget(self.cancel)
        self.stage = ""
        self.started = time.monotonic()
        self.timer = QTimer(self)
        self.timer.setInterval(TICK_MS)
        self.timer.timeout.connect(self._tick)
        self.hide()

    def begin(self, stage: str) -> None:
        self.started = time.monotonic()
        self.set_stage(stage)
        self.timer.start()
        self.show()

    def set_stage(self, stage: str) -> None:
        self.stage = stage
        self._show()

    def end(self) -> None:
        self.timer.stop()
        self.hide()

    def _tick(self) -> None:
        self.bar.step()
        self._show()

    def _show(self) -> None:
        text = f"{self.stage}  {time.monotonic() - self.started:.0f} s"
        if text != self.label.text():
            self.label.setText(text)


class Gate:
    """Whether the loader may still be signalled (plain Python: it outlives the QObject)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.closed = False

    def close(self, *_args) -> None:
        with self.lock:
            self.closed = True


class Loader(QObject):
    """The background opening of one window.

    ``deliver(document, mark, prep)`` gets the finished document (``mark``: what :meth:`start`
    was given, to tell whether the user edited meanwhile; ``prep``: the view's arrays for it,
    a :class:`~isochor.app.view.meshprep.DisplayPrep`), ``fail(message)`` the one-line
    message of a failure; both on the GUI thread, and only for the newest load not
    cancelled.

    Signals (internal: the thread's reports, queued to the GUI thread; generation first)
    ---------------------------------------------------------------------------------------
    staged(int, str) : a stage began
    loaded(int, object) : the document is ready
    failed(int, str) : the load raised; the message to show
    """

    staged = Signal(int, str)
    loaded = Signal(int, object)
    failed = Signal(int, str)

    def __init__(
        self,
        window: QWidget,
        deliver: Callable[[Document, object, DisplayPrep], None],
        fail: Callable[[str], None],
    ) -> None:
        super().__init__(window)
        self.win = window
        self._deliver = deliver
        self._fail = fail
        self.generation = 0  #: the id of the newest load (running or not)
        self._running: int | None = None  # the id whose result counts, if any
        self._mark: object = None
        self._reader: ChildReader | None = None
        self.threads: list[threading.Thread] = []  #: the threads not yet ended
        self.discarded = 0  #: reports of cancelled or replaced loads dropped (tests read it)
        self._gate = Gate()
        self.bar = LoadingBar()
        self.bar.cancel.clicked.connect(self.cancel)
        window.statusBar().addPermanentWidget(self.bar)
        self.staged.connect(self._on_staged)
        self.loaded.connect(self._on_loaded)
        self.failed.connect(self._on_failed)
        self.destroyed.connect(self._gate.close)
        # a child process still reading must not outlive the application
        QApplication.instance().aboutToQuit.connect(self._quit)

    def busy(self) -> bool:
        """A load runs whose result will be shown."""
        return self._running is not None

    def start(self, path: str | Path, *, template: bool = False, mark: object = None) -> int:
        """Cancel the running load, if any, and start reading ``path``; returns its id."""
        self.cancel(quiet=True)
        self.generation += 1
        gen = self._running = self.generation
        self._mark = mark
        path = Path(path)
        self._reader = ChildReader()
        thread = threading.Thread(
            target=self._run,
            args=(gen, path, template, self._reader),
            name=f"isochor-open-{gen}",
            daemon=True,
        )
        self.threads = [t for t in self.threads if t.is_alive()] + [thread]
        self.bar.begin(f"Opening {path.name}…")
        QApplication.instance().installEventFilter(self)
        thread.start()
        return gen

    def cancel(self, quiet: bool = False) -> bool:
        """Stop waiting for the running load (its thread ends on its own, unheard).
        Returns True when one was running."""
        if self._running is None:
            return False
        self._end()
        if not quiet:
            self.win.statusBar().showMessage("Opening cancelled.", 4000)
        return True

    def _end(self) -> None:
        if self._reader is not None:
            self._reader.kill()  # (a child still reading is of no use any more)
            self._reader = None
        self._running = None
        self._mark = None
        self.bar.end()
        QApplication.instance().removeEventFilter(self)

    def _quit(self) -> None:
        if self._reader is not None:
            self._reader.kill()

    # -- the loading thread ------------------------------------------------------------------
    def _run(self, gen: int, path: Path, template: bool, reader: ChildReader) -> None:
        def stage(name: str) -> None:
            self._emit("st", gen, name)

        try:
            doc = read_document(path, template=template, stage=stage, loader=reader)
            stage("Preparing the view…")
            # the view's arrays too (draw order, shading, normals: 0.5-0.75 s of the GUI
            # thread for the 346k armadillo); the GUI thread only makes the VTK objects
            prep = DisplayPrep.of(doc.surface, doc.view_nodes())
        except Exception as exc:  # every failure becomes the message shown
            self._emit("failed", gen, failure_message(path, exc))
        else:
            self._emit("loaded", gen, (doc, prep))

    def _emit(self, what: str, gen: int, payload) -> None:
        with self._gate.lock:  # never into a deleted object
            if self._gate.closed:
                return
            signal = {"st": self.staged, "loaded": self.loaded, "failed": self.failed}[what]
            with contextlib.suppress(RuntimeError):  # the window went away meanwhile
                signal.emit(gen, payload)

    # -- back on the GUI thread ------------------------------------------------------------------
    def _current(self, gen: int) -> bool:
        if gen != self._running:
            self.discarded += 1
            return False
        return True

    def _on_staged(self, gen: int, stage: str) -> None:
        if gen == self._running:
            self.bar.set_stage(stage)

    def _on_loaded(self, gen: int, loaded: tuple[Document, DisplayPrep]) -> None:
        if not self._current(gen):
            return
        mark = self._mark
        doc, prep = loaded
        self.bar.set_stage("Showing the model…")
        self.bar.repaint()  # (drawing the scene holds this thread a moment)
        try:
            self._deliver(doc, mark, prep)
        finally:
            self._end()

    def _on_failed(self, gen: int, message: str) -> None:
        if not self._current(gen):
            return
        self._end()
        self._fail(message)

    def eventFilter(self, obj, ev) -> bool:
        """Esc in the window cancels the load (but a drag's own Esc comes first)."""
        if (
            ev.type() == QEvent.Type.KeyPress
            and ev.key() == Qt.Key.Key_Escape
            and isinstance(obj, QWidget)
            and obj.window() is self.win
            and getattr(self.win.session.document, "drag", None) is None
        ):
            self.cancel()
            return True
        return False
