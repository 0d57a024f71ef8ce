"""Signals for the command line: Ctrl-C, ``kill`` (SIGTERM) and a closed terminal (SIGHUP)
stop a run the same way, with one line, exit status 128 + the signal, and nothing written.

:func:`install` runs at the very top of :mod:`isochor.app.cli`, before its other imports.
Until :func:`arm` is called (the first thing ``main`` does inside its error handling) a
signal is only remembered; ``arm`` then raises it where it is caught. After that a signal
raises :class:`Interrupted` (a ``KeyboardInterrupt``, so everything that stops a solve on
Ctrl-C stops it on SIGTERM too), except inside :func:`deferred`, the few milliseconds in
which the outputs are renamed into place: a signal there is raised when the renames are
done, so the set of outputs is never left half replaced.

A signal the parent process ignores (``nohup``, a background job) stays ignored.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager, suppress

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


class _State:
    armed = False
    deferring = False
    pending: int | None = None
    previous: dict[int, object] = {}


def _handler(signum: int, frame) -> None:
    if _State.armed and not _State.deferring:
        raise Interrupted(signum)
    if _State.pending is None:
        _State.pending = signum


def install() -> None:
    """Catch SIGINT, SIGTERM and SIGHUP (only remembered until :func:`arm`)."""
    for sig in SIGNALS:
        try:
            current = signal.getsignal(sig)
            if current is signal.SIG_IGN:
                continue
            _State.previous.setdefault(sig, current)
            signal.signal(sig, _handler)
        except (ValueError, OSError):  # not the main thread, or no such signal here
            pass


def arm() -> None:
    """From now on a signal raises :class:`Interrupted`; one that came before is raised now."""
    _State.armed = True
    _raise_pending()


def release() -> None:
    """Give the signals back to what they were before :func:`install` (the editor handles
    its own)."""
    for sig, previous in _State.previous.items():
        with suppress(ValueError, OSError, TypeError):
            signal.signal(sig, previous)
    _State.previous.clear()
    _State.armed = False


@contextmanager
def deferred() -> Iterator[None]:
    """Hold signals back for the duration of the block, then raise the first one."""
    _State.deferring = True
    try:
        yield
    finally:
        _State.deferring = False
    _raise_pending()


def _raise_pending() -> None:
    signum, _State.pending = _State.pending, None
    if signum is not None:
        raise Interrupted(signum)
