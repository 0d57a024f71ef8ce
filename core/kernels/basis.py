"""Compiled FFD basis kernels: :meth:`core.lattice.PointBasis.apply` and its transpose.

Nothing is stored per point but its lattice coordinates ``uvw`` (3, p): each block of
``BLOCK`` points evaluates its Bernstein rows (:mod:`core.kernels.bern`) in scratch that stays
in the L1 cache and contracts them with the nodes at once, so one evaluation reads 24
bytes per point instead of the factored basis's ``8 (l m + n)``.

The loops run over the points of a block (they vectorise); the node axes are loops around
them. The innermost node axis ``k`` (n nodes) is summed in registers: all n layers at once
up to 5, else in groups of 2 or 3 whose last one adds straight into the result, so each
point costs about ``3 l m n`` multiply-adds and few loads and stores:

- apply: ``out_c = sum_ij Bu_i Bv_j (sum_k Bw_k X_ijkc)``;
- transpose: ``G_ijkc += sum_q Bu_i Bv_j Bw_k g_c`` over the block's points, summed with
  reassociation (several partial sums, so the loop vectorises), into an accumulator of
  the caller's, one per range of points (:mod:`core.kernels` adds them in a fixed order, so
  the result does not depend on the number of threads).

The kernels release the GIL; :mod:`core.kernels` runs them on ranges of points, one thread
each. Compiled on first use by :mod:`core.kernels` in a background thread.
"""

from __future__ import annotations

import numpy as np

from .base import INLINE, INLINE_REDUCE, KERNEL, REDUCE, njit
from .bern import _bernstein

#: points per block: the Bernstein rows and accumulators of a block (at most 45 rows of
#: 2 KB) stay in the L1 cache
BLOCK = 256

#: the loop helpers are inlined into the kernels in numba's IR (``inline="always"``), each
#: taking the rows it reads: a helper that indexed a 2-D scratch and branched on the group
#: size inside its loops was called, and its loops ran 2-2.5x slower than these (the
#: 1M-triangle evaluation's apply 8.6 ns a point instead of 3.6, one thread)
_IN = {**INLINE, "inline": "always"}
_IN_REDUCE = {**INLINE_REDUCE, "inline": "always"}


