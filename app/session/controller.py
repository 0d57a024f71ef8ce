"""The editing session: the document, the undo stack, the solver worker and frame scheduling.

:class:`EditorSession` is a QObject with no widgets. The window calls its methods for what the
user does and draws what its signals say; the document (Qt-free) holds the edit rules.

Data flow. An edit is a :class:`~isochor.app.editor.document.Edit` from one of the document's rules;
:meth:`EditorSession.commit` pushes it as one undo command, which makes the new state cell
current. Every change of the current cell (edit, undo, redo) arrives here as the document's
``"state"`` event: the running solve is stopped and, when "preserve volume" is on and the
state was never solved, a new solve starts from it. Progress records arrive by queued
signals; the newest is kept and a frame timer hands it to the window, so the view redraws at
most once per frame however fast records come. Records of any solve but the accepted one are
dropped by their generation id, so a stale result never overwrites a newer state.

Frames and the solver share two cores with a software renderer that uses both. A frame is
measured whole (the window deforms, shades and renders it before ``frameReady`` returns:
``frame_cost``); while a solve runs the next frame waits a share of that after the frame
ends (``SOLVER_SHARE``, ``LIVE_SHARE`` for a live drag's previews). During a frame the
solver is held between steps, and a frame waits (briefly) for a running step to end
(:mod:`isochor.app.session.worker`).
"""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtGui import QUndoStack

from ..editor.document import Document, Edit, SolveSummary, StateCell, describe_status
from .commands import EditCommand
from .drag import DragHost, SessionDrag
from .worker import SolveWorker

FRAME_MS = 16  #: the redraw timer: at most one redraw per frame (~60 Hz)
#: while a solve runs, the next frame waits this fraction of what the last one cost (its
#: deformation, shading and render), at least FRAME_MS: the solver's share of the time;
#: a live drag's preview solves need little (a few ms each), the view more
SOLVER_SHARE, LIVE_SHARE = 0.5, 0.25
#: Python's thread switch interval while a window runs, seconds (the default is 0.005):
#: the GUI thread gets the GIL back from the solver thread this soon after asking for it;
#: it asks at every call into Qt or VTK that released it, so the default made each frame
#: wait for the GIL many times over
SWITCH_INTERVAL = 0.0005
#: a frame is put off while a solver step runs (it would share the cores), by this many ms
#: at a time, at most DEFER_LIMIT_MS in all (the solver starts no new step meanwhile)
DEFER_MS, DEFER_LIMIT_MS = 3, 150


