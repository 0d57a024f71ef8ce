"""Signals for the command line: Ctrl-C, ``kill`` (SIGTERM) and a closed terminal (SIGHUP)
stop a run the same way, with one line, exit status 128 + the signal, and nothing written.

:func:`install` runs at the very top of :mod:`isochor.app.cli.main`, before its other imports.
Until :func:`arm` is called (the first thing ``main`` does inside its error handling) a
signal is only remembered; ``arm`` then raises it where it is caught. After that the first
signal raises :class:`Interrupted` (a ``KeyboardInterrupt``, so everything that stops a
solve on Ctrl-C stops it on SIGTERM too); later ones are only noted, so the way out is
never interrupted. :func:`hold` ends the raising for good when the outputs start to be
renamed into place: from then on the run completes, and its exit status tells the truth
about the files.

A signal the parent process ignores (``nohup``, a background job) stays ignored.
"""

from __future__ import annotations

import signal
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


state = State()


def _handler(signum: int, frame) -> None:
    if state.armed:
        state.armed = False  # once: the way out is never interrupted again
        state.raised = signum
        raise Interrupted(signum)
    if state.pending is None:
        state.pending = signum


def install() -> None:
    """Catch SIGINT, SIGTERM and SIGHUP (only noted until :func:`arm`)."""
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
    state.armed = True
    signum, state.pending = state.pending, None
    if signum is not None:
        state.armed = False
        state.raised = signum
        raise Interrupted(signum)


def hold() -> None:
    """From now on signals are only noted: the run goes on to its end."""
    state.armed = False


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
    state.armed = False
    state.pending = None
