"""Signals for the command line: Ctrl-C, ``kill`` (SIGTERM) and a closed terminal (SIGHUP)
stop a run the same way, with one line, exit status 128 + the signal, and nothing written.

**The handler only records.** :func:`install` runs at the very top of
:mod:`isochor.app.cli.main`, before its other imports, and from then on a signal is
*recorded* (:attr:`State.pending`), never raised by the handler itself: an exception raised
from a signal handler lands wherever Python happens to be (an importlib callback, a
``__del__``, a library's ``try: ... except BaseException``, numba loading its kernels),
where it can be dropped, printed as "Exception ignored", or leave a library half-initialised.
The run instead asks at its safe points (:func:`check`): when it starts (:func:`arm`),
between its phases, at every step of the solve, and last before anything is written or
renamed (:func:`commit`). So a signal is never lost: it ends the run at the next safe point
with 128 + the signal, one line, and nothing written.

:func:`commit` ends the checking when the outputs start to be renamed into place: from then
on the run completes (all or none). A signal that arrives during the renames is answered
when they are done (:func:`finish`): the line then says every output was written. After
that the run's status is decided and later signals are ignored.

**A long C call cannot hold the answer.** A safe point comes only between Python steps,
and one step of a big lattice's solve can be a minute inside SciPy's sparse LU. The solve
therefore runs on a worker thread (:func:`run_answering`) while the main thread waits and
looks for a signal every :data:`POLL` seconds: a signal is answered then, with the same
line and status, however long the worker's call goes on (SuperLU and NumPy's big loops
release the GIL). The abandoned worker stops at its next safe point (:func:`check` raises
there too) and never writes: the outputs are written by the main thread after the solve,
and the process ends without waiting for the worker (``entry``'s ``leave_now``).

A signal the parent process ignores (``nohup``, a background job) stays ignored.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable
from contextlib import suppress
from typing import TypeVar

T = TypeVar("T")

#: how often the main thread looks for a signal while a worker runs (:func:`run_answering`)
POLL = 0.05

SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal (``signum``)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def status(self) -> int:
        """The exit status by the shell's convention: 128 + the signal number."""
        return 128 + self.signum


class State:
    """What the run has received and where it stands.

    A plain class, not a dataclass: this module runs before the handlers are installed,
    so it imports nothing heavier than ``signal`` and ``contextlib``."""

    #: :func:`check` raises a recorded signal (from :func:`arm` to :func:`commit`)
    armed = False
    #: the first signal received and not yet answered
    pending: int | None = None
    #: the signal :func:`check` raised: the run ends as interrupted by it, even if its
    #: exception comes out as another one
    raised: int | None = None
    previous: dict[int, object] = {}
    #: :func:`commit` has run: from then on the run completes
    committed = False
    #: :func:`finish` has run: the status is decided, signals are ignored
    done = False
    #: ``sys.unraisablehook`` before :func:`install`
    previous_hook = None
    #: the main thread answered a signal and left the worker of :func:`run_answering`:
    #: the worker's next :func:`check` stops it
    abandoned = False


state = State()


def _handler(signum: int, frame) -> None:
    """Record the signal; never raise (see the module's text). The handler stays
    installed: a second signal is recorded too (the first one counts)."""
    if state.pending is None and not state.done:
        state.pending = signum


def _unraisable(unraisable) -> None:
    """``sys.unraisablehook``: an interrupt raised where Python ignores exceptions is not
    printed (it is recorded, and :func:`commit` answers it); anything else goes to the
    hook there was."""
    if isinstance(unraisable.exc_value, Interrupted):
        return
    (state.previous_hook or sys.__unraisablehook__)(unraisable)


