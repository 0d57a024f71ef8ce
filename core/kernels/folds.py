"""Compiled ``det J`` of the FFD at points given by their lattice coordinates: the fold
check of every solve's result (:func:`core.goal.folds._determinants`).

Per block of ``BLOCK`` points the Bernstein polynomials and their derivatives are evaluated
(:func:`_pair`, the formula of :func:`core.goal.folds._bernstein_pair`), then the three parameter
derivatives ``dX/du``, ``dX/dv``, ``dX/dw`` are contracted axis by axis, w first, with the
points innermost (the loops vectorise), and turned into world columns by ``to_world``;
``det J`` is their triple product. Compiled by :mod:`core.kernels` in the background.
"""

from __future__ import annotations

import numpy as np

from .base import INLINE, KERNEL, njit
from .basis import BLOCK
from .bern import _bernstein


@njit(**INLINE)
def _pair(t, w, d, low, b, db):
    """``b[i, q] = B_i^d(t[q])`` and ``db[i, q]`` its derivative, i = 0..d (d >= 1), from
    the degree d - 1 polynomials (written to ``low``)."""
    _bernstein(t, w, d - 1, low)
    for i in range(d + 1):
        bi, dbi = b[i], db[i]
        for q in range(w):
            v = 0.0
            dv = 0.0
            if i < d:
                v += (1.0 - t[q]) * low[i, q]
                dv -= low[i, q]
            if i > 0:
                v += t[q] * low[i - 1, q]
                dv += low[i - 1, q]
            bi[q] = v
            dbi[q] = d * dv


#: the node-column helpers are inlined (numba IR), taking the rows they read: one loop over
#: the block's points a column, its layers summed in registers (as in
#: :mod:`core.kernels.basis`), instead of a loop a layer and coordinate through scratch
_IN = {**INLINE, "inline": "always"}


@njit(**_IN)
def _column2(zv, zdv, zdw, b0, b1, e0, e1, bj, dbj, x, c, w):
    """One node column (i, j) of 2 layers: ``y = sum_k x_k B_k``, ``yd = sum_k x_k
    B'_k`` (k in order, as the layer-by-layer loop adds them), then ``zv += y B_j``,
    ``zdv += y B'_j``, ``zdw += yd B_j``; x flat from ``c``."""
    x00, x01, x02 = x[c + 0], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    zv0, zv1, zv2 = zv[0], zv[1], zv[2]
    zdv0, zdv1, zdv2 = zdv[0], zdv[1], zdv[2]
    zdw0, zdw1, zdw2 = zdw[0], zdw[1], zdw[2]
    for q in range(w):
        u0, v0 = b0[q], e0[q]
        u1, v1 = b1[q], e1[q]
        y0 = 0.0
        d0 = 0.0
        y1 = 0.0
        d1 = 0.0
        y2 = 0.0
        d2 = 0.0
        y0 += x00 * u0
        d0 += x00 * v0
        y1 += x01 * u0
        d1 += x01 * v0
        y2 += x02 * u0
        d2 += x02 * v0
        y0 += x10 * u1
        d0 += x10 * v1
        y1 += x11 * u1
        d1 += x11 * v1
        y2 += x12 * u1
        d2 += x12 * v1
        bq, dq = bj[q], dbj[q]
        zv0[q] += y0 * bq
        zdv0[q] += y0 * dq
        zdw0[q] += d0 * bq
        zv1[q] += y1 * bq
        zdv1[q] += y1 * dq
        zdw1[q] += d1 * bq
        zv2[q] += y2 * bq
        zdv2[q] += y2 * dq
        zdw2[q] += d2 * bq


