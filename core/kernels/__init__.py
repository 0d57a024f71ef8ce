"""Optional compiled kernels (numba) for the hot loops of the evaluation and of the solver's
own step, with the NumPy path as the fallback. This module is their one entry point; the
package's other modules:

- :mod:`.step`       the solver step's entry points (springs, L-BFGS recursion and memory, a
  small preconditioner's inverse); :mod:`.pairs`, the L-BFGS memory on the NumPy path
- :mod:`.basis`, :mod:`.bern`  the Bernstein basis products; :mod:`.local` the local
  (Blender) bases' products and det J; :mod:`.volume` the volume and its gradient;
  :mod:`.fused` the basis, the volume's gradient and the transpose in one pass;
  :mod:`.folds` det J; :mod:`.solver` the solver step; :mod:`.winding` the solid-angle
  term both paths share
- :mod:`.base`       numba or stand-ins, the cache folder; :mod:`.signatures` the types each
  kernel is compiled for; :mod:`.check` their self-check; :mod:`.cache` the cache marker and
  the one compiling child at a time; :mod:`.threads` ranges of work on a few threads
- ``python -m isochor.core.kernels --compile`` fills the cache (:mod:`.__main__`)

What they compute (the same numbers as the NumPy path, to rounding; ``tests/test_kernels``):

- :func:`apply` and :func:`apply_transpose`: :meth:`core.lattice.PointBasis.apply` and its
  transpose, evaluating the Bernstein basis per point from its lattice coordinates
  (:mod:`core.kernels.basis`);
- :func:`fans`, :func:`volume_gradient`, :func:`face_volume`: the volume and its gradient
  of :class:`core.volume.VolumeOperator`, vertex by vertex (:mod:`core.kernels.volume`);
- :func:`evaluation` (with :func:`evaluation_plan`):
  :meth:`core.volume.VolumeOperator.node_gradient`, the basis applied, the volume's
  gradient and its transpose in one pass over ranges of vertices (:mod:`core.kernels.fused`);
- :func:`winding_numbers`: :func:`core.bodies.winding_numbers` (the fold guard's interior
  samples, on the first solve of a model);
- :func:`determinants`: det J at many points, the fold check of every result
  (:mod:`core.kernels.folds`);
- :func:`local_apply`, :func:`local_transpose`, :func:`local_determinants`: the same three
  for the local (Blender) bases of :mod:`core.localbasis`, a 4x4x4 window per point
  (:mod:`core.kernels.local`);
- the solver's own work per step (:mod:`core.kernels.solver`): its entry points are in
  :mod:`core.kernels.step`.

Each returns None when the compiled kernels are not there (yet); the caller then runs its
NumPy code. They are there once numba (the ``fast`` extra) imports and has compiled them.
Compiling never happens in the caller: :func:`start` (called by ``load_model`` and by the
first evaluation of ``START_SIZE`` points or faces) loads them in a background thread from
numba's on-disk cache (:mod:`core.kernels.base`), and NumPy serves until that is done. A
one-shot command turns that off (:func:`set_autostart`) and asks :func:`worth`: numba only
for a big model, waited for (``isochor solve``, :mod:`isochor.app.cli.opening`). With an
empty cache a child interpreter compiles them first (:mod:`core.kernels.cache`). Whatever
goes wrong (numba missing, an import or compile error, a failed self-check, a compiled call
that raises) leaves the NumPy path in place; :func:`status` says why. A solve keeps the
path it started on to its end (:func:`one_path`), so its result never depends on when
the kernels arrived. ``ISOCHOR_NO_JIT=1`` switches them off; :func:`ready` waits for
them, :func:`numpy_path` forces the NumPy path for a while (tests and benchmarks compare
the two).

Large inputs are cut into fixed ranges (``CHUNK`` points, vertices or faces), run on up to
``ISOCHOR_JIT_THREADS`` threads (default: the usable cores, at most 4; the kernels release
the GIL) and combined in range order, so results do not depend on the thread count.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import sys
import threading
from types import SimpleNamespace

import numpy as np

from . import threads as _jitthreads
from .cache import ENV_OFF

#: evaluations at least this large (points, vertices or faces) start the compilation
START_SIZE = 4096
#: points, vertices or faces per range of work (a multiple of the kernels' block)
CHUNK = 1 << 14
_FACE_CHUNK = 1 << 15
#: (point, triangle) pairs per range of winding-number work
WINDING_PAIRS = 1 << 20
#: a one-shot command (``isochor solve``) loads the kernels only for a model of at least
#: this many triangles, and then waits for them before solving (:func:`worth`). Measured
#: (the benchmark's First use rows, a loaded machine): the 346k armadillo's cold command
#: took 8.7 s waiting for numba against 7.5 s on NumPy; at 1.38M the compiled release
#: solve is about 4x faster than NumPy's
WORTH_TRIANGLES = 1_000_000
#: ... and, for a model file of at least this many bytes (about ``WORTH_TRIANGLES``
#: triangles of binary PLY), starts them once the model's pyramid is made and waits for
#: them before the problem is built (:mod:`isochor.app.cli.opening`)
WORTH_BYTES = 20 * WORTH_TRIANGLES

#: threads per call (:mod:`core.kernels.threads`)
set_threads = _jitthreads.set_threads

_log = logging.getLogger(__name__)
_lock = threading.Lock()
_state = SimpleNamespace(
    status="idle", reason="", kernels=None, thread=None, mode="auto", autostart=True
)
#: ``mode``: the path this thread's running solve keeps (see :func:`one_path`)
_local = threading.local()


def _off_by_env() -> bool:
    return os.environ.get(ENV_OFF, "").strip() not in ("", "0")


def status() -> str:
    """``ready``, ``loading``, ``idle`` (nothing started yet), ``off: <why>`` or
    ``failed: <why>``."""
    if _off_by_env():
        return f"off: {ENV_OFF} is set"
    if _state.mode == "numpy":
        return "off: the NumPy path is forced"
    if _state.status in ("failed", "off"):
        return f"{_state.status}: {_state.reason}"
    return _state.status


def set_mode(mode: str) -> str:
    """``"numpy"``: every evaluation takes the NumPy path; ``"auto"``: the compiled one when
    it is ready. Returns the previous mode (tests and benchmarks compare the two)."""
    if mode not in ("auto", "numpy"):
        raise ValueError(f"mode must be 'auto' or 'numpy', not {mode!r}")
    previous, _state.mode = _state.mode, mode
    return previous


@contextlib.contextmanager
def numpy_path():
    """Within: every evaluation takes the NumPy path."""
    previous = set_mode("numpy")
    try:
        yield
    finally:
        set_mode(previous)


def set_autostart(on: bool) -> bool:
    """Whether loading a model and large evaluations start loading the kernels by
    themselves (the default: right for the window and the API, whose process lives on).
    A one-shot command turns it off and decides with :func:`worth`. Returns the previous
    setting."""
    previous, _state.autostart = _state.autostart, bool(on)
    return previous


def worth(triangles: int) -> bool:
    """Whether a one-shot solve of a model of ``triangles`` triangles should wait for the
    kernels: below :data:`WORTH_TRIANGLES` the compiled solve saves less than loading
    numba costs the command (about 0.5 s of CPU from a warm cache, and its threads on the
    same cores), and loading it beside a NumPy solve only slows that down (the cold
    command rows of the benchmark)."""
    return triangles >= WORTH_TRIANGLES


def start(auto: bool = False) -> None:
    """Start loading the kernels in a background thread, unless started or switched off
    (with ``auto``: only where :func:`set_autostart` allows it)."""
    if _off_by_env() or _state.status != "idle" or (auto and not _state.autostart):
        return
    with _lock:
        if _state.status != "idle":
            return
        _state.status = "loading"
        thread = threading.Thread(target=_load, name="isochor-jit", daemon=True)
        _state.thread = thread
    thread.start()


def ready(timeout: float | None = None) -> bool:
    """Start loading and wait up to ``timeout`` seconds (None: until done); whether the
    compiled kernels are in use."""
    start()
    thread = _state.thread
    if thread is not None and _state.status == "loading":
        thread.join(timeout)
    return _kernels() is not None


def active(size: int = 0) -> bool:
    """Whether the compiled kernels are in use; starts loading them for a large input."""
    return _kernels(size) is not None


def _kernels(size: int = 0) -> SimpleNamespace | None:
    """The compiled kernels if they are to be used; starts loading them for a large input."""
    k = _state.kernels
    if k is not None:
        return k if (getattr(_local, "mode", None) or _state.mode) == "auto" else None
    if size >= START_SIZE and _state.status == "idle":
        start(auto=True)
    return None


def one_path(solver):
    """Decorate a generator function (a solve): each generator it makes runs on one path,
    the compiled one if the kernels are in use when it starts, else NumPy to its end.

    The kernels load in the background, and the two paths round differently; a solve that
    changed path when they arrived would end a little elsewhere (within its tolerance)
    depending on when that was, so the same command could give different nodes. A solve
    started inside another keeps the outer one's path."""

    @functools.wraps(solver)
    def run(*args, **kwargs):
        return _on_one_path(solver(*args, **kwargs))

    return run


