"""Limited-memory BFGS as a generator: the inner minimisation of the augmented Lagrangian
(:mod:`isochor.core.solve.solver`).

Two-loop recursion with scipy's strong-Wolfe line search (:mod:`.linesearch`, SciPy's
``scipy.optimize.line_search`` step for step) on the analytic gradient. It is written as a
generator rather than a call to ``scipy.optimize.minimize`` because the editor must see every
iterate as it comes and must be able to stop the work at once, which a blocking call cannot
offer. An approximate inverse
Hessian (:mod:`isochor.core.solve.precondition`) can replace the scaled identity the recursion
starts from.
"""

from __future__ import annotations

from collections.abc import Callable, Generator

import numpy as np

from ..kernels import step as stepkernels
from ..kernels.pairs import Pairs
from .linesearch import line_search

#: a preconditioned L-BFGS run that has not converged after this many steps goes on with
#: the plain scaled identity (keeping its correction pairs): the preconditioner is the
#: curvature where the run started, and where the fold guard takes hold the curvature
#: changes so much that the fixed one slows the run down (the kitten bend: 251 steps
#: instead of 82; the cow shrunk to 0.2: 500 without converging instead of 407). A run
#: that can renew its preconditioner (a dense local lattice's sparse one) takes it again
#: at its current point instead: plain L-BFGS on 10k variables crawls (the whole top layer
#: of a 16^3 lattice pushed down: runs of 500 steps without converging)
PRECONDITIONED_STEPS = 40


Objective = Callable[[np.ndarray], tuple[float, np.ndarray, tuple[float, float]]]


def lbfgs(
    fun: Objective,
    x0: np.ndarray,
    *,
    gtol: float,
    max_iter: int,
    memory: int = 12,
    h0: Callable[[np.ndarray], np.ndarray] | None = None,
    loose: Callable[[tuple[float, float]], float] | None = None,
    renew: Callable[[np.ndarray], Callable[[np.ndarray], np.ndarray] | None] | None = None,
) -> Generator[tuple[np.ndarray, tuple[float, float]], None, tuple[np.ndarray, int, bool]]:
    """Minimise ``fun`` from ``x0``; yields ``(x, aux)`` after every accepted step.

    ``fun(x)`` returns ``(f, grad, aux)``. Returns ``(x, steps, converged)``. ``h0``, when
    given, applies an approximate inverse Hessian (the preconditioner): it replaces the
    scaled identity of the two-loop recursion, and the first step is ``-h0(g)`` tried
    whole, like every quasi-Newton step. ``loose``, when given, is a second stopping
    tolerance on ``max |grad|`` taken from the iterate's ``aux`` (the inexact inner runs of
    :func:`isochor.core.solve.solver.augmented_lagrangian`). ``renew``, when given, makes
    the preconditioner again at the current ``x`` every :data:`PRECONDITIONED_STEPS` steps
    of a run that has not converged (None from it: the scaled identity from then on),
    instead of going on with the scaled identity.
    """
    cache: dict[bytes, tuple[float, np.ndarray, tuple[float, float]]] = {}

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray, tuple[float, float]]:
        key = x.tobytes()
        if key not in cache:
            if len(cache) > 8:
                cache.clear()
            cache[key] = fun(x)
        return cache[key]

    x = np.array(x0, dtype=np.float64)
    f, g, aux = evaluate(x)
    pairs = Pairs(memory, len(x))
    f_old = None
    for it in range(max_iter):
        if it and it % PRECONDITIONED_STEPS == 0 and h0 is not None:
            h0 = None if renew is None else renew(x)  # see PRECONDITIONED_STEPS
        d, g_max, slope = _direction(pairs, g, h0)
        if not np.isfinite(g_max):
            raise FloatingPointError("the objective gradient is not finite")
        if g_max <= gtol or (loose is not None and g_max <= loose(aux)):
            return x, it, True
        if slope >= 0:  # not a descent direction: restart from steepest descent
            pairs.forget()
            d, h0 = -g, None
        if not pairs.count:  # first step: a move of at most 1% (10% preconditioned) of the size
            d = d * min(1.0, (0.01 if h0 is None else 0.1) / max(float(np.abs(d).max()), 1e-300))
            slope = float(g @ d)
        step = None  # (x_new, f_new, g_new, aux) of the accepted step
        if pairs.count or h0 is not None:  # the quasi-Newton step usually fits: take it if it can
            x_try = x + d
            f_try, g_try, aux_try = evaluate(x_try)
            if f_try <= f + 1e-4 * slope and abs(g_try @ d) <= 0.9 * abs(slope):
                step = x_try, f_try, g_try, aux_try
        if step is None:
            alpha = line_search(
                lambda z: evaluate(z)[0],
                lambda z: evaluate(z)[1],
                x,
                d,
                g,
                f,
                f_old,
                maxiter=30,
            )
            if alpha is None:  # Wolfe search failed: backtrack on sufficient decrease only
                alpha = 1.0
                while alpha > 1e-12 and evaluate(x + alpha * d)[0] > f + 1e-4 * alpha * slope:
                    alpha *= 0.25
                if alpha <= 1e-12:
                    return x, it, False
            x_try = x + alpha * d
            step = (x_try, *evaluate(x_try))
        x_new, f_new, g_new, aux = step
        _push(pairs, x_new, x, g_new, g)
        f_old, x, f, g = f, x_new, f_new, g_new
        yield x, aux
        if f_old - f <= 1e-15 * max(1.0, abs(f)):  # no measurable progress left
            return x, it + 1, np.max(np.abs(g)) <= 10 * gtol
    return x, max_iter, False


def _direction(pairs: Pairs, g: np.ndarray, h0) -> tuple[np.ndarray, float, float]:
    """The search direction ``d = -H g``, ``max |g|`` and the slope ``g . d`` (one compiled
    call where the kernels are ready)."""
    g = np.asarray(g, dtype=np.float64)
    out = stepkernels.two_loop(pairs, g, h0)
    if out is not None:
        return out
    d = pairs.direction(g.copy(), h0)
    return d, float(np.abs(g).max()) if len(g) else 0.0, float(g @ d)


def _push(pairs: Pairs, x_new, x, g_new, g) -> None:
    """Keep the correction pair of a step: compiled where the kernels are ready."""
    kept = stepkernels.push_pair(pairs, x_new, x, g_new, g)
    if kept is None:
        pairs.push(x_new, x, g_new, g)
    else:
        pairs.stored(kept)
