"""numba for the compiled kernels (:mod:`core.kernels`), or stand-ins where it is missing.

numba is optional (``pip install isochor[fast]``). Importing this module never fails: when
numba is missing or does not import, ``AVAILABLE`` is False, ``ERROR`` says why and ``njit``
returns the plain Python function (the kernel modules still import, nothing compiles, and
:mod:`core.kernels` keeps the NumPy path).

The on-disk cache: numba reads ``NUMBA_CACHE_DIR`` when it is imported, so this module sets
it first (unless the user has) to a writable per-user folder,
``$XDG_CACHE_HOME/isochor/numba/<key>`` or ``~/.cache/isochor/numba/<key>``. The key is a
hash of the kernel sources: numba checks only the time stamp of the file that defines a
function, not of the helpers it calls from another file, so a changed helper gets a
fresh folder instead of stale machine code. Without a writable folder nothing is cached
(every run compiles again, in the background).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

#: the modules whose source decides the cache folder: every module that defines a compiled
#: function or a helper compiled into one (``winding``), the options they are compiled with
#: (this module) and the types they are compiled for (``signatures``). A module missing
#: here would let numba load stale machine code after it changed (tests/test_kernels.py
#: checks that each one exists and that every module calling ``njit`` is listed).
SOURCES = (
    "base.py",
    "basis.py",
    "bern.py",
    "folds.py",
    "fused.py",
    "local.py",
    "signatures.py",
    "solver.py",
    "volume.py",
    "winding.py",
)


def source_key(folder: Path | None = None) -> str:
    """A hash of the :data:`SOURCES` in ``folder`` (by default this package's folder): the
    name of the cache folder. A listed file that cannot be read counts by its name."""
    h = hashlib.sha1()
    here = Path(__file__).resolve().parent if folder is None else Path(folder)
    for name in SOURCES:
        h.update(name.encode())
        try:
            h.update((here / name).read_bytes())
        except OSError:
            h.update(b"missing")
    return h.hexdigest()[:12]


def cache_dir() -> Path:
    """The cache folder for these kernels (not created)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "isochor" / "numba" / source_key()


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
        return True
    except OSError:
        return False


def _configure_cache() -> bool:
    """Point numba's cache at :func:`cache_dir` unless the user chose one; whether to cache."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True
    try:
        folder = cache_dir()
    except (OSError, RuntimeError):  # no home folder
        return False
    if not _writable(folder):
        return False
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    return True


CACHE = _configure_cache()
ERROR = ""
try:
    import numba
    from numba import njit
except Exception as exc:  # missing, or an install that does not import
    numba = None  # type: ignore[assignment]
    ERROR = f"numba does not import ({type(exc).__name__}: {exc})"

    def njit(*args, **kwargs):  # type: ignore[no-redef]
        """Stand-in: returns the function unchanged."""
        if len(args) == 1 and callable(args[0]) and not kwargs:
            return args[0]
        return lambda f: f


AVAILABLE = numba is not None

#: the hot loops: no Python error checks for division, FMA contraction allowed (1 rounding
#: instead of 2, well inside the tolerance); no reassociation, so loops over points keep
#: the order of the NumPy path's sums
KERNEL: dict[str, Any] = {
    "cache": CACHE,
    "nogil": True,
    "error_model": "numpy",
    "fastmath": {"contract"},
}
#: sums over points: reassociation lets them vectorise (several partial sums)
REDUCE: dict[str, Any] = {**KERNEL, "fastmath": {"contract", "reassoc"}}
#: helpers inlined into the kernels (numba IR inlining; never compiled on their own)
INLINE: dict[str, Any] = {"error_model": "numpy", "fastmath": {"contract"}}
INLINE_REDUCE: dict[str, Any] = {**INLINE, "fastmath": {"contract", "reassoc"}}