class EditorSession(QObject):
    """The editing session of one window.

    Composed of parts that own their state: the :class:`SolveWorker` (``worker``), the
    undo stack (``undo_stack``) and the drags with their live previews (``drags``, a
    :class:`~isochor.app.session.drag.SessionDrag`, which reaches the session through a
    :class:`~isochor.app.session.drag.DragHost` only). The drag methods the window calls
    (:meth:`begin_drag`, :meth:`drag_to`, :meth:`finish_drag`, ...) are the part's.

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
    idle() : nothing runs and the last frame was handed out (and drawn: ``view_busy``)
    failed(str) : the solver stopped with this message
    flushed() : :meth:`flush` handed out the pending frame: the view finishes drawing it
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
    flushed = Signal()

    def __init__(self, document: Document, parent: QObject | None = None) -> None:
        super().__init__(parent)
        sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL))
        self.document = document
        self.undo_stack = QUndoStack(self)
        self.worker = SolveWorker(self)
        self.worker.progress.connect(self._on_progress)
        self.worker.finished.connect(self._on_finished)
        self.worker.failed.connect(self._on_failed)
        #: seconds the window took to draw the last frame, whole (deform, shade, render)
        self.frame_cost = 0.0
        #: the window is still drawing the last frame (a big model's full mesh): no idle
        self.view_busy: Callable[[], bool] = lambda: False
        self.activity = "idle"  #: idle, solving, dragging, stopped or failed
        self._accept_gen: int | None = None  # the only generation whose records count
        self._solving_cell: StateCell | None = None
        self._live_preview = False  # the accepted solve is a live-drag preview
        self.last_solve_near = False  #: the last solve of a state started near (tests)
        self._pending: tuple[np.ndarray, object] | None = None  # the next frame
        self._view_ready = False  # the window drew once: solves may start
        self._deferred = False
        self._idle_owed = False
        self._shut = False
        self._put_off_since: float | None = None  # the pending frame was put off since
        # what the tests read
        self.frames_by_generation: dict[int, int] = {}
        self.accepted_log: deque[tuple[int, str]] = deque(maxlen=50_000)
        self.dropped = 0
        #: the nodes, (n, 3) fixed coordinates and goal of the last solve of a state
        self.last_solve_input: tuple[np.ndarray, np.ndarray, object] | None = None
        self.last_result = None

        self.frame_timer = QTimer(self)  # single shot, restarted after each frame
        self.frame_timer.setSingleShot(True)
        self.frame_timer.setInterval(FRAME_MS)
        self.frame_timer.timeout.connect(lambda: self._on_frame())
        self.frame_timer.start()
        self.drags = SessionDrag(
            DragHost(
                document=lambda: self.document,
                stop=self._stop,
                show=self._show,
                preview=self._preview,
                commit=self.commit,
                activity=self._set_activity,
                told=self.statusChanged.emit,
            ),
            self,
        )
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
        document.set_preserve(preserve)
        document.subscribe(lambda event, doc=document: self._on_document(doc, event))
        _prepare(document)
        self.undo_stack.clear()
        self.undo_stack.setClean()
        self.activity = "idle"
        self.documentLoaded.emit()
        self._pending = (document.view_nodes(), None)
        self._solve_if_needed()

    def set_live(self, on: bool) -> None:
        """Solve while a node is dragged (on), or only when the drag ends."""
        self.live = bool(on)

    def watch_view(self, busy: Callable[[], bool]) -> None:
        """``busy()`` says the window is still drawing the last frame (a big model's full
        mesh): ``idle`` waits for it."""
        self.view_busy = busy

    def frame_drawn(self, seconds: float) -> None:
        """The window drew the last frame in ``seconds``, whole (deform, shade, render):
        the next frame leaves the solver a share of that (``frame_cost``)."""
        self.frame_cost = float(seconds)

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

    # -- the drags (the part's) ---------------------------------------------------------------
    @property
    def live(self) -> bool:
        """Solve while dragging (live previews)."""
        return self.drags.live

    @live.setter
    def live(self, on: bool) -> None:
        self.drags.set_live(on)

    def begin_drag(self, verb: str = "Move") -> bool:
        """Start a drag (or a grab, rotate or scale: ``verb``) of the selection."""
        return self.drags.begin(verb)

    def begin_handle_drag(self, index: int | None = None, at=None) -> bool:
        """Start dragging handle ``index``'s target, or a new handle on the rest point
        ``at``."""
        return self.drags.begin_handle(index, at)

    def drag_to(self, delta) -> None:
        """The dragged nodes moved by ``delta`` (3,) from where the drag started."""
        self.drags.move(delta)

    def drag_transform(self, matrix) -> None:
        """The dragged nodes mapped by the (4, 4) affine ``matrix`` from where they were."""
        self.drags.transform(matrix)

    def finish_drag(self) -> None:
        """The drag ends: its edit becomes one undo step."""
        self.drags.finish()

    def cancel_drag(self) -> None:
        """The drag ends without an edit."""
        self.drags.cancel()

    def drag_text(self, lock: str = "") -> str:
        """What the view says while a drag runs ("" with none)."""
        return self.drags.text(lock)

    def _set_activity(self, activity: str) -> None:
        self.activity = activity

    def _show(self, nodes: np.ndarray) -> None:
        self._pending = (nodes, None)

    def _preview(self, st, nodes, fixed, handles) -> None:
        """A live drag's preview solve (solved on a coarse level only; keeps no state)."""
        self._solving_cell = None
        self._begin(st, nodes, fixed, handles, live=True)

    # -- edits that are not one rule ---------------------------------------------------------
    def set_preserve(self, on: bool) -> None:
        """Turn the volume constraint on or off (off: plain FFD, nothing is solved)."""
        if bool(on) == self.document.preserve:
            return
        self.document.set_preserve(bool(on))
        if not on:
            self._stop()
        self.document.show_live(None)
        self._pending = (self.document.view_nodes(), None)
        self._solve_if_needed()

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
        self.last_solve_input = (np.array(st.nodes), np.array(st.fixed_axes), st.goal)
        # after a live drag the nodes are its last frame: start near them
        self.last_solve_near = self.drags.take_near()
        self._begin(st, st.nodes, st.fixed_axes, st.handles, near=self.last_solve_near)

    def _begin(self, st, nodes, fixed, handles=(), live: bool = False, near=False) -> None:
        """Solve ``nodes`` with the (n, 3) ``fixed`` coordinates and the ``handles``, to
        ``st``'s goal; ``live``: a live drag's preview (solved on a coarse level only);
        ``near``: the nodes are a live drag's last frame."""
        self._deferred = False
        gen = self.worker.start(
            st.problem, nodes, fixed, goal=st.goal, handles=handles, live=live, near=near
        )
        self._accept_gen = gen
        self._live_preview = live
        if not live:
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
        self._live_preview = False
        self.drags.stop_previews()
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
        self.document.show_live(nodes)
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
            self.document.show_live(np.array(result.nodes))
            if drag is not None:
                self._pending = (drag.with_dragged(result.nodes), None)
            self.solveDone.emit(gen, True)
            return
        cell, self._solving_cell = self._solving_cell, None
        assert cell is not None, "an accepted solve that is no preview solves a cell"
        self.activity = "idle"
        summary = SolveSummary.of(result, len(cell.state.surface.levels))
        self.document.record_result(cell, result.nodes, summary)
        self._pending = (self.document.view_nodes(), None)
        if not self._shut:  # the result is drawn at the next turn, not after the solver's share
            self.frame_timer.start(0)
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
    def _on_frame(self, now: bool = False) -> None:
        """The frame timer: hand out the newest pending nodes, if any (once a frame);
        ``now``: without putting it off for a running solver step."""
        wait = FRAME_MS
        if self._pending is not None:
            # the frame gets the cores, the solver the time after it: no new step now, and
            # a step that runs ends before the frame is drawn (or DEFER_LIMIT_MS passed)
            self.worker.hold()
            if not now and self._put_off():
                if not self._shut:
                    self.frame_timer.start(DEFER_MS)
                return
            self._put_off_since = None
            nodes, record = self._pending
            self._pending = None
            try:
                self._hand_out(nodes, record)
            finally:
                self.worker.release()
            # A software renderer takes both cores for a frame: while a solve runs, the
            # next frame waits a share of what this one cost, counted from its end.
            if self._accept_gen is not None:
                share = LIVE_SHARE if self._live_preview else SOLVER_SHARE
                wait = max(FRAME_MS, int(1000 * share * self.frame_cost))
        else:
            self.worker.release()
        if self._idle_owed and self._pending is None and not self.busy() and not self.view_busy():
            self._idle_owed = False
            self.idle.emit()
        if not self._shut:
            self.frame_timer.start(wait)

    def _put_off(self) -> bool:
        """Put the frame off a little: a solver step runs (see
        :mod:`isochor.app.session.worker`)."""
        if not self.worker.stepping_now():
            return False
        t = time.perf_counter()
        if self._put_off_since is None:
            self._put_off_since = t
        return t - self._put_off_since < DEFER_LIMIT_MS / 1000

    def _hand_out(self, nodes, record) -> None:
        if len(nodes) == self.document.state.lattice.n_nodes:
            gen = self._accept_gen
            if gen is not None and record is not None:
                self.frames_by_generation[gen] = self.frames_by_generation.get(gen, 0) + 1
            self.frameReady.emit(nodes, record)  # drawn and rendered: frame_cost

    @property
    def frame_pending(self) -> bool:
        """A frame waits to be handed out (the view has not drawn the newest nodes yet)."""
        return self._pending is not None

    def redraw(self) -> None:
        """Draw the current state again at the next frame (the timeline changed the view)."""
        self._pending = (self.document.base_nodes(), None)

    def flush(self) -> None:
        """Hand out the pending frame now and have it drawn whole (before a screenshot)."""
        self._on_frame(now=True)
        self.flushed.emit()

    def shutdown(self) -> None:
        """Stop the timers and the worker (waits at most ``worker.SHUTDOWN_WAIT`` for it)."""
        self._shut = True
        self.frame_timer.stop()
        self._stop()
        self.worker.shutdown()


def _prepare(document: Document) -> None:
    """Compute on the GUI thread what the display needs: the full level's basis and the
    spring network. The solver thread computes the other levels lazily."""
    surface = document.surface
    surface.level(-1)
    _ = surface.springs
    _ = surface.bodies  # the window offers "Each body" only for several