@njit(**_IN)
def _column3(zv, zdv, zdw, b0, b1, b2, e0, e1, e2, bj, dbj, x, c, w):
    """One node column (i, j) of 3 layers: ``y = sum_k x_k B_k``, ``yd = sum_k x_k
    B'_k`` (k in order, as the layer-by-layer loop adds them), then ``zv += y B_j``,
    ``zdv += y B'_j``, ``zdw += yd B_j``; x flat from ``c``."""
    x00, x01, x02 = x[c + 0], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    zv0, zv1, zv2 = zv[0], zv[1], zv[2]
    zdv0, zdv1, zdv2 = zdv[0], zdv[1], zdv[2]
    zdw0, zdw1, zdw2 = zdw[0], zdw[1], zdw[2]
    for q in range(w):
        u0, v0 = b0[q], e0[q]
        u1, v1 = b1[q], e1[q]
        u2, v2 = b2[q], e2[q]
        y0 = 0.0
        d0 = 0.0
        y1 = 0.0
        d1 = 0.0
        y2 = 0.0
        d2 = 0.0
        y0 += x00 * u0
        d0 += x00 * v0
        y1 += x01 * u0
        d1 += x01 * v0
        y2 += x02 * u0
        d2 += x02 * v0
        y0 += x10 * u1
        d0 += x10 * v1
        y1 += x11 * u1
        d1 += x11 * v1
        y2 += x12 * u1
        d2 += x12 * v1
        y0 += x20 * u2
        d0 += x20 * v2
        y1 += x21 * u2
        d1 += x21 * v2
        y2 += x22 * u2
        d2 += x22 * v2
        bq, dq = bj[q], dbj[q]
        zv0[q] += y0 * bq
        zdv0[q] += y0 * dq
        zdw0[q] += d0 * bq
        zv1[q] += y1 * bq
        zdv1[q] += y1 * dq
        zdw1[q] += d1 * bq
        zv2[q] += y2 * bq
        zdv2[q] += y2 * dq
        zdw2[q] += d2 * bq


@njit(**_IN)
def _column4(zv, zdv, zdw, b0, b1, b2, b3, e0, e1, e2, e3, bj, dbj, x, c, w):
    """One node column (i, j) of 4 layers: ``y = sum_k x_k B_k``, ``yd = sum_k x_k
    B'_k`` (k in order, as the layer-by-layer loop adds them), then ``zv += y B_j``,
    ``zdv += y B'_j``, ``zdw += yd B_j``; x flat from ``c``."""
    x00, x01, x02 = x[c + 0], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    x30, x31, x32 = x[c + 9], x[c + 10], x[c + 11]
    zv0, zv1, zv2 = zv[0], zv[1], zv[2]
    zdv0, zdv1, zdv2 = zdv[0], zdv[1], zdv[2]
    zdw0, zdw1, zdw2 = zdw[0], zdw[1], zdw[2]
    for q in range(w):
        u0, v0 = b0[q], e0[q]
        u1, v1 = b1[q], e1[q]
        u2, v2 = b2[q], e2[q]
        u3, v3 = b3[q], e3[q]
        y0 = 0.0
        d0 = 0.0
        y1 = 0.0
        d1 = 0.0
        y2 = 0.0
        d2 = 0.0
        y0 += x00 * u0
        d0 += x00 * v0
        y1 += x01 * u0
        d1 += x01 * v0
        y2 += x02 * u0
        d2 += x02 * v0
        y0 += x10 * u1
        d0 += x10 * v1
        y1 += x11 * u1
        d1 += x11 * v1
        y2 += x12 * u1
        d2 += x12 * v1
        y0 += x20 * u2
        d0 += x20 * v2
        y1 += x21 * u2
        d1 += x21 * v2
        y2 += x22 * u2
        d2 += x22 * v2
        y0 += x30 * u3
        d0 += x30 * v3
        y1 += x31 * u3
        d1 += x31 * v3
        y2 += x32 * u3
        d2 += x32 * v3
        bq, dq = bj[q], dbj[q]
        zv0[q] += y0 * bq
        zdv0[q] += y0 * dq
        zdw0[q] += d0 * bq
        zv1[q] += y1 * bq
        zdv1[q] += y1 * dq
        zdw1[q] += d1 * bq
        zv2[q] += y2 * bq
        zdv2[q] += y2 * dq
        zdw2[q] += d2 * bq


