"""Repeated timings, peak memory, and the machine the benchmark runs on."""

from __future__ import annotations

import datetime
import os
import platform
import resource
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy

from benchmarks import BLAS_ENV

_THREADPOOL = None  # threadpoolctl limiter, kept alive while the benchmark runs


@dataclass(frozen=True)
class Timing:
    """Repeated measurements of one thing.

    Parameters
    ----------
    values : (r,) seconds, one per run (at least one)
    """

    values: tuple[float, ...]

    @property
    def median(self) -> float:
        """Median, seconds."""
        return float(np.median(self.values))

    @property
    def lo(self) -> float:
        """Fastest run, seconds."""
        return float(min(self.values))

    @property
    def hi(self) -> float:
        """Slowest run, seconds."""
        return float(max(self.values))

    @property
    def spread(self) -> float:
        """Slowest minus fastest, seconds."""
        return self.hi - self.lo

    def ms(self, digits: int = 1) -> str:
        """``median (min-max)`` in milliseconds, ``digits`` decimals."""
        med, lo, hi = (f"{1e3 * t:.{digits}f}" for t in (self.median, self.lo, self.hi))
        return f"{med} ({lo}-{hi})"


def time_call(fn: Callable[[], object], repeats: int, warmup: int = 1) -> Timing:
    """Call ``fn`` ``warmup`` times untimed, then time ``repeats`` calls (at least one)."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return Timing(tuple(out))


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB.

    Linux's ``VmHWM`` (the high-water mark of this process's own memory map) when there is
    one: ``ru_maxrss`` of a child started by a large parent reports the parent's size,
    because Linux carries the old map's peak over ``fork`` and ``exec``.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def limit_blas_threads(numpy_first: bool, user_blas: Mapping[str, str]) -> bool:
    """Limit BLAS to one thread with threadpoolctl when the environment came too late.

    ``python -m benchmarks`` sets :data:`benchmarks.BLAS_ENV` before NumPy is imported; when
    NumPy was imported first (``numpy_first``) and the user set none of them, threadpoolctl
    (if installed) limits the threads instead. Returns True when it did.
    """
    global _THREADPOOL
    if _THREADPOOL is not None:
        return True
    if not numpy_first or user_blas:
        return False
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return False
    _THREADPOOL = threadpool_limits(1, user_api="blas")
    return True


def environment(user_blas: Mapping[str, str] | None = None, unit: bool = False) -> dict[str, str]:
    """The machine and libraries, for the report's header.

    ``user_blas``: the BLAS variables the user had set before the benchmark started;
    ``unit``: measure the machine unit too (``"unit"``, :mod:`benchmarks.machine`).
    """
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    blas = ", ".join(f"{k}={os.environ.get(k, 'unset')}" for k in BLAS_ENV)
    try:
        from threadpoolctl import threadpool_info

        pools = [
            f"{p.get('internal_api')} {p.get('num_threads')} thread(s)"
            for p in threadpool_info()
            if p.get("user_api") == "blas"
        ]
        if pools:
            blas += "; threadpoolctl: " + ", ".join(pools)
    except ImportError:
        pass
    if user_blas:
        blas += " (set by the user before the benchmark started)"
    out = {
        "date": datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        "cpu": f"{cpu}, {os.cpu_count()} logical CPUs",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "blas": blas,
        "platform": platform.platform(),
        "kernels": kernel_status(),
    }
    if unit:
        from benchmarks.machine import machine_unit  # (machine imports this module)

        out["unit"] = machine_unit().words()
    return out


def kernel_status() -> str:
    """Wait for the optional compiled kernels (``core.kernels``) so that every timing
    measures one path, and say which: numba's version, or why the NumPy path runs."""
    from isochor.core import kernels

    if kernels.ready(timeout=900):
        import numba

        return f"compiled (numba {numba.__version__}); NumPy-path figures where a row says so"
    return f"NumPy path ({kernels.status()})"
