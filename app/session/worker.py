"""The solver worker: iterates the core's solve generator on a background thread.

The thread only iterates the generator and emits Qt signals carrying the immutable
``Progress`` records and the final ``SolveResult``; it never touches a widget, VTK or
pyvista. Signals cross to the GUI thread as queued events.

Every solve has a generation id, carried by each signal. Starting a solve stops the one
before it: a stop flag is set, which the thread checks between records, and the thread
then closes the generator itself (a generator must be closed by the thread running it).
The flag is set under the same lock the thread holds while it emits, so once
:meth:`SolveWorker.stop` returns, the stopped solve emits nothing more; records it emitted
earlier may still be queued, and the receiver drops them by their generation id.

While the window draws a frame it *holds* the worker (:meth:`SolveWorker.hold`): the
thread waits before its next step until the frame is drawn (:meth:`SolveWorker.release`),
at most :data:`HOLD_LIMIT` seconds. A software renderer draws on every core, and a solver
step running meanwhile would make the frame, a stall of the window, last longer; so the
window also puts a frame off while a step runs (:meth:`SolveWorker.stepping_now`), and the
frame scheduler gives the solver its time between frames. (The thread marks its step
before it looks at the gate, the window clears the gate before it looks at the mark: one
of them always sees the other.)
"""

from __future__ import annotations

import sys
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
from PySide6.QtCore import QObject, Signal

from ...core.errors import IsochorError
from ...core.goal.spec import Goal
from ...core.scenario.problem import Problem

#: a held worker waits at most this long for :meth:`SolveWorker.release`, seconds
HOLD_LIMIT = 0.25


#: closing a window waits this long for its stopped solver threads, seconds: a step ends at
#: once, a long one (a big model's first solve sets up its levels: seconds under load) is
#: not waited for; it ends on its own, emitting nothing (it was 0.5 s, twice: the timeline's
#: solver too, a quit's longest freeze)
SHUTDOWN_WAIT = 0.1


class SolveJob:
    """One solve: the generator ``make()`` makes, iterated by :meth:`run` on a thread of its
    own (``thread``), its records emitted by the ``worker``'s signals with ``generation``.

    :meth:`run` is the thread's whole body; called on the calling thread instead (a test),
    it runs the same solve synchronously. :meth:`stop` may come from any thread: nothing is
    emitted after it returns.
    """

    def __init__(self, worker: SolveWorker, generation: int, make: Callable) -> None:
        self.worker = worker
        self.generation = generation
        self.make = make
        self.stop_flag = threading.Event()
        self.lock = threading.Lock()
        self.thread = threading.Thread(
            target=self.run, name=f"isochor-solve-{generation}", daemon=True
        )

    def stop(self) -> None:
        with self.lock:
            self.stop_flag.set()

    def _emit(self, signal, payload) -> bool:
        with self.lock:
            if self.stop_flag.is_set():
                return False
            signal.emit(self.generation, payload)
            return True

    def run(self) -> None:
        w = self.worker
        try:
            gen = self.make()
            try:
                while not self.stop_flag.is_set():
                    free = w.gate.wait(HOLD_LIMIT)  # (the window draws a frame)
                    with w.stepping():
                        if free and not w.gate.is_set():
                            continue  # a frame began meanwhile: it draws first
                        try:
                            record = next(gen)
                        except StopIteration as stop:
                            self._emit(w.finished, stop.value)
                            return
                    self._emit(w.progress, record)
            finally:
                gen.close()  # on this thread, which is the one running it
        except IsochorError as exc:
            self._emit(w.failed, str(exc))
        except Exception as exc:
            traceback.print_exc(file=sys.stderr)
            self._emit(w.failed, f"The solver failed unexpectedly: {type(exc).__name__}: {exc}")
        finally:
            self.make = None  # drop the references to the problem