@njit(**_IN)
def _z2(z0, z1, z2, b0, b1, x, c, w, first):
    """``z_c (=, or += unless first) b0 x[c + c'] + b1 x[c + 3 + c']``."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    if first:
        for q in range(w):
            u0, u1 = b0[q], b1[q]
            z0[q] = u0 * x00 + u1 * x10
            z1[q] = u0 * x01 + u1 * x11
            z2[q] = u0 * x02 + u1 * x12
    else:
        for q in range(w):
            u0, u1 = b0[q], b1[q]
            z0[q] += u0 * x00 + u1 * x10
            z1[q] += u0 * x01 + u1 * x11
            z2[q] += u0 * x02 + u1 * x12


@njit(**_IN)
def _z3(z0, z1, z2, b0, b1, b2, x, c, w, first):
    """``z_c (=, or += unless first) sum_t b_t x[c + 3 t + c']`` over 3 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    if first:
        for q in range(w):
            u0, u1, u2 = b0[q], b1[q], b2[q]
            z0[q] = u0 * x00 + u1 * x10 + u2 * x20
            z1[q] = u0 * x01 + u1 * x11 + u2 * x21
            z2[q] = u0 * x02 + u1 * x12 + u2 * x22
    else:
        for q in range(w):
            u0, u1, u2 = b0[q], b1[q], b2[q]
            z0[q] += u0 * x00 + u1 * x10 + u2 * x20
            z1[q] += u0 * x01 + u1 * x11 + u2 * x21
            z2[q] += u0 * x02 + u1 * x12 + u2 * x22


@njit(**_IN)
def _f2z(o0, o1, o2, a_i, a_j, z0, z1, z2, b0, b1, x, c, w):
    """``o_c += a_i a_j (z_c + b0 x[c + c'] + b1 x[c + 3 + c'])``: the last 2 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    for q in range(w):
        u0, u1 = b0[q], b1[q]
        a = a_i[q] * a_j[q]
        o0[q] += a * (z0[q] + u0 * x00 + u1 * x10)
        o1[q] += a * (z1[q] + u0 * x01 + u1 * x11)
        o2[q] += a * (z2[q] + u0 * x02 + u1 * x12)


@njit(**_IN)
def _f3z(o0, o1, o2, a_i, a_j, z0, z1, z2, b0, b1, b2, x, c, w):
    """``o_c += a_i a_j (z_c + sum_t b_t x[c + 3 t + c'])``: the last 3 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    for q in range(w):
        u0, u1, u2 = b0[q], b1[q], b2[q]
        a = a_i[q] * a_j[q]
        o0[q] += a * (z0[q] + u0 * x00 + u1 * x10 + u2 * x20)
        o1[q] += a * (z1[q] + u0 * x01 + u1 * x11 + u2 * x21)
        o2[q] += a * (z2[q] + u0 * x02 + u1 * x12 + u2 * x22)


@njit(**_IN)
def _f2(o0, o1, o2, a_i, a_j, b0, b1, x, c, w):
    """``o_c += a_i a_j (b0 x[c + c'] + b1 x[c + 3 + c'])``: all 2 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    for q in range(w):
        u0, u1 = b0[q], b1[q]
        a = a_i[q] * a_j[q]
        o0[q] += a * (u0 * x00 + u1 * x10)
        o1[q] += a * (u0 * x01 + u1 * x11)
        o2[q] += a * (u0 * x02 + u1 * x12)


@njit(**_IN)
def _f3(o0, o1, o2, a_i, a_j, b0, b1, b2, x, c, w):
    """``o_c += a_i a_j sum_t b_t x[c + 3 t + c']``: all 3 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    for q in range(w):
        u0, u1, u2 = b0[q], b1[q], b2[q]
        a = a_i[q] * a_j[q]
        o0[q] += a * (u0 * x00 + u1 * x10 + u2 * x20)
        o1[q] += a * (u0 * x01 + u1 * x11 + u2 * x21)
        o2[q] += a * (u0 * x02 + u1 * x12 + u2 * x22)


@njit(**_IN)
def _f4(o0, o1, o2, a_i, a_j, b0, b1, b2, b3, x, c, w):
    """``o_c += a_i a_j sum_t b_t x[c + 3 t + c']``: all 4 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    x30, x31, x32 = x[c + 9], x[c + 10], x[c + 11]
    for q in range(w):
        u0, u1, u2, u3 = b0[q], b1[q], b2[q], b3[q]
        a = a_i[q] * a_j[q]
        o0[q] += a * (u0 * x00 + u1 * x10 + u2 * x20 + u3 * x30)
        o1[q] += a * (u0 * x01 + u1 * x11 + u2 * x21 + u3 * x31)
        o2[q] += a * (u0 * x02 + u1 * x12 + u2 * x22 + u3 * x32)


@njit(**_IN)
def _f5(o0, o1, o2, a_i, a_j, b0, b1, b2, b3, b4, x, c, w):
    """``o_c += a_i a_j sum_t b_t x[c + 3 t + c']``: all 5 layers."""
    x00, x01, x02 = x[c], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    x30, x31, x32 = x[c + 9], x[c + 10], x[c + 11]
    x40, x41, x42 = x[c + 12], x[c + 13], x[c + 14]
    for q in range(w):
        u0, u1, u2, u3, u4 = b0[q], b1[q], b2[q], b3[q], b4[q]
        a = a_i[q] * a_j[q]
        o0[q] += a * (u0 * x00 + u1 * x10 + u2 * x20 + u3 * x30 + u4 * x40)
        o1[q] += a * (u0 * x01 + u1 * x11 + u2 * x21 + u3 * x31 + u4 * x41)
        o2[q] += a * (u0 * x02 + u1 * x12 + u2 * x22 + u3 * x32 + u4 * x42)


@njit(**_IN_REDUCE)
def _r2(acc, c, b0, b1, a_i, a_j, g0, g1, g2, w):
    """``acc[c + 3 t + c'] += sum_q a_i a_j g_c' b_t`` for the 2 layers t."""
    t00, t01, t02 = 0.0, 0.0, 0.0
    t10, t11, t12 = 0.0, 0.0, 0.0
    for q in range(w):
        a = a_i[q] * a_j[q]
        y0, y1, y2 = a * g0[q], a * g1[q], a * g2[q]
        u0, u1 = b0[q], b1[q]
        t00 += u0 * y0
        t01 += u0 * y1
        t02 += u0 * y2
        t10 += u1 * y0
        t11 += u1 * y1
        t12 += u1 * y2
    acc[c] += t00
    acc[c + 1] += t01
    acc[c + 2] += t02
    acc[c + 3] += t10
    acc[c + 4] += t11
    acc[c + 5] += t12


@njit(**_IN_REDUCE)
def _r3(acc, c, b0, b1, b2, a_i, a_j, g0, g1, g2, w):
    """``acc[c + 3 t + c'] += sum_q a_i a_j g_c' b_t`` for the 3 layers t."""
    t00, t01, t02 = 0.0, 0.0, 0.0
    t10, t11, t12 = 0.0, 0.0, 0.0
    t20, t21, t22 = 0.0, 0.0, 0.0
    for q in range(w):
        a = a_i[q] * a_j[q]
        y0, y1, y2 = a * g0[q], a * g1[q], a * g2[q]
        u0, u1, u2 = b0[q], b1[q], b2[q]
        t00 += u0 * y0
        t01 += u0 * y1
        t02 += u0 * y2
        t10 += u1 * y0
        t11 += u1 * y1
        t12 += u1 * y2
        t20 += u2 * y0
        t21 += u2 * y1
        t22 += u2 * y2
    acc[c] += t00
    acc[c + 1] += t01
    acc[c + 2] += t02
    acc[c + 3] += t10
    acc[c + 4] += t11
    acc[c + 5] += t12
    acc[c + 6] += t20
    acc[c + 7] += t21
    acc[c + 8] += t22


@njit(**_IN_REDUCE)
def _r4(acc, c, b0, b1, b2, b3, a_i, a_j, g0, g1, g2, w):
    """``acc[c + 3 t + c'] += sum_q a_i a_j g_c' b_t`` for the 4 layers t."""
    t00, t01, t02 = 0.0, 0.0, 0.0
    t10, t11, t12 = 0.0, 0.0, 0.0
    t20, t21, t22 = 0.0, 0.0, 0.0
    t30, t31, t32 = 0.0, 0.0, 0.0
    for q in range(w):
        a = a_i[q] * a_j[q]
        y0, y1, y2 = a * g0[q], a * g1[q], a * g2[q]
        u0, u1, u2, u3 = b0[q], b1[q], b2[q], b3[q]
        t00 += u0 * y0
        t01 += u0 * y1
        t02 += u0 * y2
        t10 += u1 * y0
        t11 += u1 * y1
        t12 += u1 * y2
        t20 += u2 * y0
        t21 += u2 * y1
        t22 += u2 * y2
        t30 += u3 * y0
        t31 += u3 * y1
        t32 += u3 * y2
    acc[c] += t00
    acc[c + 1] += t01
    acc[c + 2] += t02
    acc[c + 3] += t10
    acc[c + 4] += t11
    acc[c + 5] += t12
    acc[c + 6] += t20
    acc[c + 7] += t21
    acc[c + 8] += t22
    acc[c + 9] += t30
    acc[c + 10] += t31
    acc[c + 11] += t32


@njit(**_IN_REDUCE)
def _r5(acc, c, b0, b1, b2, b3, b4, a_i, a_j, g0, g1, g2, w):
    """``acc[c + 3 t + c'] += sum_q a_i a_j g_c' b_t`` for the 5 layers t."""
    t00, t01, t02 = 0.0, 0.0, 0.0
    t10, t11, t12 = 0.0, 0.0, 0.0
    t20, t21, t22 = 0.0, 0.0, 0.0
    t30, t31, t32 = 0.0, 0.0, 0.0
    t40, t41, t42 = 0.0, 0.0, 0.0
    for q in range(w):
        a = a_i[q] * a_j[q]
        y0, y1, y2 = a * g0[q], a * g1[q], a * g2[q]
        u0, u1, u2, u3, u4 = b0[q], b1[q], b2[q], b3[q], b4[q]
        t00 += u0 * y0
        t01 += u0 * y1
        t02 += u0 * y2
        t10 += u1 * y0
        t11 += u1 * y1
        t12 += u1 * y2
        t20 += u2 * y0
        t21 += u2 * y1
        t22 += u2 * y2
        t30 += u3 * y0
        t31 += u3 * y1
        t32 += u3 * y2
        t40 += u4 * y0
        t41 += u4 * y1
        t42 += u4 * y2
    acc[c] += t00
    acc[c + 1] += t01
    acc[c + 2] += t02
    acc[c + 3] += t10
    acc[c + 4] += t11
    acc[c + 5] += t12
    acc[c + 6] += t20
    acc[c + 7] += t21
    acc[c + 8] += t22
    acc[c + 9] += t30
    acc[c + 10] += t31
    acc[c + 11] += t32
    acc[c + 12] += t40
    acc[c + 13] += t41
    acc[c + 14] += t42


@njit(**KERNEL)
def apply_range(uvw, x, out, start, stop):
    """``out[:, start:stop]``: the deformed points ``start..stop`` (rows x, y, z).

    uvw : (3, p) lattice coordinates; x : (l, m, 3 n) nodes, ``x[i, j, 3 k + c]``.
    """
    u, v, t = uvw[0, start:stop], uvw[1, start:stop], uvw[2, start:stop]
    _apply_rows(u, v, t, x, out[0, start:stop], out[1, start:stop], out[2, start:stop])


@njit(**INLINE)
def _apply_rows(u, v, t, x, r0, r1, r2):
    """``r_c[q]``: the deformed points of the lattice coordinates ``u, v, t`` (rows of one
    length; blocks of ``BLOCK`` from the first), x as in :func:`apply_range`."""
    start, stop = 0, len(u)
    l, m, n3 = x.shape
    n = n3 // 3
    ng = (n + 2) // 3
    xf = x.reshape(l * m * n3)
    bu = np.empty((l, BLOCK))
    bv = np.empty((m, BLOCK))
    bw = np.empty((n, BLOCK))
    z = np.empty((3, BLOCK))
    o = np.empty((3, BLOCK))
    z0, z1, z2 = z[0], z[1], z[2]
    o0, o1, o2 = o[0], o[1], o[2]
    for s in range(start, stop, BLOCK):
        w = min(BLOCK, stop - s)
        _bernstein(u[s : s + w], w, l - 1, bu)
        _bernstein(v[s : s + w], w, m - 1, bv)
        _bernstein(t[s : s + w], w, n - 1, bw)
        for q in range(w):
            o0[q] = 0.0
            o1[q] = 0.0
            o2[q] = 0.0
        # the rows of the first layers, taken once a block (not once a node column)
        b0, b1, b2 = bw[0], bw[1], bw[min(2, n - 1)]
        b3, b4 = bw[min(3, n - 1)], bw[min(4, n - 1)]
        # all layers at once up to 5, one loop nest per count (a branch inside the nest
        # kept its loops from vectorising as well)
        if n == 2:
            for i in range(l):
                for j in range(m):
                    _f2(o0, o1, o2, bu[i], bv[j], b0, b1, xf, (i * m + j) * n3, w)
        elif n == 3:
            for i in range(l):
                for j in range(m):
                    _f3(o0, o1, o2, bu[i], bv[j], b0, b1, b2, xf, (i * m + j) * n3, w)
        elif n == 4:
            for i in range(l):
                for j in range(m):
                    _f4(o0, o1, o2, bu[i], bv[j], b0, b1, b2, b3, xf, (i * m + j) * n3, w)
        elif n == 5:
            for i in range(l):
                for j in range(m):
                    _f5(o0, o1, o2, bu[i], bv[j], b0, b1, b2, b3, b4, xf, (i * m + j) * n3, w)
        else:
            for i in range(l):
                a_i = bu[i]
                for j in range(m):
                    a_j = bv[j]
                    at = (i * m + j) * n3
                    k = 0  # groups of 2 or 3 layers, the last one added to the result
                    for gi in range(ng - 1):
                        g = (n - k) // (ng - gi)
                        if g == 2:
                            _z2(z0, z1, z2, bw[k], bw[k + 1], xf, at + 3 * k, w, gi == 0)
                        else:
                            _z3(
                                z0, z1, z2, bw[k], bw[k + 1], bw[k + 2], xf, at + 3 * k, w,
                                gi == 0,
                            )  # fmt: skip
                        k += g
                    if n - k == 2:
                        _f2z(
                            o0, o1, o2, a_i, a_j, z0, z1, z2, bw[k], bw[k + 1], xf, at + 3 * k, w
                        )  # fmt: skip
                    else:
                        _f3z(
                            o0, o1, o2, a_i, a_j, z0, z1, z2, bw[k], bw[k + 1], bw[k + 2], xf,
                            at + 3 * k, w,
                        )  # fmt: skip
        for q in range(w):
            r0[s + q] = o0[q]
            r1[s + q] = o1[q]
            r2[s + q] = o2[q]


@njit(**REDUCE)
def transpose_range(uvw, g, l, m, n, start, stop, acc):
    """``acc[((i m + j) n + k) 3 + c] += sum_q B_ijk(q) g[c, q]`` over the points
    ``start..stop``; uvw and g are (3, p)."""
    u, v, t = uvw[0, start:stop], uvw[1, start:stop], uvw[2, start:stop]
    _transpose_rows(u, v, t, g[0, start:stop], g[1, start:stop], g[2, start:stop], l, m, n, acc)


@njit(**INLINE_REDUCE)
def _transpose_rows(u, v, t, h0, h1, h2, l, m, n, acc):
    """:func:`transpose_range` of the rows ``u, v, t`` (lattice coordinates) and ``h_c``
    (per-point values), all of one length, in blocks of ``BLOCK`` from the first."""
    start, stop = 0, len(u)
    ng = (n + 2) // 3
    n3 = 3 * n
    bu = np.empty((l, BLOCK))
    bv = np.empty((m, BLOCK))
    bw = np.empty((n, BLOCK))
    for s in range(start, stop, BLOCK):
        w = min(BLOCK, stop - s)
        _bernstein(u[s : s + w], w, l - 1, bu)
        _bernstein(v[s : s + w], w, m - 1, bv)
        _bernstein(t[s : s + w], w, n - 1, bw)
        g0, g1, g2 = h0[s : s + w], h1[s : s + w], h2[s : s + w]
        b0, b1, b2 = bw[0], bw[1], bw[min(2, n - 1)]
        b3, b4 = bw[min(3, n - 1)], bw[min(4, n - 1)]
        # all layers at once up to 5, one loop nest per count (as in apply_range)
        if n == 2:
            for i in range(l):
                for j in range(m):
                    _r2(acc, (i * m + j) * n3, b0, b1, bu[i], bv[j], g0, g1, g2, w)
        elif n == 3:
            for i in range(l):
                for j in range(m):
                    _r3(acc, (i * m + j) * n3, b0, b1, b2, bu[i], bv[j], g0, g1, g2, w)
        elif n == 4:
            for i in range(l):
                for j in range(m):
                    _r4(acc, (i * m + j) * n3, b0, b1, b2, b3, bu[i], bv[j], g0, g1, g2, w)
        elif n == 5:
            for i in range(l):
                for j in range(m):
                    at = (i * m + j) * n3
                    _r5(acc, at, b0, b1, b2, b3, b4, bu[i], bv[j], g0, g1, g2, w)
        else:
            for i in range(l):
                a_i = bu[i]
                for j in range(m):
                    a_j = bv[j]
                    at = (i * m + j) * n3
                    k = 0
                    for gi in range(ng):  # groups of 2 or 3 layers
                        size = (n - k) // (ng - gi)
                        c = at + 3 * k
                        if size == 2:
                            _r2(acc, c, bw[k], bw[k + 1], a_i, a_j, g0, g1, g2, w)
                        else:
                            _r3(acc, c, bw[k], bw[k + 1], bw[k + 2], a_i, a_j, g0, g1, g2, w)
                        k += size
