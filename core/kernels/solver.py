"""Compiled pieces of the solver's own step (:mod:`core.kernels`): the spring energy, its
gradient and Hessian (:class:`core.springs.SpringNetwork`), and the L-BFGS two-loop
recursion (:mod:`core.solve.lbfgs`). On a lattice they are loops over a few hundred springs or a
dozen correction pairs, where NumPy's per-call overhead (tens of calls, about a
microsecond each) is most of the time; compiled, each is one call.

The formulas are the NumPy path's, term by term, so the results agree to rounding
(``tests/test_kernels``).
"""

from __future__ import annotations

import math

import numpy as np

from .base import INLINE, KERNEL, njit


@njit(**KERNEL)
def spring_energy_gradient(x, starts, ends, rest, stiffness, grad):
    """``sum k/2 (|x_e - x_s| - L)^2`` over the springs; its gradient is written to the
    (n, 3) ``grad`` (overwritten). A zero-length spring adds no force."""
    grad[:, :] = 0.0
    energy = 0.0
    for j in range(len(starts)):
        a, b = starts[j], ends[j]
        d0 = x[b, 0] - x[a, 0]
        d1 = x[b, 1] - x[a, 1]
        d2 = x[b, 2] - x[a, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        stretch = length - rest[j]
        energy += stretch * stretch
        if length > 0.0:
            f = stiffness * stretch / length
            grad[b, 0] += f * d0
            grad[b, 1] += f * d1
            grad[b, 2] += f * d2
            grad[a, 0] -= f * d0
            grad[a, 1] -= f * d1
            grad[a, 2] -= f * d2
    return 0.5 * stiffness * energy


@njit(**KERNEL)
def spring_hessian(x, starts, ends, rest, stiffness, out):
    """The (3n, 3n) ``out`` (overwritten): per spring ``k (u u^T + max(0, 1 - L/l)
    (I - u u^T))`` on the difference of its ends (see ``SpringNetwork.hessian``)."""
    out[:, :] = 0.0
    u = np.empty(3)
    for j in range(len(starts)):
        a, b = 3 * starts[j], 3 * ends[j]
        length = 0.0
        for r in range(3):
            u[r] = x[ends[j], r] - x[starts[j], r]
            length += u[r] * u[r]
        length = math.sqrt(length)
        safe = length if length > 0.0 else 1.0
        bend = max(1.0 - rest[j] / safe, 0.0)
        for r in range(3):
            u[r] /= safe
        for r in range(3):
            for c in range(3):
                uu = u[r] * u[c]
                v = stiffness * (uu + bend * ((1.0 if r == c else 0.0) - uu))
                out[a + r, a + c] += v
                out[b + r, b + c] += v
                out[a + r, b + c] -= v
                out[b + r, a + c] -= v


@njit(**KERNEL)
def push_pair(x_new, x, g_new, g, s, y, rho, head):
    """Store ``s = x_new - x``, ``y = g_new - g`` at row ``head`` of the ring when their
    curvature ``s.y`` is positive beyond rounding; whether it was stored."""
    sy = ss = yy = 0.0
    for k in range(len(x)):
        a = x_new[k] - x[k]
        b = g_new[k] - g[k]
        sy += a * b
        ss += a * a
        yy += b * b
    if not sy > 1e-12 * math.sqrt(ss * yy):
        return False  # (the row at head may be the oldest pair kept: left as it is)
    for k in range(len(x)):
        s[head, k] = x_new[k] - x[k]
        y[head, k] = g_new[k] - g[k]
    rho[head] = 1.0 / sy
    return True


@njit(**KERNEL)
def two_loop(g, s, y, rho, head, count, alphas, h, q, out):
    """``out = -H g``: both loops around the start matrix ``h`` (n, n), or, when ``h`` is
    empty, the newest pair's scaled identity; ``q`` (n,) is work space. Returns ``max |g|``
    (NaN where ``g`` has one) and the slope ``g . out``: the step's convergence test and
    line-search slope, in the same call."""
    n = len(g)
    g_max = 0.0
    for k in range(n):
        q[k] = g[k]
        a = abs(g[k])
        if a > g_max or a != a:  # a NaN stays: nothing is greater than it
            g_max = a
    _first(q, s, y, rho, head, count, alphas)
    if h.shape[0]:
        for r in range(n):
            v = 0.0
            for c in range(n):
                v += h[r, c] * q[c]
            out[r] = v
    else:
        scale = 1.0
        if count:
            r = (head - 1) % s.shape[0]
            sy = yy = 0.0
            for k in range(n):
                sy += s[r, k] * y[r, k]
                yy += y[r, k] * y[r, k]
            scale = sy / yy
        for k in range(n):
            out[k] = scale * q[k]
    _second(out, s, y, rho, head, count, alphas)
    slope = 0.0
    for k in range(n):
        out[k] = -out[k]
        slope += g[k] * out[k]
    return g_max, slope


@njit(**KERNEL)
def two_loop_first(q, s, y, rho, head, count, alphas):
    """The recursion's first loop, where the start matrix is applied outside (``alphas``
    carries over to :func:`two_loop_second`)."""
    _first(q, s, y, rho, head, count, alphas)


@njit(**KERNEL)
def two_loop_second(q, s, y, rho, head, count, alphas):
    """The recursion's second loop (see :func:`two_loop_first`)."""
    _second(q, s, y, rho, head, count, alphas)


@njit(**INLINE)
def _first(q, s, y, rho, head, count, alphas):
    """The recursion's first loop, newest pair first, on ``q`` (changed in place); the
    pairs are rows of ``s``, ``y`` in a ring, the newest at ``head - 1``."""
    memory = s.shape[0]
    for i in range(count):
        r = (head - 1 - i) % memory
        a = 0.0
        for k in range(q.shape[0]):
            a += s[r, k] * q[k]
        a *= rho[r]
        alphas[i] = a
        for k in range(q.shape[0]):
            q[k] -= a * y[r, k]


@njit(**INLINE)
def _second(q, s, y, rho, head, count, alphas):
    """The second loop, oldest pair first, on ``q`` (changed in place)."""
    memory = s.shape[0]
    for i in range(count - 1, -1, -1):
        r = (head - 1 - i) % memory
        b = 0.0
        for k in range(q.shape[0]):
            b += y[r, k] * q[k]
        b = alphas[i] - rho[r] * b
        for k in range(q.shape[0]):
            q[k] += b * s[r, k]


@njit(**KERNEL)
def spd_inverse(a, ridge, out):
    """``out = (A + ridge I)^-1`` for a symmetric ``A`` (n, n; its lower triangle is read),
    by the Cholesky factor ``L`` and ``W = L^-1``: ``out = W^T W``. False (``out``
    undefined) where ``A + ridge I`` is not positive definite or has a number that is not
    finite (it reaches a pivot through the factor)."""
    n = a.shape[0]
    low = np.zeros((n, n))
    for j in range(n):
        d = a[j, j] + ridge
        for k in range(j):
            d -= low[j, k] * low[j, k]
        if not (d > 0.0 and d < math.inf):
            return False
        pivot = math.sqrt(d)
        low[j, j] = pivot
        for i in range(j + 1, n):
            v = a[i, j]
            for k in range(j):
                v -= low[i, k] * low[j, k]
            low[i, j] = v / pivot
    w = np.zeros((n, n))
    for j in range(n):
        w[j, j] = 1.0 / low[j, j]
        for i in range(j + 1, n):
            v = 0.0
            for k in range(j, i):
                v += low[i, k] * w[k, j]
            w[i, j] = -v / low[i, i]
    out[:, :] = 0.0
    for k in range(n):
        for i in range(k + 1):
            wi = w[k, i]
            for j in range(i, k + 1):
                out[i, j] += wi * w[k, j]
    for i in range(n):
        for j in range(i):
            out[i, j] = out[j, i]
    return True