def _on_one_path(gen):
    mode = getattr(_local, "mode", None) or ("auto" if active() else "numpy")
    try:
        while True:
            outer, _local.mode = getattr(_local, "mode", None), mode
            try:
                record = next(gen)
            except StopIteration as stop:
                return stop.value
            finally:
                _local.mode = outer
            yield record
    finally:
        gen.close()  # closing this closes the solve at once


def _fail(why: str) -> None:
    with _lock:
        _state.kernels = None
        _state.status, _state.reason = "failed", why
    _log.info("isochor: compiled kernels off, NumPy path in use (%s)", why)


def _load() -> None:
    """The background thread: import numba, compile (or load from the cache), check."""
    try:
        from . import base as _jitbase
        from . import cache as _jitcache
        from . import check as _jitcheck
        from .signatures import compile_all

        if not _jitbase.AVAILABLE:
            with _lock:
                _state.status, _state.reason = "off", _jitbase.ERROR
            return
        marker = _jitcache.marker()
        if marker is not None and not marker.exists():
            _jitcache.compile_in_child(marker, __name__)
        k = compile_all()
        why = _jitcheck.self_check(k, sys.modules[__name__])
        if why:
            _fail(f"self-check: {why}")
            return
        with _lock:
            _state.kernels, _state.status = k, "ready"
    except Exception as exc:  # never let the optional path break the program
        _fail(f"{type(exc).__name__}: {exc}")