def install() -> None:
    """Catch SIGINT, SIGTERM and SIGHUP (only noted until :func:`arm`)."""
    if sys.unraisablehook is not _unraisable:
        state.previous_hook, sys.unraisablehook = sys.unraisablehook, _unraisable
    for sig in SIGNALS:
        try:
            current = signal.getsignal(sig)
            if current is signal.SIG_IGN:
                continue
            state.previous.setdefault(sig, current)
            signal.signal(sig, _handler)
        except (ValueError, OSError):  # not the main thread, or no such signal here
            pass


def arm() -> None:
    """A run starts: from now on :func:`check` raises a recorded signal; one received
    before (while the program was imported) is raised now."""
    state.raised, state.committed, state.done = None, False, False
    state.abandoned = False
    state.armed = True
    check()


_LOCK = threading.Lock()


def check() -> None:
    """A safe point: raise :class:`Interrupted` if a signal was received (and the run is
    armed and not committed); on an abandoned worker thread, always."""
    with _LOCK:  # the main thread and a worker: one of them raises a signal, once
        if state.abandoned and threading.current_thread() is not threading.main_thread():
            raise Interrupted(state.raised or signal.SIGTERM)
        signum = state.pending
        if signum is not None and state.armed and not state.committed:
            state.armed = False
            state.raised, state.pending = signum, None
            raise Interrupted(signum)


def run_answering(work: Callable[[], T]) -> T:
    """``work()`` on a worker thread, this (the main) thread waiting and answering a
    signal within :data:`POLL` seconds (see the module's text): :class:`Interrupted` is
    raised here then, the worker left to stop at its next :func:`check`. What ``work``
    returns or raises comes back here. From any other thread, ``work()`` runs at once."""
    if threading.current_thread() is not threading.main_thread():
        return work()
    box: dict[str, object] = {}

    def target() -> None:
        try:
            box["value"] = work()
        except BaseException as exc:  # handed to the main thread, raised there
            box["error"] = exc

    worker = threading.Thread(target=target, name="isochor-solve", daemon=True)
    worker.start()
    try:
        while worker.is_alive():
            worker.join(POLL)
            check()
    except BaseException:
        state.abandoned = True
        raise
    if "error" in box:
        raise box["error"]  # type: ignore[misc]
    return box["value"]  # type: ignore[return-value]


def hold() -> None:
    """From now on signals are only recorded: the run goes on to its end."""
    state.armed = False


def commit() -> None:
    """The last step before anything is written or renamed: a signal received since
    :func:`arm` is raised now; from then on signals are only recorded and the run goes on
    to its end (see :func:`finish`). Only the first call checks."""
    if state.committed:
        return
    check()
    state.armed, state.committed = False, True


def finish() -> int | None:
    """The outputs are in place: the signal received since :func:`commit` (during the
    renames), if any, which the caller answers with its line; from now on signals are
    ignored."""
    state.done, state.armed = True, False
    signum, state.pending = state.pending, None
    return signum


def answer_late(signum: int, paths) -> int:
    """Print the one line for a signal received while the outputs were renamed into place
    (they were all written: the renames complete, all or none); its exit status."""
    late = Interrupted(signum)
    names = ", ".join(str(p) for p in paths)
    print(
        f"isochor: interrupted ({late.name}) while the outputs were put in place; all of "
        f"them were written: {names}",
        file=sys.stderr,
    )
    return late.status


def ignore() -> None:
    """Ignore the signals from now on (the program is on its way out)."""
    state.armed = False
    for sig in SIGNALS:
        with suppress(ValueError, OSError):
            signal.signal(sig, signal.SIG_IGN)


def release() -> None:
    """Give the signals back to what they were before :func:`install` (the editor keeps
    Python's default handling)."""
    for sig, previous in state.previous.items():
        with suppress(ValueError, OSError, TypeError):
            signal.signal(sig, previous)
    state.previous.clear()
    if sys.unraisablehook is _unraisable:
        sys.unraisablehook, state.previous_hook = state.previous_hook, None
    state.armed = state.committed = state.done = state.abandoned = False
    state.pending = state.raised = None
