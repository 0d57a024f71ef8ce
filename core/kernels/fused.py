"""The compiled evaluation in one pass: the basis applied, the volume and its gradient
(:mod:`core.kernels.volume`) and the gradient taken back to the nodes (the basis's
transpose, :mod:`core.kernels.basis`), range of vertices by range.

The three passes one after the other write the (3, m) points and read them back by the
fans' gathers, then write the (3, m) gradient and read it back with the lattice
coordinates again: on a million triangles three times the bytes the evaluation must read
(the coordinates and the fans). Here a range of ``CHUNK`` vertices goes in steps of
``STEP``: it applies the basis to the points up to ``window`` past the step, walks the
step's fans there and takes the step's gradient to the nodes at once, so the points and
the gradient stay in the core's cache. A neighbour outside what has been applied (the
seam of a torus, a model numbered without locality) is one of the range's *far* points,
applied first. The fans are renumbered for that once (a :class:`Plan`), so the kernel
walks them as :func:`core.kernels.volume.fan_gradient_range` does, with the same
arithmetic and the same order of every sum: the numbers are the three passes', bit for
bit. A regular vertex (one closed chain of six faces: most of a triangle mesh's) is walked
by straight-line code from a six-column table instead of the fans' loop (about half the
time a vertex); the volume is then summed over the step in vertex order, as the fans'
kernel sums it. The plan costs about 0.1 s and 14 bytes a triangle, once (1M triangles).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .base import INLINE, KERNEL, njit
from .basis import _apply_rows, _transpose_rows
from .volume import _plus_cross, _vertex_called

#: vertices a step within a range (a multiple of the basis's block: the transpose sums
#: block by block from the range's start either way, so the sums are the same)
STEP = 2048
#: the regular vertex's fan written out, inlined (numba IR) into the kernel
_IN = {**INLINE, "inline": "always"}


class Plan(NamedTuple):
    """The fans renumbered for :func:`evaluation_range` (see the module)."""

    vertices: int  #: m
    far: np.ndarray  #: int32, the ranges' far vertices one after the other
    far_ptr: np.ndarray  #: (ranges + 1,) int64: range r's far vertices
    chunk: int  #: vertices a range
    window: int  #: vertices applied on either side of a range
    width: int  #: ``chunk + 2 window``: where the far points start in a range's buffer
    most_far: int  #: the most far points of one range
    six: np.ndarray  #: int32 (6, regular): the six entries a regular vertex's fan starts
    #: with (its closed chain without the last, which is the first again), one column each
    regular: np.ndarray  #: int32, the regular vertices (one closed chain of six faces)
    regular_ptr: np.ndarray  #: (steps + 1,) int64: step s's regular vertices
    other: np.ndarray  #: int32, the other vertices
    other_ptr: np.ndarray  #: (steps + 1,) int64: step s's other vertices
    entries: np.ndarray  #: int32, the other vertices' fans one after the other, each
    #: neighbour by its place in its range's buffer: in the window by its place there, a
    #: far one by ``width +`` its place in the range's far list (chain starts negative)
    starts: np.ndarray  #: (others + 1,) int64: where each other vertex's entries start


def plan(ptr: np.ndarray, seq: np.ndarray, chunk: int, window: int | None = None) -> Plan:
    """The :class:`Plan` of the fans (ptr, seq) for ranges of ``chunk`` vertices: the
    window (by default :func:`_window`'s) and each range's far vertices."""
    if chunk % STEP:
        raise ValueError(f"a range of {chunk} vertices is not a whole number of steps")
    n = len(ptr) - 1
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    start = seq < 0
    index = np.where(start, -seq.astype(np.int64) - 1, seq)
    r = owner // chunk
    # the points a vertex's fan may read: back to its range's window, ahead to its step's
    # end and the window (what the kernel has applied when it walks that step)
    ahead = np.minimum((owner // STEP + 1) * STEP, (r + 1) * chunk)
    if window is None:  # what each entry needs: how far it lies beyond that
        beyond = np.maximum(np.maximum(r * chunk - index, index - ahead + 1), 0)
        window = _window(beyond, max(1, -(-n // chunk)), chunk)
    lo = np.maximum(r * chunk - window, 0)
    inside = (index >= lo) & (index < np.minimum(ahead + window, n))
    ranges = max(1, -(-n // chunk))
    key = np.unique(r[~inside] * n + index[~inside])  # (range, vertex), sorted
    far_range, far = key // n, key % n
    far_ptr = np.searchsorted(far_range, np.arange(ranges + 1)).astype(np.int64)
    width = chunk + 2 * window
    local = index - lo
    outside = np.flatnonzero(~inside)
    place = np.searchsorted(key, r[outside] * n + index[outside]) - far_ptr[r[outside]]
    local[outside] = width + place
    local = np.where(start, -local - 1, local)
    if n + 1 >= 2**31 or width + len(far) >= 2**31:
        raise ValueError("too many vertices for int32 fans")
    most = int(np.diff(far_ptr).max()) if ranges else 0
    # regular vertices: seven entries, one chain start, the last the first again
    count = np.diff(ptr)
    seven = np.flatnonzero(count == 7)
    at = ptr[seven][:, None] + np.arange(7)
    entries = local.astype(np.int32)[at] if len(seven) else np.zeros((0, 7), np.int32)
    first = -entries[:, 0] - 1
    one_chain = (entries[:, 1:] >= 0).all(axis=1) & (entries[:, 6] == first)
    regular = seven[one_chain]
    six = np.ascontiguousarray(entries[one_chain, :6].T)
    six[0] = first[one_chain]
    other = np.setdiff1d(np.arange(n), regular, assume_unique=True)
    bounds = np.arange(0, -(-n // STEP) + 1) * STEP
    regular_ptr = np.searchsorted(regular, bounds).astype(np.int64)
    other_ptr = np.searchsorted(other, bounds).astype(np.int64)
    mine = np.repeat(np.isin(np.arange(n), other), count)  # an other vertex's entries
    starts = np.zeros(len(other) + 1, np.int64)
    np.cumsum(count[other], out=starts[1:])
    return Plan(
        n,
        far.astype(np.int32),
        far_ptr,
        int(chunk),
        int(window),
        width,
        most,
        six.astype(np.int32),
        regular.astype(np.int32),
        regular_ptr,
        other.astype(np.int32),
        other_ptr,
        local[mine].astype(np.int32),
        starts,
    )


def _window(beyond: np.ndarray, ranges: int, chunk: int) -> int:
    """The window (a multiple of 256 up to ``chunk``) that costs least: each range applies
    ``2 window`` points more, and every fan entry ``beyond`` it (how far its neighbour lies
    past what its step has applied) a far point, which costs about as much (a gather and
    an apply). A torus's seam or a model numbered without locality then goes far instead
    of widening every range."""
    steps = chunk // 256
    # entries by the least window that holds them, in 256s: far(w) = those above w / 256
    need = np.bincount(np.minimum(-(-beyond // 256), steps + 1), minlength=steps + 2)
    far = need[::-1].cumsum()[::-1][1 : steps + 2]  # far[k]: entries needing more than 256 k
    candidates = 256 * np.arange(steps + 1)
    return int(candidates[np.argmin(2 * ranges * candidates + far)])


@njit(**_IN)
def _six(points, six, k, o, grad):
    """``grad[:, o]`` of a regular vertex (column k of ``six``): the fans' kernel's
    arithmetic for one closed chain of six faces (its three pairs), written out."""
    x, y, z = points[0], points[1], points[2]
    px, py, pz = x[o], y[o], z[o]
    i0, i1, i2 = six[0, k], six[1, k], six[2, k]
    i3, i4, i5 = six[3, k], six[4, k], six[5, k]
    fx, fy, fz = x[i0], y[i0], z[i0]
    sx, sy, sz = 0.0, 0.0, 0.0
    hx, hy, hz = x[i1] - px, y[i1] - py, z[i1] - pz
    ex, ey, ez = x[i2], y[i2], z[i2]
    sx, sy, sz = _plus_cross(sx, sy, sz, hx, hy, hz, ex - fx, ey - fy, ez - fz)
    hx, hy, hz = x[i3] - px, y[i3] - py, z[i3] - pz
    nx, ny, nz = x[i4], y[i4], z[i4]
    sx, sy, sz = _plus_cross(sx, sy, sz, hx, hy, hz, nx - ex, ny - ey, nz - ez)
    hx, hy, hz = x[i5] - px, y[i5] - py, z[i5] - pz
    sx, sy, sz = _plus_cross(sx, sy, sz, hx, hy, hz, fx - nx, fy - ny, fz - nz)
    grad[0, o] = sx / 6.0
    grad[1, o] = sy / 6.0
    grad[2, o] = sz / 6.0


@njit(**KERNEL)
def evaluation_range(
    uvw, x, l, m, n, cx, cy, cz, far, far_ptr, six, regular, regular_ptr, other, other_ptr,
    entries, starts, r, start, stop, window, width, far_uvw, points, grad, acc,
):  # fmt: skip
    """Range r (vertices ``start..stop``) of the evaluation: adds its share of the node
    gradient to ``acc`` (as :func:`core.kernels.basis.transpose_range` does) and returns
    its ``sum_o (P_o - c) . grad_o``. Each helper keeps its own compile options (the
    apply's and the fans' sums in order, the transpose's reassociated), so the numbers are
    the three passes'. ``far_uvw`` (3, far vertices): the lattice coordinates of ``far``
    (gathered by the caller: read-only like ``uvw``, so the apply is compiled once);
    ``points`` (3, width + most far) and ``grad`` (3, width) are scratch."""
    p = uvw.shape[1]
    lo, hi = max(start - window, 0), min(stop + window, p)
    f0, f1 = far_ptr[r], far_ptr[r + 1]
    nf = f1 - f0
    if nf > 0:
        e = width + nf
        _apply_rows(
            far_uvw[0, f0:f1], far_uvw[1, f0:f1], far_uvw[2, f0:f1], x,
            points[0, width:e], points[1, width:e], points[2, width:e],
        )  # fmt: skip
    # steps of STEP vertices: the points are applied just ahead of the fans that read
    # them, and each step's gradient goes to the nodes at once, so what a step touches
    # stays in the core's own cache
    total = 0.0
    done = lo  # the window's points applied so far: lo..done
    for s in range(start, stop, STEP):
        e = min(s + STEP, stop)
        ahead = min(e + window, hi)
        if ahead > done:
            a, b = done - lo, ahead - lo
            u, v, t = uvw[0, done:ahead], uvw[1, done:ahead], uvw[2, done:ahead]
            _apply_rows(u, v, t, x, points[0, a:b], points[1, a:b], points[2, a:b])
            done = ahead
        a, b = s - lo, e - lo
        step = s // STEP
        for k in range(regular_ptr[step], regular_ptr[step + 1]):
            _six(points, six, k, regular[k] - lo, grad)
        x0, x1, x2 = points[0], points[1], points[2]
        g0, g1, g2 = grad[0], grad[1], grad[2]
        for k in range(other_ptr[step], other_ptr[step + 1]):
            o = other[k] - lo
            px, py, pz = x0[o], x1[o], x2[o]
            a0, b0 = starts[k], starts[k + 1]
            sx, sy, sz = _vertex_called(x0, x1, x2, px, py, pz, cx, cy, cz, entries, a0, b0)
            g0[o] = sx / 6.0
            g1[o] = sy / 6.0
            g2[o] = sz / 6.0
        for o in range(a, b):  # the volume's sum in vertex order, as the fans' kernel adds it
            total += (x0[o] - cx) * g0[o] + (x1[o] - cy) * g1[o] + (x2[o] - cz) * g2[o]
        u, v, t = uvw[0, s:e], uvw[1, s:e], uvw[2, s:e]
        _transpose_rows(u, v, t, grad[0, a:b], grad[1, a:b], grad[2, a:b], l, m, n, acc)
    return total