def _reset_after_fork() -> None:
    if _state.status == "loading":  # the loading thread did not survive the fork
        _state.status, _state.thread = "idle", None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_after_fork)


def _chunks(size: int, chunk: int = CHUNK) -> list[tuple[int, int]]:
    return [(s, min(s + chunk, size)) for s in range(0, size, chunk)] or [(0, 0)]


def _guard(fn):
    """Run a compiled call; on any error switch the kernels off and return None."""

    def wrapped(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except Exception as exc:
            _fail(f"{fn.__name__}: {type(exc).__name__}: {exc}")
            return None

    wrapped.__name__ = wrapped.__qualname__ = fn.__name__
    wrapped.__doc__ = fn.__doc__
    return wrapped


# --- the entry points ------------------------------------------------------------------------


@_guard
def apply(uvw: np.ndarray, nodes: np.ndarray, shape, k=None) -> np.ndarray | None:
    """(3, p) points for the (3, p) lattice coordinates and (l m n, 3) nodes; None: no
    kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None:
        return None
    l, m, n = shape
    if nodes.shape != (l * m * n, 3):
        return None  # the NumPy path says what is wrong
    x = np.ascontiguousarray(nodes, dtype=np.float64).reshape(l, m, 3 * n)
    out = np.empty(uvw.shape)
    ranges = _chunks(uvw.shape[1])
    _jitthreads.run(lambda i: k.apply_range(uvw, x, out, *ranges[i]), len(ranges))
    return out


@_guard
def apply_transpose(uvw: np.ndarray, rows: np.ndarray, shape, k=None) -> np.ndarray | None:
    """(l m n, 3) node values for (3, p) per-point rows; None: no kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None:
        return None
    l, m, n = shape
    if rows.shape != uvw.shape:
        return None
    g = np.ascontiguousarray(rows, dtype=np.float64)
    return _summed(
        uvw.shape[1], l * m * n, lambda r, out: k.transpose_range(uvw, g, l, m, n, *r, out)
    )


def _summed(points: int, nodes: int, fill) -> np.ndarray:
    """(nodes, 3) node values summed over the threads' chunks of ``points``: ``fill(range,
    out)`` adds a chunk's share into its own ``out`` (nodes * 3,)."""
    ranges = _chunks(points)
    acc = np.zeros((len(ranges), nodes * 3))
    _jitthreads.run(lambda i: fill(ranges[i], acc[i]), len(ranges))
    return acc.sum(axis=0).reshape(nodes, 3) if len(ranges) > 1 else acc[0].reshape(-1, 3)


@_guard
def fans(faces: np.ndarray, n_vertices: int, k=None):
    """The vertex fans (ptr, seq) of :mod:`core.kernels.volume` for a face list; None: no
    kernels (or a mesh too large for int32 indices)."""
    k = k or _kernels(len(faces))
    if k is None or max(int(n_vertices), 3 * len(faces)) >= 2**31 - 1:
        return None
    return k.build_fans(np.ascontiguousarray(faces, dtype=np.int64), int(n_vertices))


@_guard
def volume_gradient(fan, rows: np.ndarray, center, k=None):
    """(volume, (3, m) gradient) for (3, m) C-ordered vertex rows; None: no kernels."""
    k = k or _kernels(rows.shape[1])
    if k is None or fan is None:
        return None
    ptr, seq = fan
    if rows.shape != (3, len(ptr) - 1):
        return None
    c = np.zeros(3) if center is None else np.asarray(center, dtype=np.float64).reshape(3)
    grad = np.empty(rows.shape)
    ranges = _chunks(rows.shape[1])
    part = np.zeros(len(ranges))

    def task(i):
        part[i] = k.fan_gradient_range(rows, c[0], c[1], c[2], ptr, seq, grad, *ranges[i], 0.0)

    _jitthreads.run(task, len(ranges))
    return float(part.sum()) / 3.0, grad


_scratch = threading.local()


def _buffers(plan) -> tuple[np.ndarray, np.ndarray]:
    """This thread's scratch for :func:`evaluation`: kept, and grown to the largest plan
    seen (a solve's levels and bodies take turns; the kernel reads only what its plan
    needs), so a call does not allocate and fault in a megabyte."""
    width, most = plan.width, plan.most_far
    held = getattr(_scratch, "buffers", None)
    if held is None or held[0][0] < width or held[0][1] < most:
        if held is not None:
            width, most = max(width, held[0][0]), max(most, held[0][1])
        held = _scratch.buffers = (
            (width, most),
            (np.empty((3, width + most)), np.empty((3, width))),
        )
    return held[1]


def evaluation_plan(fan, k=None):
    """The fans (ptr, seq) renumbered for :func:`evaluation` (:mod:`core.kernels.fused`);
    None: no kernels or no fans."""
    k = k or _kernels()
    if k is None or fan is None:
        return None
    from .fused import plan

    return plan(*fan, CHUNK)


@_guard
def evaluation(plan, uvw: np.ndarray, nodes: np.ndarray, shape, center, k=None):
    """(volume, (l m n, 3) node gradient) of the faces whose fans ``plan`` renumbers, at
    the points the (3, p) lattice coordinates ``uvw`` take for the (l m n, 3) nodes:
    :func:`apply`, :func:`volume_gradient` and :func:`apply_transpose` in one pass, the
    same numbers (:mod:`core.kernels.fused`); None: no kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None or plan is None:
        return None
    l, m, n = shape
    p = uvw.shape[1]
    if nodes.shape != (l * m * n, 3) or plan.vertices != p or plan.chunk != CHUNK:
        return None
    x = np.ascontiguousarray(nodes, dtype=np.float64).reshape(l, m, 3 * n)
    c = np.zeros(3) if center is None else np.asarray(center, dtype=np.float64).reshape(3)
    ranges = _chunks(p)
    acc = np.zeros((len(ranges), l * m * n * 3))
    part = np.zeros(len(ranges))
    far_uvw = np.ascontiguousarray(uvw[:, plan.far])

    def task(i):
        points, grad = _buffers(plan)
        start, stop = ranges[i]
        part[i] = k.evaluation_range(
            uvw, x, l, m, n, c[0], c[1], c[2], plan.far, plan.far_ptr, plan.six,
            plan.regular, plan.regular_ptr, plan.other, plan.other_ptr, plan.entries,
            plan.starts, i, start, stop, plan.window, plan.width, far_uvw, points, grad,
            acc[i],
        )  # fmt: skip

    _jitthreads.run(task, len(ranges))
    gradient = acc.sum(axis=0) if len(ranges) > 1 else acc[0]
    return float(part.sum()) / 3.0, gradient.reshape(-1, 3)


@_guard
def face_volume(corners: np.ndarray, rows: np.ndarray, center, k=None) -> float | None:
    """The signed volume of the faces (3, f) (int32 rows, or converted; every index
    checked to lie in 0..m by the caller) of (3, m) vertex rows; None: no kernels (or
    more vertices than int32 numbers)."""
    k = k or _kernels(corners.shape[1])
    if k is None or rows.shape[1] > np.iinfo(np.int32).max:
        return None
    corners = np.ascontiguousarray(corners, dtype=np.int32)
    c = np.zeros(3) if center is None else np.asarray(center, dtype=np.float64).reshape(3)
    f0, f1, f2 = corners
    ranges = _chunks(corners.shape[1], _FACE_CHUNK)
    part = np.zeros(len(ranges))

    def task(i):
        part[i] = k.face_volume_range(rows, c[0], c[1], c[2], f0, f1, f2, *ranges[i])

    _jitthreads.run(task, len(ranges))
    return float(part.sum()) / 6.0


@_guard
def winding_numbers(points: np.ndarray, corners: np.ndarray, k=None) -> np.ndarray | None:
    """(p,) winding numbers of the (3, p) points over the triangles ``corners`` (3, 3, t);
    None: no kernels."""
    k = k or _kernels(points.shape[1] * corners.shape[2])
    if k is None:
        return None
    pts = np.ascontiguousarray(points, dtype=np.float64)
    tri = np.ascontiguousarray(corners, dtype=np.float64)
    out = np.empty(pts.shape[1])
    ranges = _chunks(pts.shape[1], max(1, WINDING_PAIRS // max(tri.shape[2], 1)))
    _jitthreads.run(lambda i: k.winding_range(pts, tri, out, *ranges[i]), len(ranges))
    return out


@_guard
def determinants(
    uvw: np.ndarray, grid: np.ndarray, to_world: np.ndarray, k=None, frobenius: bool = False
):
    """(p,) det J at the (3, p) lattice coordinates for the (l, m, n, 3) nodes ``grid``
    (``to_world``: ``inv(axes).T``), with ``frobenius`` also (p,) ``|J|_F^2``; None: no
    kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None:
        return None
    uvw = np.ascontiguousarray(uvw, dtype=np.float64)
    x = np.ascontiguousarray(grid, dtype=np.float64)
    t = np.ascontiguousarray(to_world, dtype=np.float64)
    out = np.empty(uvw.shape[1])
    norms = np.empty(uvw.shape[1] if frobenius else 0)
    ranges = _chunks(uvw.shape[1])

    def task(i):
        k.determinant_range(uvw, x, t, out, norms, *ranges[i])

    _jitthreads.run(task, len(ranges))
    return (out, norms) if frobenius else out


# --- the local (Blender) bases: core.localbasis ----------------------------------------------


@_guard
def local_apply(uvw, points, codes, displacements, shape, k=None) -> np.ndarray | None:
    """(3, p) points ``p + sum w D`` for the (3, p) lattice coordinates and world points and
    the (l m n, 3) displacements; None: no kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None:
        return None
    l, m, n = shape
    if displacements.shape != (l * m * n, 3):
        return None
    d = np.ascontiguousarray(displacements, dtype=np.float64).reshape(l, m, n, 3)
    out = np.empty(uvw.shape)
    ranges = _chunks(uvw.shape[1])
    _jitthreads.run(
        lambda i: k.local_apply_range(uvw, points, codes, d, out, *ranges[i]), len(ranges)
    )
    return out


@_guard
def local_transpose(uvw, codes, rows, shape, k=None) -> np.ndarray | None:
    """(l m n, 3) ``W^T g`` for (3, p) per-point rows; None: no kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None:
        return None
    l, m, n = shape
    if rows.shape != uvw.shape:
        return None
    g = np.ascontiguousarray(rows, dtype=np.float64)
    return _summed(
        uvw.shape[1],
        l * m * n,
        lambda r, out: k.local_transpose_range(uvw, codes, g, l, m, n, *r, out),
    )


@_guard
def local_determinants(uvw, codes, displacements, shape, to_world, k=None, frobenius=False):
    """(p,) det J of a local basis at the (3, p) lattice coordinates for the (l m n, 3)
    displacements, with ``frobenius`` also (p,) ``|J|_F^2``; None: no kernels."""
    k = k or _kernels(uvw.shape[1])
    if k is None:
        return None
    l, m, n = shape
    uvw = np.ascontiguousarray(uvw, dtype=np.float64)
    d = np.ascontiguousarray(displacements, dtype=np.float64).reshape(l, m, n, 3)
    t = np.ascontiguousarray(to_world, dtype=np.float64)
    out = np.empty(uvw.shape[1])
    norms = np.empty(uvw.shape[1] if frobenius else 0)
    ranges = _chunks(uvw.shape[1])

    def task(i):
        k.local_determinant_range(uvw, codes, d, t, out, norms, *ranges[i])

    _jitthreads.run(task, len(ranges))
    return (out, norms) if frobenius else out
