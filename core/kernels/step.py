"""The compiled pieces of the solver's own step (:mod:`core.kernels.solver`), with the NumPy
path as the fallback: the entry points :mod:`core.springs`, :mod:`core.solve.lbfgs` and
:mod:`core.solve.precondition` call.

On a lattice every piece of a step is a loop over a few hundred springs, a dozen correction
pairs or a matrix of a few dozen rows, where NumPy's per-call overhead (about a
microsecond a call, tens of calls) is most of the time; compiled, each is one call.

- :func:`springs`, :func:`spring_hessian`: the spring energy, gradient and Hessian of
  :class:`core.springs.SpringNetwork`;
- :func:`two_loop`, :func:`push_pair`: the L-BFGS recursion and its memory
  (:class:`core.kernels.pairs.Pairs`);
- :func:`spd_inverse`: the preconditioner's explicit inverse of a small curvature matrix
  (:class:`core.solve.precondition.Curvature`), one call instead of a factorisation and a solve
  through SciPy's wrappers.

Like every entry point of :mod:`core.kernels`, each returns None when the kernels are not
in use (the caller then runs its NumPy code) and switches them off on any error.
"""

from __future__ import annotations

import numpy as np

from . import _guard, _kernels

#: up to this many variables :func:`spd_inverse` (plain loops, 2 n^3 / 3 multiply-adds)
#: is faster than LAPACK behind SciPy's wrappers; measured: 7.6 against 26.7 us at 27
#: variables, 34 against 43 us at 48, 79 against 61 us at 64
SMALL_INVERSE = 48
_NO_MATRIX = np.zeros((0, 0))


@_guard
def springs(x: np.ndarray, starts, ends, rest, stiffness: float, k=None):
    """(energy, (n, 3) gradient) of the springs ``starts -> ends`` (int64) with rest lengths
    ``rest`` at the (n, 3) C-ordered float64 nodes ``x``; None: no kernels."""
    k = k or _kernels()
    if k is None:
        return None
    grad = np.empty(x.shape)
    return k.spring_energy_gradient(x, starts, ends, rest, stiffness, grad), grad


@_guard
def spring_hessian(x: np.ndarray, starts, ends, rest, stiffness: float, k=None):
    """(3n, 3n) the springs' Hessian (see :func:`springs`); None: no kernels."""
    k = k or _kernels()
    if k is None:
        return None
    out = np.empty((3 * len(x), 3 * len(x)))
    k.spring_hessian(x, starts, ends, rest, stiffness, out)
    return out


@_guard
def two_loop(pairs, g: np.ndarray, h0, k=None) -> tuple[np.ndarray, float, float] | None:
    """``(d, max |g|, g . d)`` with ``d = -H g`` by the two-loop recursion over ``pairs``
    (:class:`core.kernels.pairs.Pairs`): ``h0`` the start matrix's product (one call when it keeps
    its matrix as ``h0.matrix``), or None for the scaled identity; None: no kernels."""
    k = k or _kernels()
    if k is None:
        return None
    p = pairs
    matrix = _NO_MATRIX if h0 is None else getattr(h0, "matrix", None)
    if matrix is not None:
        out = np.empty(g.shape)
        g_max, slope = k.two_loop(
            g, p.s, p.y, p.rho, p.head, p.count, p.alphas, matrix, np.empty(g.shape), out
        )
        return out, g_max, slope
    q = np.array(g, dtype=np.float64)
    k.two_loop_first(q, p.s, p.y, p.rho, p.head, p.count, p.alphas)
    q = p.start(q, h0)
    k.two_loop_second(q, p.s, p.y, p.rho, p.head, p.count, p.alphas)
    d = np.negative(q, out=q)
    return d, float(np.abs(g).max()) if len(g) else 0.0, float(g @ d)


@_guard
def push_pair(pairs, x_new, x, g_new, g, k=None) -> bool | None:
    """Store ``(x_new - x, g_new - g)`` in ``pairs`` (:class:`core.kernels.pairs.Pairs`) at its
    head when its curvature is positive beyond rounding; whether it was stored (for
    ``pairs.stored``); None: no kernels."""
    k = k or _kernels()
    if k is None:
        return None
    return k.push_pair(x_new, x, g_new, g, pairs.s, pairs.y, pairs.rho, pairs.head)


@_guard
def spd_inverse(a: np.ndarray, ridge: float, k=None) -> np.ndarray | bool | None:
    """``(A + ridge I)^-1`` for a symmetric (n, n) ``A`` of at most :data:`SMALL_INVERSE`
    rows; False where that is not positive definite (or not finite); None: no kernels, or
    ``A`` too large (LAPACK is faster there)."""
    if len(a) > SMALL_INVERSE:
        return None
    k = k or _kernels()
    if k is None:
        return None
    out = np.empty(a.shape)
    return out if k.spd_inverse(np.ascontiguousarray(a, dtype=np.float64), ridge, out) else False
