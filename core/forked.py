"""Run a function in a forked child process, so that the memory it leaves behind goes back
to the system when the child ends.

fast-simplification (the level pyramid, :mod:`isochor.core.solve.pyramid`) keeps the mesh
it simplifies in global C++ vectors that it empties but never frees: after the finest
level of the 1.38M-triangle armadillo 420 MB stay with the process for its whole life,
about 300 bytes a triangle, more than the model itself (measured: 569 MB at the peak of one
simplification, 516 MB after it, 94 MB before). :func:`call` runs such work in a child
made with ``fork`` (it sees this process's arrays without copying them) and takes its
result back through a pipe, pickled; ``progress`` calls are relayed to the caller as they
come.

It forks only where that is safe: on Linux (macOS's system libraries, Accelerate among
them, are not safe to use in a forked child; Windows has no fork) and only while this
process runs one thread (a fork copies the calling thread alone; a lock another
thread holds would stay locked in the child). Otherwise, and if the child ends without a
result (it cannot be made, or it was killed), the function runs here: the same code on the
same arrays, the same result. An exception the function raises in the child is raised
here.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import struct
import sys
import threading
from collections.abc import Callable
from typing import Any

_HEADER = struct.Struct("<Q")


def can_fork() -> bool:
    """Whether :func:`call` would run its function in a child: on Linux (macOS's system
    libraries are not safe to use in a forked child; Windows cannot fork) while this
    process runs one thread."""
    return sys.platform.startswith("linux") and threading.active_count() == 1


def call(
    fn: Callable[..., Any],
    *args: Any,
    progress: Callable[[float], None] | None = None,
    **kwargs: Any,
) -> Any:
    """``fn(*args, progress=..., **kwargs)`` in a forked child (see the module's text);
    ``progress(fraction)`` is called here for each call the function makes in the child.
    The result must pickle."""
    if not can_fork():
        return fn(*args, progress=progress, **kwargs)
    _trim()
    try:
        read, write = os.pipe()
        pid = os.fork()
    except OSError:  # no memory for the child's tables, too many processes
        return fn(*args, progress=progress, **kwargs)
    if pid == 0:  # the child: never returns
        os.close(read)
        _child(write, fn, args, kwargs)
    os.close(write)
    outcome = None
    try:
        with os.fdopen(read, "rb") as pipe:
            while (message := _receive(pipe)) is not None:
                kind, payload = message
                if kind == "progress":
                    if progress is not None:
                        progress(payload)
                    continue
                outcome = message
                break
    finally:
        if outcome is None:  # interrupted here, or the child died: it must not run on
            _kill(pid)
        os.waitpid(pid, 0)
    if outcome is None:
        return fn(*args, progress=progress, **kwargs)
    kind, payload = outcome
    if kind == "error":
        raise payload
    return payload


def _child(write: int, fn, args, kwargs) -> None:
    """Run ``fn`` and send its outcome; end the process without Python's finalisation
    (nothing of the parent's is flushed or closed twice)."""
    from os import _exit  # (os's documented exit without interpreter shutdown)

    status = 1
    try:
        with os.fdopen(write, "wb") as pipe:

            def relay(fraction: float) -> None:
                _send(pipe, ("progress", float(fraction)))

            try:
                outcome = ("result", fn(*args, progress=relay, **kwargs))
            except Exception as exc:
                outcome = ("error", exc)
            try:
                _send(pipe, outcome)
            except Exception as exc:  # an exception that does not pickle
                _send(pipe, ("error", RuntimeError(f"{type(exc).__name__}: {exc}")))
        status = 0
    finally:
        _exit(status)


def _send(pipe, message) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    pipe.write(_HEADER.pack(len(data)))
    pipe.write(data)
    pipe.flush()


def _receive(pipe):
    """The next message, or None at the end of the pipe (the child ended without one)."""
    head = pipe.read(_HEADER.size)
    if len(head) < _HEADER.size:
        return None
    (size,) = _HEADER.unpack(head)
    data = pipe.read(size)
    return pickle.loads(data) if len(data) == size else None


def _kill(pid: int) -> None:
    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGKILL)


def _trim() -> None:
    """Give the heap's free pages back to the system (glibc's ``malloc_trim``; nothing
    elsewhere): a page the child reuses would otherwise be copied for it and kept here."""
    import ctypes

    with contextlib.suppress(AttributeError, OSError):
        ctypes.CDLL(None).malloc_trim(0)
