"""The timeline's frames solved in the background (issue 13). GUI thread only, but the
solve itself runs on a thread of its own.

:func:`isochor.core.scenario.sequence.solve_sequence` runs on its own
:class:`~isochor.app.session.worker.SolveWorker`, and only while the editing session is idle: an
edit, a drag or the session's own solve stops it (the session's worker and this one never
run together), and once the session is idle again it starts over from the first key (the
frames solved before stay in the cache and are solved again to the same nodes). Each solved
:class:`~isochor.core.scenario.sequence.Frame` reaches the GUI thread by a queued signal and
goes into the frame cache of the timeline it was solved for
(:class:`~isochor.app.editor.timeline.FrameCaches`: a change of the keys, the range, the
interpolation or the goal selects another cache, an empty one or one kept from before).
"""

from __future__ import annotations

from PySide6.QtCore import QObject, Signal

from ...core.errors import IsochorError
from ...core.scenario.sequence import solve_sequence
from ..editor.timeline import FrameCache, FrameCaches, sequence_problem
from .worker import SolveWorker


class FrameSolver(QObject):
    """The frame caches of one window and the background solve that fills them.

    Signals
    -------
    frameSolved(object) : a :class:`~isochor.core.scenario.sequence.Frame` of the current cache
    changed() : the progress changed (started, stopped, done, failed)
    """

    frameSolved = Signal(object)
    changed = Signal()

    def __init__(self, session, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.session = session
        self.caches = FrameCaches()
        self.cache: FrameCache | None = None  #: the current state's frames
        self.ready = False  #: the window drew its first frame
        self.worker = SolveWorker(self)
        self.worker.progress.connect(self._on_frame)
        self.worker.finished.connect(self._on_done)
        self.worker.failed.connect(self._on_failed)
        self._job: int | None = None  # the generation whose frames count
        self._job_cache: FrameCache | None = None
        self.runs = 0  #: solves started (the tests read it)

    @property
    def running(self) -> bool:
        return self._job is not None

    def reset(self) -> None:
        """A new document: every cache goes."""
        self.stop()
        self.caches.clear()
        self.cache = None

    def follow(self, st) -> None:
        """Make the cache of state ``st``'s timeline current (stopping a solve of another)."""
        cache = self.caches.get(st)
        if cache is not self.cache:
            self.stop()
            self.cache = cache

    def view_ready(self) -> None:
        """The window drew its first frame: the frames may be solved from now on."""
        self.ready = True
        self.schedule()

    def schedule(self) -> None:
        """Start solving the missing frames when the session is idle; stop while it is
        busy (its solve, a drag)."""
        s = self.session
        doc = s.document
        cache = self.cache
        idle = self.ready and doc.preserve and not s.busy() and doc.drag is None
        if cache is None or not idle:
            if self._job is not None:
                self.stop()
                self.changed.emit()
            return
        if self._job is not None or cache.complete or cache.failed:
            return
        try:
            problem = sequence_problem(doc.state)
        except IsochorError as exc:
            cache.fail(str(exc))
            self.changed.emit()
            return
        self._job_cache = cache
        self._job = self.worker.run(lambda: solve_sequence(problem))
        self.runs += 1
        self.changed.emit()

    def stop(self) -> None:
        if self._job is not None:
            self.worker.stop()
            self._job = self._job_cache = None

    def progress(self) -> str:
        """``"Solving frames 7/25"`` (and why it waits), or "" without keys."""
        cache = self.cache
        if cache is None:
            return ""
        if not self.session.document.preserve:
            return "Not solved: volume off"
        text = cache.progress()
        if self._job is None and not cache.complete and not cache.failed:
            if self.session.document.drag is not None:
                text += " (paused while you drag)"
            elif self.session.busy():
                text += " (paused while the edit solves)"
        return text

    def _on_frame(self, gen: int, frame) -> None:
        if gen != self._job:
            return
        self._job_cache.add(frame)
        if self._job_cache is self.cache:
            self.frameSolved.emit(frame)

    def _on_done(self, gen: int, _sequence) -> None:
        if gen != self._job:
            return
        self._job_cache.finish()
        self._job = self._job_cache = None
        self.changed.emit()

    def _on_failed(self, gen: int, message: str) -> None:
        if gen != self._job:
            return
        self._job_cache.fail(message)
        self._job = self._job_cache = None
        self.changed.emit()

    def shutdown(self) -> None:
        self.stop()
        self.worker.shutdown()  # (never waits for a long solve's end)
