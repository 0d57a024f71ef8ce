"""Compiled kernels of the local (Blender) lattice bases (:mod:`core.localbasis`).

Per point, each axis's window is evaluated (:func:`_window`: four node indices clamped to
the axis and Blender's four weights, the formula of :func:`core.localbasis.key_weights`,
and with ``deriv`` their derivatives along the axis), then the 4 x 4 x 4 nodes are
visited; the apply and det J sum the tensor product separably (along w, then v, then u),
the transpose skips zero weights (the linear basis has two per axis):

- :func:`local_apply_range`: ``out = p + sum w D`` (D the (l, m, n, 3) displacements);
- :func:`local_transpose_range`: ``acc[node] += w g`` into the caller's accumulator, one per
  range of points (:mod:`core.kernels` adds them in range order);
- :func:`local_determinant_range`: det J of ``x + sum w(x) D``.

Codes: 0 linear, 1 cardinal (tension 0.71), 2 Catmull-Rom (0.5), 3 B-spline, as
:data:`core.localbasis.KINDS`.
"""

from __future__ import annotations

import numpy as np

from .base import INLINE, KERNEL, njit


@njit(**INLINE)
def _window(code, count, u, index, w, dw, deriv):
    """``index[0:4]``, ``w[0:4]`` (and ``dw`` d/du with ``deriv``) of one axis at ``u``."""
    if count == 1:
        for a in range(4):
            index[a] = 0
            w[a] = 0.0
            dw[a] = 0.0
        w[1] = 1.0
        return
    t = u * (count - 1)
    low = np.floor(t)
    f = t - low
    base = int(low) - 1
    top = count - 1
    for a in range(4):
        i = base + a
        index[a] = 0 if i < 0 else (top if i > top else i)
    f2 = f * f
    f3 = f2 * f
    if code == 0:
        w[0] = 0.0
        w[1] = 1.0 - f
        w[2] = f
        w[3] = 0.0
        if deriv:
            dw[0] = 0.0
            dw[1] = -1.0
            dw[2] = 1.0
            dw[3] = 0.0
    elif code == 3:
        w[0] = -f3 / 6.0 + 0.5 * f2 - 0.5 * f + 1.0 / 6.0
        w[1] = 0.5 * f3 - f2 + 2.0 / 3.0
        w[2] = -0.5 * f3 + 0.5 * f2 + 0.5 * f + 1.0 / 6.0
        w[3] = f3 / 6.0
        if deriv:
            dw[0] = -0.5 * f2 + f - 0.5
            dw[1] = 1.5 * f2 - 2.0 * f
            dw[2] = -1.5 * f2 + f + 0.5
            dw[3] = 0.5 * f2
    else:
        fc = 0.71 if code == 1 else 0.5
        w[0] = -fc * f3 + 2.0 * fc * f2 - fc * f
        w[1] = (2.0 - fc) * f3 + (fc - 3.0) * f2 + 1.0
        w[2] = (fc - 2.0) * f3 + (3.0 - 2.0 * fc) * f2 + fc * f
        w[3] = fc * f3 - fc * f2
        if deriv:
            dw[0] = -3.0 * fc * f2 + 4.0 * fc * f - fc
            dw[1] = 3.0 * (2.0 - fc) * f2 + 2.0 * (fc - 3.0) * f
            dw[2] = 3.0 * (fc - 2.0) * f2 + 2.0 * (3.0 - 2.0 * fc) * f + fc
            dw[3] = 3.0 * fc * f2 - 2.0 * fc * f
    if deriv:
        for a in range(4):
            dw[a] *= count - 1


@njit(**KERNEL)
def local_apply_range(uvw, points, codes, d, out, start, stop):
    """``out[:, start:stop]``: the deformed points ``start..stop`` (rows x, y, z), the
    tensor product summed separably (along w, then v, then u: 252 multiply-adds a point
    instead of 320, without a test per weight)."""
    l, m, n = d.shape[0], d.shape[1], d.shape[2]
    iu, iv, iw = np.empty(4, np.int64), np.empty(4, np.int64), np.empty(4, np.int64)
    wu, wv, ww = np.empty(4), np.empty(4), np.empty(4)
    scratch = np.empty(4)
    for q in range(start, stop):
        _window(codes[0], l, uvw[0, q], iu, wu, scratch, False)
        _window(codes[1], m, uvw[1, q], iv, wv, scratch, False)
        _window(codes[2], n, uvw[2, q], iw, ww, scratch, False)
        sx, sy, sz = 0.0, 0.0, 0.0
        for a in range(4):
            rx, ry, rz = 0.0, 0.0, 0.0
            for b in range(4):
                row = d[iu[a], iv[b]]
                px, py, pz = 0.0, 0.0, 0.0
                for c in range(4):
                    dd = row[iw[c]]
                    wc = ww[c]
                    px += wc * dd[0]
                    py += wc * dd[1]
                    pz += wc * dd[2]
                wb = wv[b]
                rx += wb * px
                ry += wb * py
                rz += wb * pz
            wa = wu[a]
            sx += wa * rx
            sy += wa * ry
            sz += wa * rz
        out[0, q] = points[0, q] + sx
        out[1, q] = points[1, q] + sy
        out[2, q] = points[2, q] + sz