@njit(**_IN)
def _column5(zv, zdv, zdw, b0, b1, b2, b3, b4, e0, e1, e2, e3, e4, bj, dbj, x, c, w):
    """One node column (i, j) of 5 layers: ``y = sum_k x_k B_k``, ``yd = sum_k x_k
    B'_k`` (k in order, as the layer-by-layer loop adds them), then ``zv += y B_j``,
    ``zdv += y B'_j``, ``zdw += yd B_j``; x flat from ``c``."""
    x00, x01, x02 = x[c + 0], x[c + 1], x[c + 2]
    x10, x11, x12 = x[c + 3], x[c + 4], x[c + 5]
    x20, x21, x22 = x[c + 6], x[c + 7], x[c + 8]
    x30, x31, x32 = x[c + 9], x[c + 10], x[c + 11]
    x40, x41, x42 = x[c + 12], x[c + 13], x[c + 14]
    zv0, zv1, zv2 = zv[0], zv[1], zv[2]
    zdv0, zdv1, zdv2 = zdv[0], zdv[1], zdv[2]
    zdw0, zdw1, zdw2 = zdw[0], zdw[1], zdw[2]
    for q in range(w):
        u0, v0 = b0[q], e0[q]
        u1, v1 = b1[q], e1[q]
        u2, v2 = b2[q], e2[q]
        u3, v3 = b3[q], e3[q]
        u4, v4 = b4[q], e4[q]
        y0 = 0.0
        d0 = 0.0
        y1 = 0.0
        d1 = 0.0
        y2 = 0.0
        d2 = 0.0
        y0 += x00 * u0
        d0 += x00 * v0
        y1 += x01 * u0
        d1 += x01 * v0
        y2 += x02 * u0
        d2 += x02 * v0
        y0 += x10 * u1
        d0 += x10 * v1
        y1 += x11 * u1
        d1 += x11 * v1
        y2 += x12 * u1
        d2 += x12 * v1
        y0 += x20 * u2
        d0 += x20 * v2
        y1 += x21 * u2
        d1 += x21 * v2
        y2 += x22 * u2
        d2 += x22 * v2
        y0 += x30 * u3
        d0 += x30 * v3
        y1 += x31 * u3
        d1 += x31 * v3
        y2 += x32 * u3
        d2 += x32 * v3
        y0 += x40 * u4
        d0 += x40 * v4
        y1 += x41 * u4
        d1 += x41 * v4
        y2 += x42 * u4
        d2 += x42 * v4
        bq, dq = bj[q], dbj[q]
        zv0[q] += y0 * bq
        zdv0[q] += y0 * dq
        zdw0[q] += d0 * bq
        zv1[q] += y1 * bq
        zdv1[q] += y1 * dq
        zdw1[q] += d1 * bq
        zv2[q] += y2 * bq
        zdv2[q] += y2 * dq
        zdw2[q] += d2 * bq


