"""The editing session: the document, the undo stack, the solver worker and frame scheduling.

:class:`EditorSession` is a QObject with no widgets. The window calls its methods for what the
user does and draws what its signals say; the document (Qt-free) holds the edit rules.

Data flow. An edit is a :class:`~isochor.app.document.Edit` from one of the document's rules;
:meth:`EditorSession.commit` pushes it as one undo command, which makes the new state cell
current. Every change of the current cell (edit, undo, redo) arrives here as the document's
``"state"`` event: the running solve is stopped and, when "preserve volume" is on and the
state was never solved, a new solve starts from it. Progress records arrive by queued
signals; the newest is kept and a frame timer hands it to the window, so the view redraws at
most once per frame however fast records come. Records of any solve but the accepted one are
dropped by their generation id, so a stale result never overwrites a newer state.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtGui import QUndoStack

from .commands import EditCommand
from .document import Document, Edit, SolveSummary, StateCell, describe_status, plural
from .worker import SolveWorker

FRAME_MS = 16  #: the redraw timer: at most one redraw per frame (~60 Hz)
LIVE_MS = 40  #: during a live drag, restart the preview solve at most this often


class EditorSession(QObject):
    """The editing session of one window.

    Signals
    -------
    documentLoaded() : a new document: rebuild the scene and frame the camera
    sceneChanged() : the lattice changed (an edit, undo or redo): rebuild, keep the camera
    stateChanged() : the current state changed (flags, target, result)
    selectionChanged() : the selected nodes changed
    statusChanged() : what :meth:`status` says changed
    frameReady(object, object) : draw these nodes; the progress record or None
    solveStarted() : a solve (or live preview) started
    recordAccepted(object) : a progress record of the accepted solve
    solveDone(int, bool) : an accepted solve ended (generation, success)
    idle() : nothing runs and the last frame was handed out
    failed(str) : the solver stopped with this message
    """

    documentLoaded = Signal()
    sceneChanged = Signal()
    stateChanged = Signal()
    selectionChanged = Signal()
    statusChanged = Signal()
    frameReady = Signal(object, object)
    solveStarted = Signal()
    recordAccepted = Signal(object)
    solveDone = Signal(int, bool)
    idle = Signal()
    failed = Signal(str)

    def __init__(self, document: Document, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.document = document
        self.undo_stack = QUndoStack(self)
        self.worker = SolveWorker(self)
        self.worker.progress.connect(self._on_progress)
        self.worker.finished.connect(self._on_finished)
        self.worker.failed.connect(self._on_failed)
        self.live = False  #: solve while dragging
        self.frame_cost = 0.0  #: seconds the window took to draw the last frame
        self.activity = "idle"  #: idle, solving, dragging, stopped or failed
        self._accept_gen: int | None = None  # the only generation whose records count
        self._solving_cell: StateCell | None = None
        self._live_preview = False  # the accepted solve is a live-drag preview
        self._pending: tuple[np.ndarray, object] | None = None  # the next frame
        self._view_ready = False  # the window drew once: solves may start
        self._deferred = False
        self._idle_owed = False
        # what the tests read
        self.frames_by_generation: dict[int, int] = {}
        self.accepted_log: deque[tuple[int, str]] = deque(maxlen=50_000)
        self.dropped = 0
        #: the nodes, (n, 3) fixed coordinates and goal of the last solve of a state
        self.last_solve_input: tuple[np.ndarray, np.ndarray, object] | None = None
        self.last_result = None

        self.frame_timer = QTimer(self)
        self.frame_timer.setInterval(FRAME_MS)
        self.frame_timer.timeout.connect(self._on_frame)
        self.frame_timer.start()
        self.live_timer = QTimer(self)
        self.live_timer.setSingleShot(True)
        self.live_timer.setInterval(LIVE_MS)
        self.live_timer.timeout.connect(self._live_solve)
        self.load(document)

    # -- the document ------------------------------------------------------------------------
    @property
    def state(self):
        return self.document.state

    def load(self, document: Document) -> None:
        """Edit ``document`` from now on (not undoable: the history starts afresh)."""
        self._stop()
        preserve = self.document.preserve
        self.document = document
        document.preserve = preserve
        document.subscribe(lambda event, doc=document: self._on_document(doc, event))
        _prepare(document)
        self.undo_stack.clear()
        self.undo_stack.setClean()
        self.activity = "idle"
        self.documentLoaded.emit()
        self._pending = (document.view_nodes(), None)
        self._solve_if_needed()

    def view_ready(self) -> None:
        """The window has drawn its first frame: a deferred solve may start now.

        The first frame's set-up (shader compilation in a software renderer) would
        otherwise hold up the solver thread."""
        if not self._view_ready:
            self._view_ready = True
            if self._deferred:
                self._deferred = False
                self._solve_if_needed()

    def commit(self, edit: Edit | None) -> bool:
        """Apply ``edit`` as one undo step; False when there was nothing to do."""
        if edit is None:
            return False
        before = self.document.cell
        self.undo_stack.push(EditCommand(self.document, edit.text, before, StateCell(edit.state)))
        return True

    def _on_document(self, doc: Document, event: str) -> None:
        if doc is not self.document:
            return
        if event == "selection":
            self.selectionChanged.emit()
        elif event == "scene":
            _prepare(doc)
            self.sceneChanged.emit()
        elif event == "state":
            if self._accept_gen is not None:
                self._stop()
            if self.activity == "dragging":
                self.activity = "idle"
            self._pending = (doc.view_nodes(), None)
            self.stateChanged.emit()  # (the window redraws the selection with the state)
            self._solve_if_needed()

    # -- edits that are not one rule ---------------------------------------------------------
    def set_preserve(self, on: bool) -> None:
        """Turn the volume constraint on or off (off: plain FFD, nothing is solved)."""
        if bool(on) == self.document.preserve:
            return
        self.document.preserve = bool(on)
        if not on:
            self._stop()
        self.document.live_nodes = None
        self._pending = (self.document.view_nodes(), None)
        self._solve_if_needed()

    # -- the drag ----------------------------------------------------------------------------
    def begin_drag(self, verb: str = "Move") -> bool:
        """Start a drag (or a grab, rotate or scale: ``verb``) of the selection."""
        return self._start_drag(lambda: self.document.begin_drag(verb))

    def begin_handle_drag(self, index: int | None = None, at=None) -> bool:
        """Start dragging handle ``index``'s target, or a new handle on the rest point
        ``at``; the drag's moves, finish and cancel are a node drag's."""
        return self._start_drag(lambda: self.document.begin_handle_drag(index, at))

    def _start_drag(self, begin) -> bool:
        """Stop the solve and start the drag ``begin()`` makes (False when it makes none)."""
        base = self.document.base_nodes()
        self._stop()
        self.document.live_nodes = base if self.document.preserve else None
        if begin() is None:
            return False
        self.activity = "dragging"
        self._pending = (base, None)
        self.statusChanged.emit()
        return True

    def drag_to(self, delta) -> None:
        """The dragged nodes moved by ``delta`` (3,) from where the drag started."""
        self._drag_by("move", delta)

    def drag_transform(self, matrix) -> None:
        """The dragged nodes mapped by the (4, 4) affine ``matrix`` from where they were."""
        self._drag_by("transform", matrix)

    def _drag_by(self, how: str, value) -> None:
        drag = self.document.drag
        if drag is None:
            return
        live = self._live_active()
        nodes = getattr(drag, how)(value, self.document.live_nodes if live else None)
        self._pending = (nodes, None)
        if live and not self.live_timer.isActive():
            self.live_timer.start()

    def finish_drag(self) -> None:
        self.live_timer.stop()
        self._stop()
        self._live_preview = False
        self.activity = "idle"
        self.commit(self.document.end_drag())

    def cancel_drag(self) -> None:
        drag = self.document.drag
        if drag is None:
            return
        self._stop()
        self._live_preview = False
        self.document.cancel_drag()
        self.document.set_cell(drag.before)

    def drag_text(self, lock: str = "") -> str:
        drag = self.document.drag
        if drag is None:
            return ""
        lock = f" — locked to the {lock}" if lock else ""
        what = plural(len(drag.rows)) if len(drag.rows) else "the handle"
        return f"Moving {what}{lock} — X/Y/Z lock an axis, Shift+X/Y/Z a plane, Esc cancels"

    def _live_active(self) -> bool:
        return self.live and self.document.preserve

    def _live_solve(self) -> None:
        """Restart the preview solve from the nodes on screen (free nodes where the last
        preview left them, the dragged ones under the cursor)."""
        drag = self.document.drag
        if drag is None:
            return
        base = self.document.live_nodes if self.document.live_nodes is not None else drag.nodes
        self._solving_cell = None
        self._live_preview = True
        self._begin(drag.before.state, drag.with_dragged(base), drag.fixed(), drag.handles)

    # -- solving -----------------------------------------------------------------------------
    def busy(self) -> bool:
        """A solve runs, or one waits for the first frame and will start then."""
        return self._accept_gen is not None or (self._deferred and self.document.needs_solve())

    def solve_again(self) -> bool:
        if not self.document.preserve:
            return False
        self._start_solve()
        return True

    def stop_solve(self) -> None:
        if self.busy():
            self._stop()
            self.activity = "stopped"
            self._owe_idle()

    def _solve_if_needed(self) -> None:
        if self.document.needs_solve():
            if not self._view_ready:
                self._deferred = True
                self.statusChanged.emit()
                return
            self._start_solve()
        else:
            if self.activity in ("solving", "dragging"):
                self.activity = "idle"
            self._owe_idle()

    def _start_solve(self) -> None:
        st = self.document.state
        self._solving_cell = self.document.cell
        self._live_preview = False
        self.last_solve_input = (np.array(st.nodes), np.array(st.fixed_axes), st.goal)
        self._begin(st, st.nodes, st.fixed_axes, st.handles)

    def _begin(self, st, nodes, fixed, handles=()) -> None:
        """Solve ``nodes`` with the (n, 3) ``fixed`` coordinates and the ``handles``, to
        ``st``'s goal."""
        self._deferred = False
        gen = self.worker.start(
            st.surface, nodes, fixed, goal=st.goal, options=st.problem.options, handles=handles
        )
        self._accept_gen = gen
        if not self._live_preview:
            self.activity = "solving"
        self._idle_owed = False
        self.solveStarted.emit()
        self.statusChanged.emit()

    def _stop(self) -> None:
        """Stop the running solve; its queued records will be dropped."""
        self._deferred = False
        self.worker.stop()
        self._accept_gen = None
        self._solving_cell = None
        self.live_timer.stop()
        if self.activity == "solving":
            self.activity = "idle"

    def _owe_idle(self) -> None:
        self._idle_owed = True
        self.statusChanged.emit()

    def _accepted(self, gen: int, kind: str) -> bool:
        if gen != self._accept_gen:
            self.dropped += 1
            return False
        self.accepted_log.append((gen, kind))
        return True

    def _on_progress(self, gen: int, record) -> None:
        if not self._accepted(gen, "progress"):
            return
        drag = self.document.drag
        nodes = np.array(record.nodes)
        self.document.live_nodes = nodes
        if self._live_preview and drag is not None:
            nodes = drag.with_dragged(nodes)
        self._pending = (nodes, record)
        self.recordAccepted.emit(record)

    def _on_finished(self, gen: int, result) -> None:
        if not self._accepted(gen, "finished"):
            return
        self._accept_gen = None
        self.last_result = result
        drag = self.document.drag
        if self._live_preview:  # a preview during a live drag: show it, keep no state
            self.document.live_nodes = np.array(result.nodes)
            if drag is not None:
                self._pending = (drag.with_dragged(result.nodes), None)
            self.solveDone.emit(gen, True)
            return
        cell, self._solving_cell = self._solving_cell, None
        self.activity = "idle"
        summary = SolveSummary.of(result, len(cell.state.surface.levels))
        self.document.record_result(cell, result.nodes, summary)
        self._pending = (self.document.view_nodes(), None)
        self._owe_idle()
        self.solveDone.emit(gen, bool(result.converged))

    def _on_failed(self, gen: int, message: str) -> None:
        if not self._accepted(gen, "failed"):
            return
        self._accept_gen = None
        cell, self._solving_cell = self._solving_cell, None
        live = self._live_preview
        if cell is not None and not live:
            self.document.record_result(cell, None, SolveSummary.failed(message))
            self._pending = (self.document.view_nodes(), None)
        self.activity = "failed"
        self._owe_idle()
        self.solveDone.emit(gen, False)
        if not live:
            self.failed.emit(message)

    def status(self) -> tuple[str, str, str]:
        """``(chip, tone, sentence)`` for the status bar and the Solve panel."""
        activity = "solving" if self._deferred and self.document.needs_solve() else self.activity
        return describe_status(
            self.document.state, preserve=self.document.preserve, activity=activity
        )

    # -- frames ------------------------------------------------------------------------------
    def _on_frame(self) -> None:
        """The frame timer: hand out the newest pending nodes, if any (once a frame)."""
        if self._pending is not None:
            nodes, record = self._pending
            self._pending = None
            if len(nodes) == self.document.state.lattice.n_nodes:
                gen = self._accept_gen
                if gen is not None and record is not None:
                    self.frames_by_generation[gen] = self.frames_by_generation.get(gen, 0) + 1
                self.frameReady.emit(nodes, record)
            # A software renderer can take longer than a frame and holds the GIL meanwhile:
            # while a solve runs, leave its thread more time than the last frame took.
            cost = int(1500 * self.frame_cost) if self._accept_gen is not None else 0
            self.frame_timer.setInterval(max(FRAME_MS, cost))
        if self._idle_owed and self._pending is None and not self.busy():
            self._idle_owed = False
            self.idle.emit()

    def redraw(self) -> None:
        """Draw the current state again at the next frame (the timeline changed the view)."""
        self._pending = (self.document.base_nodes(), None)

    def flush(self) -> None:
        """Hand out the pending frame now (before a screenshot)."""
        self._on_frame()

    def shutdown(self) -> None:
        """Stop the timers and the worker (waits at most half a second)."""
        self.frame_timer.stop()
        self.live_timer.stop()
        self._stop()
        self.worker.shutdown(timeout=0.5)


def _prepare(document: Document) -> None:
    """Compute on the GUI thread what the display needs: the full level's basis and the
    spring network. The solver thread computes the other levels lazily."""
    surface = document.surface
    surface.level(-1)
    _ = surface.springs
    _ = surface.bodies  # the window offers "Each body" only for several