class SolveWorker(QObject):
    """Runs one solve at a time in the background.

    Signals (all carry the generation id first)
    -------------------------------------------
    progress(int, Progress) : every record the generator yields
    finished(int, SolveResult) : the generator returned
    failed(int, str) : the solve raised; the message is meant for a dialog
    """

    progress = Signal(int, object)
    finished = Signal(int, object)
    failed = Signal(int, str)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._generation = 0
        self._job: SolveJob | None = None
        self._stopped: list[SolveJob] = []
        self.gate = threading.Event()  #: set: the solver may step; clear: held
        self.gate.set()
        self._stepping = 0
        self._count_lock = threading.Lock()

    def hold(self) -> None:
        """The solver waits before its next step until :meth:`release` (or
        :data:`HOLD_LIMIT` seconds): the window draws a frame meanwhile."""
        self.gate.clear()

    def release(self) -> None:
        self.gate.set()

    @contextmanager
    def held(self) -> Iterator[None]:
        """:meth:`hold` for the duration of a ``with`` block; inside a hold already (a
        frame's paint), it leaves the release to the outer one."""
        outer = not self.gate.is_set()
        self.hold()
        try:
            yield
        finally:
            if not outer:
                self.release()

    def stepping_now(self) -> bool:
        """A solver thread is inside a step (of any job, a stopped one's last included)."""
        return self._stepping > 0

    @contextmanager
    def stepping(self) -> Iterator[None]:
        """A solver thread's step (see :meth:`stepping_now`)."""
        with self._count_lock:
            self._stepping += 1
        try:
            yield
        finally:
            with self._count_lock:
                self._stepping -= 1

    @property
    def generation(self) -> int:
        """The id of the newest solve (running or not)."""
        return self._generation

    def is_running(self) -> bool:
        job = self._job
        return job is not None and job.thread.is_alive() and not job.stop_flag.is_set()

    def start(
        self,
        problem: Problem,
        nodes: np.ndarray,
        fixed: np.ndarray,
        *,
        goal: Goal | None = None,
        handles=(),
        live: bool = False,
        near: bool = False,
    ) -> int:
        """Stop the running solve and start a new one of ``problem`` (through
        :meth:`isochor.core.scenario.problem.Problem.solve`); returns its generation id.

        ``fixed`` is (n,) bool (whole nodes) or (n, 3) bool (coordinates); ``goal`` is what
        to hold (by default the problem's); ``handles`` are the surface
        handles (:class:`isochor.core.goal.handles.Handle`); ``live``: a live drag's frame,
        solved on a coarse level only and never on the full mesh (its result is a
        ``preview``, see :func:`isochor.core.solve.multilevel.solve`); ``near``: ``nodes`` are the
        last frame of a live drag, so the solve starts on the level that agrees with the
        full mesh there (see the same)."""
        nodes = np.array(nodes, dtype=np.float64)
        fixed = np.array(fixed, dtype=bool)
        handles = tuple(handles)
        live, near = bool(live), bool(near)

        def make():
            return problem.solve(nodes, fixed, goal=goal, handles=handles, live=live, near=near)

        return self.run(make)

    def run(self, make: Callable) -> int:
        """Stop the running job and iterate ``make()``, any generator (the frames of a
        timeline, :func:`isochor.core.scenario.sequence.solve_sequence`), on a new thread: what it
        yields comes as ``progress``, what it returns as ``finished``. Returns the
        generation id."""
        self.stop()
        self._generation += 1
        job = SolveJob(self, self._generation, make)
        self._job = job
        job.thread.start()
        return self._generation

    def stop(self) -> None:
        """Stop the running solve; it emits nothing after this returns."""
        job, self._job = self._job, None
        if job is not None:
            job.stop()
            self._stopped.append(job)
        self._stopped = [j for j in self._stopped if j.thread.is_alive()]

    def shutdown(self, timeout: float = SHUTDOWN_WAIT) -> bool:
        """Stop everything and wait up to ``timeout`` seconds in total for the threads.

        Returns True when every thread ended. A thread still inside a long step ends on
        its own after that step, emitting nothing (it is a daemon thread)."""
        import time

        self.release()
        self.stop()
        deadline = time.monotonic() + timeout
        for job in self._stopped:
            job.thread.join(max(0.0, deadline - time.monotonic()))
        self._stopped = [j for j in self._stopped if j.thread.is_alive()]
        return not self._stopped