@njit(**KERNEL)
def determinant_range(uvw, x, to_world, out, frobenius, start, stop):
    """``out[start:stop]``: det J at the points ``start..stop`` of the (3, p) lattice
    coordinates ``uvw``, for the (l, m, n, 3) nodes ``x``; ``to_world`` (3, 3) is
    ``inv(axes).T``. Unless ``frobenius`` is empty, ``frobenius[start:stop]`` gets
    ``|J|_F^2`` there too (the fold guard's bound)."""
    squares = len(frobenius) > 0
    l, m, n = x.shape[0], x.shape[1], x.shape[2]
    n3 = 3 * n
    xf = x.reshape(l * m * n3)
    low = np.empty((10, BLOCK))
    bu, dbu = np.empty((l, BLOCK)), np.empty((l, BLOCK))
    bv, dbv = np.empty((m, BLOCK)), np.empty((m, BLOCK))
    bw, dbw = np.empty((n, BLOCK)), np.empty((n, BLOCK))
    yw, ydw = np.empty((3, BLOCK)), np.empty((3, BLOCK))
    zv, zdv, zdw = np.empty((3, BLOCK)), np.empty((3, BLOCK)), np.empty((3, BLOCK))
    du, dv, dw = np.empty((3, BLOCK)), np.empty((3, BLOCK)), np.empty((3, BLOCK))
    for s in range(start, stop, BLOCK):
        w = min(BLOCK, stop - s)
        _pair(uvw[0, s : s + w], w, l - 1, low, bu, dbu)
        _pair(uvw[1, s : s + w], w, m - 1, low, bv, dbv)
        _pair(uvw[2, s : s + w], w, n - 1, low, bw, dbw)
        du[:, :w] = 0.0
        dv[:, :w] = 0.0
        dw[:, :w] = 0.0
        b0, b1, b2 = bw[0], bw[1], bw[min(2, n - 1)]
        b3, b4 = bw[min(3, n - 1)], bw[min(4, n - 1)]
        e0, e1, e2 = dbw[0], dbw[1], dbw[min(2, n - 1)]
        e3, e4 = dbw[min(3, n - 1)], dbw[min(4, n - 1)]
        for i in range(l):
            zv[:, :w] = 0.0
            zdv[:, :w] = 0.0
            zdw[:, :w] = 0.0
            at = i * m * n3
            if n == 2:
                for j in range(m):
                    _column2(zv, zdv, zdw, b0, b1, e0, e1, bv[j], dbv[j], xf, at + j * n3, w)
            elif n == 3:
                for j in range(m):
                    c = at + j * n3
                    _column3(zv, zdv, zdw, b0, b1, b2, e0, e1, e2, bv[j], dbv[j], xf, c, w)
            elif n == 4:
                for j in range(m):
                    c = at + j * n3
                    _column4(
                        zv, zdv, zdw, b0, b1, b2, b3, e0, e1, e2, e3, bv[j], dbv[j], xf, c, w
                    )  # fmt: skip
            elif n == 5:
                for j in range(m):
                    c = at + j * n3
                    _column5(
                        zv, zdv, zdw, b0, b1, b2, b3, b4, e0, e1, e2, e3, e4, bv[j], dbv[j],
                        xf, c, w,
                    )  # fmt: skip
            for j in range(m if n > 5 else 0):
                yw[:, :w] = 0.0
                ydw[:, :w] = 0.0
                for k in range(n):
                    bk, dbk = bw[k], dbw[k]
                    for c in range(3):
                        xc = x[i, j, k, c]
                        ywc, ydwc = yw[c], ydw[c]
                        for q in range(w):
                            ywc[q] += xc * bk[q]
                            ydwc[q] += xc * dbk[q]
                bj, dbj = bv[j], dbv[j]
                for c in range(3):
                    ywc, ydwc = yw[c], ydw[c]
                    zvc, zdvc, zdwc = zv[c], zdv[c], zdw[c]
                    for q in range(w):
                        zvc[q] += ywc[q] * bj[q]
                        zdvc[q] += ywc[q] * dbj[q]
                        zdwc[q] += ydwc[q] * bj[q]
            bi, dbi = bu[i], dbu[i]
            for c in range(3):
                duc, dvc, dwc = du[c], dv[c], dw[c]
                zvc, zdvc, zdwc = zv[c], zdv[c], zdw[c]
                for q in range(w):
                    duc[q] += zvc[q] * dbi[q]
                    dvc[q] += zdvc[q] * bi[q]
                    dwc[q] += zdwc[q] * bi[q]
        t = to_world
        for q in range(w):
            # world column e of J: sum_r to_world[r, e] * (du, dv, dw)[r], coordinates a
            c00 = t[0, 0] * du[0, q] + t[1, 0] * dv[0, q] + t[2, 0] * dw[0, q]
            c01 = t[0, 0] * du[1, q] + t[1, 0] * dv[1, q] + t[2, 0] * dw[1, q]
            c02 = t[0, 0] * du[2, q] + t[1, 0] * dv[2, q] + t[2, 0] * dw[2, q]
            c10 = t[0, 1] * du[0, q] + t[1, 1] * dv[0, q] + t[2, 1] * dw[0, q]
            c11 = t[0, 1] * du[1, q] + t[1, 1] * dv[1, q] + t[2, 1] * dw[1, q]
            c12 = t[0, 1] * du[2, q] + t[1, 1] * dv[2, q] + t[2, 1] * dw[2, q]
            c20 = t[0, 2] * du[0, q] + t[1, 2] * dv[0, q] + t[2, 2] * dw[0, q]
            c21 = t[0, 2] * du[1, q] + t[1, 2] * dv[1, q] + t[2, 2] * dw[1, q]
            c22 = t[0, 2] * du[2, q] + t[1, 2] * dv[2, q] + t[2, 2] * dw[2, q]
            out[s + q] = (
                c00 * (c11 * c22 - c12 * c21)
                + c01 * (c12 * c20 - c10 * c22)
                + c02 * (c10 * c21 - c11 * c20)
            )
            if squares:
                frobenius[s + q] = (
                    c00 * c00 + c01 * c01 + c02 * c02 + c10 * c10 + c11 * c11
                    + c12 * c12 + c20 * c20 + c21 * c21 + c22 * c22
                )  # fmt: skip
