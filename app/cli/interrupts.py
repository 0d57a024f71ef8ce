"""Signals for the command line: Ctrl-C, ``kill`` (SIGTERM) and a closed terminal (SIGHUP)
stop a run the same way, with one line, exit status 128 + the signal, and nothing written.

:func:`install` runs at the very top of :mod:`isochor.app.cli.main`, before its other imports.
Until :func:`arm` is called (the first thing ``main`` does inside its error handling) a
signal is only remembered; ``arm`` then raises it where it is caught. After that the first
signal raises :class:`Interrupted` (a ``KeyboardInterrupt``, so everything that stops a
solve on Ctrl-C stops it on SIGTERM too); later ones are only noted, so the way out is
never interrupted. :func:`commit` ends the raising for good when the outputs start to be
renamed into place: from then on the run completes, and its exit status tells the truth
about the files.

**A signal is never lost.** The handler's exception can be: raised while Python runs a
callback whose exceptions it ignores (a ``__del__``, a weakref callback, an import hook)
or inside code that catches everything (a library's optional import), it is dropped, and
the handler has disarmed itself. So the handler *records* every signal first
(:attr:`State.raised`, :attr:`State.pending`), and :func:`commit`, the last step before
anything is written or renamed, raises a recorded one again: the run then ends with
128 + the signal, one line and nothing written, however the first exception was lost. An
exception Python ignores is not printed either (:func:`install` sets
``sys.unraisablehook``), so standard error keeps its one line.

A signal the parent process ignores (``nohup``, a background job) stays ignored.
"""

from __future__ import annotations

import signal
import sys
from contextlib import suppress

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
    """What the handler does: ``armed``, raise; otherwise only note the signal.

    A plain class, not a dataclass: this module runs before the handlers are installed,
    so it imports nothing heavier than ``signal`` and ``contextlib`` (``dataclasses``
    brings ``inspect`` and widens the window in which Ctrl-C gives a traceback)."""

    armed = False
    pending: int | None = None
    #: the signal the handler raised, if it did: the exception it raised may come out as
    #: another one (a C extension being imported turns it into "ImportError: initialization
    #: failed"), and the run must still end as interrupted
    raised: int | None = None
    previous: dict[int, object] = {}
    #: :func:`commit` has run: from then on the run completes
    committed = False
    #: ``sys.unraisablehook`` before :func:`install`
    previous_hook = None


state = State()


def _handler(signum: int, frame) -> None:
    if state.armed:
        state.armed = False  # once: the way out is never interrupted again
        state.raised = signum
        raise Interrupted(signum)
    if state.pending is None:
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
    """From now on a signal raises :class:`Interrupted`; one that came before is raised now."""
    state.raised, state.committed = None, False
    state.armed = True
    signum, state.pending = state.pending, None
    if signum is not None:
        state.armed = False
        state.raised = signum
        raise Interrupted(signum)


def hold() -> None:
    """From now on signals are only noted: the run goes on to its end."""
    state.armed = False


def commit() -> None:
    """The last step before anything is written or renamed: a signal received since
    :func:`arm` is raised now (again, if its first exception was lost); from then on
    signals are only noted and the run goes on to its end. Only the first call checks."""
    if state.committed:
        return
    state.armed = False  # a plain store first: a signal from here on is only noted
    signum = state.raised if state.raised is not None else state.pending
    if signum is not None:
        state.raised, state.pending = signum, None
        raise Interrupted(signum)
    state.committed = True


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
    state.armed = False
    state.pending = state.raised = None
