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


@njit(**KERNEL)
def determinant_range(uvw, x, to_world, out, frobenius, start, stop):
    """``out[start:stop]``: det J at the points ``start..stop`` of the (3, p) lattice
    coordinates ``uvw``, for the (l, m, n, 3) nodes ``x``; ``to_world`` (3, 3) is
    ``inv(axes).T``. Unless ``frobenius`` is empty, ``frobenius[start:stop]`` gets
    ``|J|_F^2`` there too (the fold guard's bound)."""
    squares = len(frobenius) > 0
    l, m, n = x.shape[0], x.shape[1], x.shape[2]
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
        for i in range(l):
            zv[:, :w] = 0.0
            zdv[:, :w] = 0.0
            zdw[:, :w] = 0.0
            for j in range(m):
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