@njit(**KERNEL)
def local_transpose_range(uvw, codes, g, l, m, n, start, stop, acc):
    """``acc[((i m + j) n + k) 3 + c] += sum_q w_ijk(q) g[c, q]`` over the points
    ``start..stop``."""
    iu, iv, iw = np.empty(4, np.int64), np.empty(4, np.int64), np.empty(4, np.int64)
    wu, wv, ww = np.empty(4), np.empty(4), np.empty(4)
    scratch = np.empty(4)
    for q in range(start, stop):
        _window(codes[0], l, uvw[0, q], iu, wu, scratch, False)
        _window(codes[1], m, uvw[1, q], iv, wv, scratch, False)
        _window(codes[2], n, uvw[2, q], iw, ww, scratch, False)
        g0, g1, g2 = g[0, q], g[1, q], g[2, q]
        for a in range(4):
            if wu[a] == 0.0:
                continue
            for b in range(4):
                wab = wu[a] * wv[b]
                if wab == 0.0:
                    continue
                at = (iu[a] * m + iv[b]) * n
                for c in range(4):
                    wt = wab * ww[c]
                    if wt == 0.0:
                        continue
                    r = 3 * (at + iw[c])
                    acc[r] += wt * g0
                    acc[r + 1] += wt * g1
                    acc[r + 2] += wt * g2


@njit(**KERNEL)
def local_determinant_range(uvw, codes, d, to_world, out, frobenius, start, stop):
    """``out[start:stop]``: det J at the points ``start..stop``; unless ``frobenius`` is
    empty, ``frobenius[start:stop]`` gets ``|J|_F^2`` too.

    The three derivatives of the tensor product are summed separably, one axis at a time
    (w innermost, then v, then u): the 4 x 4 window's sums along w with the weights and
    their derivatives (2 x 3 numbers per row), those along v (3 x 3 per layer), then along
    u: 564 multiply-adds a point instead of the 960 of the 64 products one by one."""
    squares = len(frobenius) > 0
    l, m, n = d.shape[0], d.shape[1], d.shape[2]
    iu, iv, iw = np.empty(4, np.int64), np.empty(4, np.int64), np.empty(4, np.int64)
    wu, wv, ww = np.empty(4), np.empty(4), np.empty(4)
    du, dv, dw = np.empty(4), np.empty(4), np.empty(4)
    ju = np.empty((3, 3))  # ju[e, a] = d(displacement_a) / du_e
    jac = np.empty((3, 3))
    for q in range(start, stop):
        _window(codes[0], l, uvw[0, q], iu, wu, du, True)
        _window(codes[1], m, uvw[1, q], iv, wv, dv, True)
        _window(codes[2], n, uvw[2, q], iw, ww, dw, True)
        ju[:, :] = 0.0
        for a in range(4):
            # along v of this u layer: r0 = sum wv P, r1 = sum dv P, r2 = sum wv Q
            r00, r01, r02 = 0.0, 0.0, 0.0
            r10, r11, r12 = 0.0, 0.0, 0.0
            r20, r21, r22 = 0.0, 0.0, 0.0
            for b in range(4):
                row = d[iu[a], iv[b]]
                # along w: P = sum ww D, Q = sum dw D
                p0, p1, p2 = 0.0, 0.0, 0.0
                q0, q1, q2 = 0.0, 0.0, 0.0
                for c in range(4):
                    dd = row[iw[c]]
                    x0, x1, x2 = dd[0], dd[1], dd[2]
                    wc, dc = ww[c], dw[c]
                    p0 += wc * x0
                    p1 += wc * x1
                    p2 += wc * x2
                    q0 += dc * x0
                    q1 += dc * x1
                    q2 += dc * x2
                wb, db = wv[b], dv[b]
                r00 += wb * p0
                r01 += wb * p1
                r02 += wb * p2
                r10 += db * p0
                r11 += db * p1
                r12 += db * p2
                r20 += wb * q0
                r21 += wb * q1
                r22 += wb * q2
            wa, da = wu[a], du[a]
            ju[0, 0] += da * r00
            ju[0, 1] += da * r01
            ju[0, 2] += da * r02
            ju[1, 0] += wa * r10
            ju[1, 1] += wa * r11
            ju[1, 2] += wa * r12
            ju[2, 0] += wa * r20
            ju[2, 1] += wa * r21
            ju[2, 2] += wa * r22
        # J[s, t] = delta + sum_e ju[e, s] to_world[e, t]
        for s in range(3):
            for t in range(3):
                jac[s, t] = (1.0 if s == t else 0.0) + (
                    ju[0, s] * to_world[0, t]
                    + ju[1, s] * to_world[1, t]
                    + ju[2, s] * to_world[2, t]
                )
        out[q] = (
            jac[0, 0] * (jac[1, 1] * jac[2, 2] - jac[1, 2] * jac[2, 1])
            - jac[0, 1] * (jac[1, 0] * jac[2, 2] - jac[1, 2] * jac[2, 0])
            + jac[0, 2] * (jac[1, 0] * jac[2, 1] - jac[1, 1] * jac[2, 0])
        )
        if squares:
            total = 0.0
            for s in range(3):
                for t in range(3):
                    total += jac[s, t] * jac[s, t]
            frobenius[q] = total
