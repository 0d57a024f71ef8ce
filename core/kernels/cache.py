"""numba's on-disk cache for :mod:`core.kernels`: the marker that says it holds the
kernels, and the one child interpreter at a time that fills it.

Compiling holds the GIL for much of its seconds, so it runs in a child interpreter
(``python -m isochor.core.kernels --compile MARKER``), never in the program that waits for
the kernels. Several programs started together on a first run (command-line runs, a test
suite's subprocesses) must not each compile: the first takes a lock file beside the marker,
the others wait for the marker. The child writes the marker and removes the lock itself, so
one that outlives a short program still counts; a lock older than :data:`COMPILE_LIMIT`
(left by a killed process) is taken over.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

#: seconds a compiling child may take (and its lock counts as held)
COMPILE_LIMIT = 900
#: the variable that switches the kernels off (emptied for the compiling child)
ENV_OFF = "ISOCHOR_NO_JIT"


def compile_in_child(marker: Path, module: str) -> None:
    """Fill numba's cache from a child interpreter: compiling holds the GIL for much of
    its seconds, which here would slow the caller's NumPy work. Where the child cannot
    run, this thread compiles; a child killed by a signal switches the kernels off.
    One child at a time per cache folder: while another process's child compiles (its
    lock younger than :data:`COMPILE_LIMIT`), this one waits for the marker, which the
    child writes itself (so one that outlives a short program still counts)."""
    lock = lock_of(marker)
    if not take(lock):
        deadline = time.monotonic() + COMPILE_LIMIT
        while not marker.exists() and held(lock) and time.monotonic() < deadline:
            time.sleep(0.5)
        if marker.exists() or not take(lock):
            return
    cmd = [sys.executable, "-m", module, "--compile", str(marker)]
    env = dict(os.environ, **{ENV_OFF: "", "PYTHONPATH": child_path()})
    try:
        done = subprocess.run(cmd, capture_output=True, timeout=COMPILE_LIMIT, env=env)
    except subprocess.TimeoutExpired as exc:
        raise RuntimeError("compiling took more than 15 minutes") from exc
    except OSError:
        return
    finally:
        lock.unlink(missing_ok=True)
    if done.returncode < 0:
        raise RuntimeError(f"the compiler crashed (signal {-done.returncode}) in a child process")


def child_path() -> str:
    """The child's PYTHONPATH: this program's import path, so that it finds isochor and
    numba where this one did (inside Blender, the extension's own site-packages, which
    Blender adds to its path and a fresh interpreter would not)."""
    return os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))


def lock_of(marker: Path) -> Path:
    """The lock a compiling child holds beside ``marker``."""
    return marker.with_name(marker.name + ".lock")


def held(lock: Path) -> bool:
    """Another process compiles: its lock is there and younger than COMPILE_LIMIT."""
    try:
        return time.time() - lock.stat().st_mtime < COMPILE_LIMIT
    except OSError:
        return False


def take(lock: Path) -> bool:
    """Create the lock (a stale one is replaced); False while another process holds it."""
    for _ in range(2):
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)
            os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            return True
        except FileExistsError:
            if held(lock):
                return False
            lock.unlink(missing_ok=True)
        except OSError:  # an unwritable folder: compile without a lock
            return True
    return False


def compile_and_mark(compile_all, path: str | None) -> None:
    """The child's work (``python -m isochor.core.kernels --compile [MARKER]``):
    ``compile_all()``, then the marker (by default :func:`marker`, ``make venv``'s case)
    when that worked, the lock gone either way (its parent may have ended before it)."""
    done = Path(path) if path else marker()
    if done is None:  # no cache: nothing to mark
        compile_all()
        return
    try:
        compile_all()
        with contextlib.suppress(OSError):
            done.touch()
    finally:
        lock_of(done).unlink(missing_ok=True)


def marker() -> Path | None:
    """The file that says the cache holds these kernels, or None without a cache."""
    from . import base as _jitbase

    if not (_jitbase.AVAILABLE and _jitbase.CACHE):
        return None
    version = f"{_jitbase.numba.__version__}-py{sys.version_info[0]}{sys.version_info[1]}"
    return _jitbase.cache_dir() / f"compiled-{version}"
