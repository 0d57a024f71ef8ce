"""The strong-Wolfe line search of the L-BFGS solver (:mod:`.lbfgs`).

SciPy's ``scipy.optimize.line_search`` (``line_search_wolfe2``: Nocedal and Wright,
Algorithms 3.5 and 3.6, with cubic and quadratic interpolation in the zoom), the same
arithmetic step for step, so that a solve takes the same steps as with SciPy's. It lives
here because importing ``scipy.optimize`` costs a cold command about 0.25-0.4 s of CPU
(it imports most of SciPy), more than a whole first solve of an example. Without its
warnings: a failed search returns ``None`` and the caller backtracks.

Adapted from SciPy (``scipy/optimize/_linesearch.py``), Copyright (c) 2001-2002
Enthought, Inc. and 2003-2024 SciPy Developers, BSD 3-Clause licence.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def line_search(
    f: Callable[[np.ndarray], float],
    fprime: Callable[[np.ndarray], np.ndarray],
    xk: np.ndarray,
    pk: np.ndarray,
    gfk: np.ndarray,
    old_fval: float,
    old_old_fval: float | None,
    c1: float = 1e-4,
    c2: float = 0.9,
    maxiter: int = 10,
) -> float | None:
    """A step ``alpha`` along ``pk`` from ``xk`` that meets the strong Wolfe conditions,
    or None. ``gfk``, ``old_fval``: the gradient and value at ``xk``; ``old_old_fval``:
    the value before (for the first trial step), or None."""
    if not 0 < c1 < c2 < 1:
        raise ValueError("'c1' and 'c2' do not satisfy '0 < c1 < c2 < 1'.")

    def phi(alpha):
        return f(xk + alpha * pk)

    def derphi(alpha):
        return np.dot(fprime(xk + alpha * pk), pk)

    return _scalar_search(phi, derphi, old_fval, old_old_fval, np.dot(gfk, pk), c1, c2, maxiter)


def _scalar_search(phi, derphi, phi0, old_phi0, derphi0, c1, c2, maxiter):
    alpha0 = 0
    if old_phi0 is not None and derphi0 != 0:
        alpha1 = min(1.0, 1.01 * 2 * (phi0 - old_phi0) / derphi0)
    else:
        alpha1 = 1.0
    if alpha1 < 0:
        alpha1 = 1.0
    phi_a1 = phi(alpha1)
    phi_a0 = phi0
    derphi_a0 = derphi0
    for i in range(maxiter):
        if alpha1 == 0:  # the increment slipped below machine precision
            return None
        if (phi_a1 > phi0 + c1 * alpha1 * derphi0) or ((phi_a1 >= phi_a0) and i > 0):
            return _zoom(
                alpha0, alpha1, phi_a0, phi_a1, derphi_a0, phi, derphi, phi0, derphi0, c1, c2
            )
        derphi_a1 = derphi(alpha1)
        if abs(derphi_a1) <= -c2 * derphi0:
            return alpha1
        if derphi_a1 >= 0:
            return _zoom(
                alpha1, alpha0, phi_a1, phi_a0, derphi_a1, phi, derphi, phi0, derphi0, c1, c2
            )
        alpha2 = 2 * alpha1  # increase by factor of two on each iteration
        alpha0 = alpha1
        alpha1 = alpha2
        phi_a0 = phi_a1
        phi_a1 = phi(alpha1)
        derphi_a0 = derphi_a1
    return alpha1  # SciPy returns the last step, warning that it did not converge


def _cubicmin(a, fa, fpa, b, fb, c, fc):
    """The minimiser of the cubic through (a, fa) with slope fpa, (b, fb) and (c, fc)."""
    with np.errstate(divide="raise", over="raise", invalid="raise"):
        try:
            cc = fpa
            db = b - a
            dc = c - a
            denom = (db * dc) ** 2 * (db - dc)
            d1 = np.empty((2, 2))
            d1[0, 0] = dc**2
            d1[0, 1] = -(db**2)
            d1[1, 0] = -(dc**3)
            d1[1, 1] = db**3
            [ca, cb] = np.dot(d1, np.asarray([fb - fa - cc * db, fc - fa - cc * dc]).flatten())
            ca /= denom
            cb /= denom
            radical = cb * cb - 3 * ca * cc
            xmin = a + (-cb + np.sqrt(radical)) / (3 * ca)
        except ArithmeticError:
            return None
    if not np.isfinite(xmin):
        return None
    return xmin


def _quadmin(a, fa, fpa, b, fb):
    """The minimiser of the parabola through (a, fa) with slope fpa and (b, fb)."""
    with np.errstate(divide="raise", over="raise", invalid="raise"):
        try:
            cd = fa
            cc = fpa
            db = b - a * 1.0
            cb = (fb - cd - cc * db) / (db * db)
            xmin = a - cc / (2.0 * cb)
        except ArithmeticError:
            return None
    if not np.isfinite(xmin):
        return None
    return xmin


def _zoom(a_lo, a_hi, phi_lo, phi_hi, derphi_lo, phi, derphi, phi0, derphi0, c1, c2):
    """Nocedal and Wright's zoom: a step between ``a_lo`` and ``a_hi``, or None."""
    maxiter = 10
    i = 0
    delta1 = 0.2  # cubic interpolant check
    delta2 = 0.1  # quadratic interpolant check
    phi_rec = phi0
    a_rec = 0
    while True:
        dalpha = a_hi - a_lo
        a, b = (a_hi, a_lo) if dalpha < 0 else (a_lo, a_hi)
        if i > 0:
            cchk = delta1 * dalpha
            a_j = _cubicmin(a_lo, phi_lo, derphi_lo, a_hi, phi_hi, a_rec, phi_rec)
        if (i == 0) or (a_j is None) or (a_j > b - cchk) or (a_j < a + cchk):
            qchk = delta2 * dalpha
            a_j = _quadmin(a_lo, phi_lo, derphi_lo, a_hi, phi_hi)
            if (a_j is None) or (a_j > b - qchk) or (a_j < a + qchk):
                a_j = a_lo + 0.5 * dalpha
        phi_aj = phi(a_j)
        if (phi_aj > phi0 + c1 * a_j * derphi0) or (phi_aj >= phi_lo):
            phi_rec = phi_hi
            a_rec = a_hi
            a_hi = a_j
            phi_hi = phi_aj
        else:
            derphi_aj = derphi(a_j)
            if abs(derphi_aj) <= -c2 * derphi0:
                return a_j
            if derphi_aj * (a_hi - a_lo) >= 0:
                phi_rec = phi_hi
                a_rec = a_hi
                a_hi = a_lo
                phi_hi = phi_lo
            else:
                phi_rec = phi_lo
                a_rec = a_lo
            a_lo = a_j
            phi_lo = phi_aj
            derphi_lo = derphi_aj
        i += 1
        if i > maxiter:  # no conforming step size
            return None
