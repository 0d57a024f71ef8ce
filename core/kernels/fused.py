"""The compiled evaluation in one pass: the basis applied, the volume and its gradient
(:mod:`core.kernels.volume`) and the gradient taken back to the nodes (the basis's
transpose, :mod:`core.kernels.basis`), range of vertices by range.

The three passes one after the other write the (3, m) points and read them back by the
fans' gathers, then write the (3, m) gradient and read it back with the lattice
coordinates again: on a million triangles three times the bytes the evaluation must read
(the coordinates and the fans). Here a range of ``CHUNK`` vertices applies the basis to
its own vertices and ``window`` on either side (their points stay in the cache), walks
its fans there, and takes its gradient back to the nodes at once. A neighbour outside
the window (the seam of a torus, a model numbered without locality) is one of the range's
*far* points, applied beside the window. The fans are renumbered for that once (a
:class:`Plan`), so the kernel walks them as :func:`core.kernels.volume.fan_gradient_range`
does, with the same arithmetic: the numbers are those of the three passes, bit for bit.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .base import KERNEL, njit
from .basis import _apply_rows, _transpose_rows
from .volume import _fan_gradient


class Plan(NamedTuple):
    """The fans renumbered for :func:`evaluation_range` (see the module)."""

    ptr: np.ndarray  #: (m + 1,) int64, as the fans'
    seq: np.ndarray  #: int32: a neighbour in the window by its place there, a far one by
    #: ``width + `` its place in the range's far list (chain starts negative, as the fans')
    far: np.ndarray  #: int32, the ranges' far vertices one after the other
    far_ptr: np.ndarray  #: (ranges + 1,) int64: range r's far vertices
    chunk: int  #: vertices a range
    window: int  #: vertices applied on either side of a range
    width: int  #: ``chunk + 2 window``: where the far points start in a range's buffer
    most_far: int  #: the most far points of one range


def plan(ptr: np.ndarray, seq: np.ndarray, chunk: int, window: int | None = None) -> Plan:
    """The :class:`Plan` of the fans (ptr, seq) for ranges of ``chunk`` vertices: the
    window (by default :func:`_window`'s) and each range's far vertices."""
    n = len(ptr) - 1
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    start = seq < 0
    index = np.where(start, -seq.astype(np.int64) - 1, seq)
    r = owner // chunk
    if window is None:  # what each entry needs: how far it lies beyond its range
        beyond = np.maximum(np.maximum(r * chunk - index, index - (r + 1) * chunk + 1), 0)
        window = _window(beyond, max(1, -(-n // chunk)), chunk)
    lo = np.maximum(r * chunk - window, 0)
    hi = np.minimum((r + 1) * chunk + window, n)
    inside = (index >= lo) & (index < hi)
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
    return Plan(
        np.ascontiguousarray(ptr, dtype=np.int64),
        local.astype(np.int32),
        far.astype(np.int32),
        far_ptr,
        int(chunk),
        int(window),
        width,
        most,
    )


def _window(beyond: np.ndarray, ranges: int, chunk: int) -> int:
    """The window (a multiple of 256 up to ``chunk``) that costs least: each range applies
    ``2 window`` points more, and every fan entry ``beyond`` it (how far its neighbour lies
    past its range) a far point, which costs about as much (a gather and an apply). A
    torus's seam or a model numbered without locality then goes far instead of widening
    every range."""
    need = np.sort(beyond)
    candidates = np.arange(0, chunk + 1, 256)
    far = len(need) - np.searchsorted(need, candidates, side="right")
    return int(candidates[np.argmin(2 * ranges * candidates + far)])


@njit(**KERNEL)
def evaluation_range(
    uvw, x, l, m, n, cx, cy, cz, ptr, seq, far, far_ptr, r, start, stop, window, width,
    points, grad, far_uvw, acc,
):  # fmt: skip
    """Range r (vertices ``start..stop``) of the evaluation: adds its share of the node
    gradient to ``acc`` (as :func:`core.kernels.basis.transpose_range` does) and returns
    its ``sum_o (P_o - c) . grad_o``. Each helper keeps its own compile options (the
    apply's and the fans' sums in order, the transpose's reassociated), so the numbers are
    the three passes'. ``points`` (3, width + most far), ``grad`` (3, width) and
    ``far_uvw`` (3, most far) are scratch."""
    p = uvw.shape[1]
    lo, hi = max(start - window, 0), min(stop + window, p)
    w = hi - lo
    u, v, t = uvw[0, lo:hi], uvw[1, lo:hi], uvw[2, lo:hi]
    _apply_rows(u, v, t, x, points[0, :w], points[1, :w], points[2, :w])
    f0, f1 = far_ptr[r], far_ptr[r + 1]
    nf = f1 - f0
    if nf > 0:
        for q in range(nf):
            i = far[f0 + q]
            far_uvw[0, q] = uvw[0, i]
            far_uvw[1, q] = uvw[1, i]
            far_uvw[2, q] = uvw[2, i]
        e = width + nf
        _apply_rows(
            far_uvw[0, :nf], far_uvw[1, :nf], far_uvw[2, :nf], x,
            points[0, width:e], points[1, width:e], points[2, width:e],
        )  # fmt: skip
    total = _fan_gradient(points, cx, cy, cz, ptr[lo:], seq, grad, start - lo, stop - lo)
    a, b = start - lo, stop - lo
    u, v, t = uvw[0, start:stop], uvw[1, start:stop], uvw[2, start:stop]
    _transpose_rows(u, v, t, grad[0, a:b], grad[1, a:b], grad[2, a:b], l, m, n, acc)
    return total
