"""Ranges of work on a few threads, for :mod:`core.kernels` (whose compiled kernels
release the GIL).

:func:`run` hands the ranges 0..n out one at a time to the calling thread and up to
``threads() - 1`` pool threads, whichever asks first, and returns when all are done; a
pool thread that starts late (busy with another call) finds nothing left, so a call never
waits for another. The callers write each range's result to its own slot and combine the
slots in range order, so results do not depend on the number of threads.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

ENV_THREADS = "ISOCHOR_JIT_THREADS"

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None


def _default_threads() -> int:
    try:
        return max(1, int(os.environ[ENV_THREADS]))
    except (KeyError, ValueError):
        pass
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(4, cores))


_threads = _default_threads()


def threads() -> int:
    """Threads per call: ``ISOCHOR_JIT_THREADS``, else the usable cores (at most 4)."""
    return _threads


def set_threads(n: int | None) -> int:
    """Use up to n threads per call (None: the default); returns the previous number."""
    global _threads
    previous, _threads = _threads, max(1, int(n)) if n else _default_threads()
    return previous


class _Ranges:
    def __init__(self, task, n: int) -> None:
        self.task, self.n = task, n
        self.next = self.done = 0
        self.error: BaseException | None = None
        self.cond = threading.Condition()

    def work(self) -> None:
        while True:
            with self.cond:
                i = self.next
                if i >= self.n:
                    return
                self.next += 1
            try:
                self.task(i)
            except BaseException as exc:
                self.error = exc
            with self.cond:
                self.done += 1
                if self.done == self.n:
                    self.cond.notify_all()


def run(task, n: int) -> None:
    """``task(i)`` for i in 0..n (see the module); re-raises a task's exception."""
    helpers = min(_threads, n) - 1
    if helpers <= 0:
        for i in range(n):
            task(i)
        return
    global _pool
    if _pool is None:
        with _lock:
            if _pool is None:
                _pool = ThreadPoolExecutor(max_workers=3, thread_name_prefix="isochor-kernel")
    ranges = _Ranges(task, n)
    for _ in range(helpers):
        _pool.submit(ranges.work)
    ranges.work()
    with ranges.cond:
        while ranges.done < n:
            ranges.cond.wait()
    if ranges.error is not None:
        raise ranges.error


def _reset_after_fork() -> None:
    global _pool
    _pool = None  # its threads did not survive the fork


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_after_fork)
