"""The solver's BLAS threads: one while a solve computes, unless the user chose.

NumPy's BLAS (OpenBLAS in the wheels) runs every matrix product above a size on all its
threads, the solver's tall, thin ones too (a fold guard's 2500 samples by 27 nodes by 3
coordinates, a level's basis). They gain nothing there, and on a busy machine each waits
for threads that are not scheduled: the four paper examples' first solves through the
API, beside one other busy process on two cores, took 230 ms with OpenBLAS's two threads
and 98 ms limited (106 and 83 ms on an idle machine; :mod:`benchmarks.api_threads`).

The command line and the editor set ``OPENBLAS_NUM_THREADS=1`` before NumPy loads
(:func:`at_start`, from :mod:`isochor.app.cli.main` and :mod:`isochor.app.cli.launch`); a
program that imported NumPy first (a script using the API, Blender with the add-on) gets
:func:`one_thread` instead: every BLAS library limited to one thread while a solve step
runs (:func:`per_step`), and the program's own setting back between the steps, when
control is its own.

The limit is threadpoolctl's (a dependency; without it nothing is limited and everything
works as before). It is not applied where the user chose: any of :data:`CHOICES` set in the
environment, or BLAS already on one thread. Solves on several threads at once share one
limit: the first to start sets it, the last to leave gives the setting back.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Generator
from contextlib import contextmanager
from typing import Any

#: environment variables by which a user sets BLAS's threads: any of them set, and the
#: solver leaves the threads as they are
CHOICES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def _chosen() -> bool:
    """Whether the user set BLAS's threads in the environment (any of :data:`CHOICES`)."""
    return any(os.environ.get(v) for v in CHOICES)


def at_start() -> None:
    """For a program's start, before NumPy loads (the command line, the editor): BLAS on
    one thread for the whole process, by the environment, unless the user set any of
    :data:`CHOICES`. Measured under load: a 125-node basis product took 32 ms with two
    OpenBLAS threads and 1.4 ms with one."""
    if not _chosen():
        for name in CHOICES:
            os.environ[name] = "1"


class _Limit:
    """The process's one limit: the threadpoolctl controller (made on first use; False
    where there is nothing to limit), how many steps are inside it and what restores it."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.controller: Any = None
        self.depth = 0
        self.held: Any = None

    def _made(self):
        if self.controller is None:
            self.controller = False
            try:
                from threadpoolctl import ThreadpoolController

                blas = ThreadpoolController().select(user_api="blas")
                if any(lib.num_threads > 1 for lib in blas.lib_controllers):
                    self.controller = blas
            except Exception:  # no threadpoolctl, or a library it cannot read
                self.controller = False
        return self.controller

    def wanted(self) -> bool:
        """Whether a limit would do anything: nobody chose the threads in the environment
        and a BLAS library runs more than one (the libraries read once)."""
        if _chosen():
            return False
        with self.lock:
            return bool(self._made())

    def enter(self) -> None:
        with self.lock:
            if self.depth == 0 and not _chosen():
                blas = self._made()
                try:
                    self.held = blas.limit(limits=1) if blas else None
                except Exception:  # a library that will not be set: leave them all alone
                    self.controller, self.held = False, None
            self.depth += 1

    def leave(self) -> None:
        with self.lock:
            self.depth -= 1
            if self.depth == 0 and self.held is not None:
                held, self.held = self.held, None
                try:
                    held.restore_original_limits()
                except Exception:  # as above: never the solve's failure
                    self.controller = False

    def forget(self) -> None:
        """Read the libraries and their threads again at the next use (tests)."""
        with self.lock:
            self.controller = None


_LIMIT = _Limit()


@contextmanager
def one_thread():
    """BLAS on one thread inside (see the module); nested and concurrent uses share it."""
    _LIMIT.enter()
    try:
        yield
    finally:
        _LIMIT.leave()


def forget() -> None:
    """Look at the BLAS libraries and their threads again on the next use."""
    _LIMIT.forget()


def per_step(solver):
    """Decorate a generator function (a solve): each step of each generator it makes (every
    ``next``) runs under :func:`one_thread`; the caller's code between the steps does not.
    Where no limit is wanted when the solve starts (the command line, the editor: a step
    costs nothing more), the steps run as they are."""

    @functools.wraps(solver)
    def run(*args, **kwargs):
        return _limited(solver(*args, **kwargs))

    return run


def _limited(gen: Generator) -> Generator:
    if not _LIMIT.wanted():  # decided when the solve starts: then nothing a step
        return (yield from gen)
    try:
        while True:
            with one_thread():
                try:
                    record = next(gen)
                except StopIteration as stop:
                    return stop.value
            yield record
    finally:
        gen.close()  # closing this closes the solve at once
