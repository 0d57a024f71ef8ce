"""Augmented Lagrangian over the free nodes (paper Eq 15-21, Fig 3).

``La = E + sigma/2 g^2 - lambda g`` where ``g = (V(X) - V_target) / V_ref`` is the volume
deviation made scale-free by one reference volume, and ``E`` is the spring energy of node
positions measured in units of the object size. The optimisation variables are the free
nodes in those units, ``y = (X_free - centre) / size``, so a model in millimetres and the
same model in metres take the same steps with the same sigma.

The inner unconstrained minimisation is limited-memory BFGS (two-loop recursion) with
scipy's strong-Wolfe line search (:func:`scipy.optimize.line_search`) on the analytic
gradient. It is written as a generator rather than a call to ``scipy.optimize.minimize``
because the editor must see every iterate as it comes and must be able to stop the work at
once, which a blocking call cannot offer.

Outer loop (Fig 3): ``lambda <- lambda - sigma g``; sigma doubles whenever ``|g|`` did not
fall to half its previous value (Powell's rule), up to ``sigma_max``.
"""

from __future__ import annotations

import warnings
from collections import deque
from collections.abc import Callable, Generator
from dataclasses import dataclass

import numpy as np
from scipy.optimize import line_search

from .defaults import TOL_NODES, TOL_VOLUME
from .generators import relay


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances and limits; every length is relative to the object size, every volume to
    the reference volume, so the defaults suit any model."""

    tol_volume: float = TOL_VOLUME  #: |dV| / V0 that counts as preserved
    tol_nodes: float = TOL_NODES  #: epsilon: largest node change between levels (Sec 4.3)
    sigma0: float = 10.0  #: first penalty factor
    sigma_max: float = 1e8  #: cap on the penalty factor (paper: "an upper bound for sigma")
    #: inner minimisation stops when max |dLa/dy| is below this (1e-6 cost 7-40% more time
    #: for no gain in the results' accuracy; 1e-4 lets the cow's node change reach 0.1%)
    gtol: float = 1e-5
    max_inner: int = 500  #: inner steps per outer iteration at most
    max_outer: int = 60  #: Lagrange-multiplier updates per level at most
    memory: int = 12  #: L-BFGS correction pairs
    volume_margin: float = 0.5  #: a level is solved at ``volume_margin * tol_volume``
    symmetry_break: float = 1e-4  #: size of the start nudge of free nodes, / object size
    #: A fresh solve starts on the coarsest level with at least this many triangles. Below
    #: a few hundred triangles a step costs as much as on a mid-sized level (fixed call
    #: overhead) and the level's optimum is far from the real one (a 16-triangle torus has
    #: 14% of the torus's volume), so those levels cost time without earning it: measured
    #: on the paper's examples, starting at 16 or 20 triangles was up to 2x slower than
    #: starting near 1000 (docs/BENCHMARKS.md, start-level sweep). 0 gives the paper's
    #: schedule.
    start_triangles: int = 1000


@dataclass(frozen=True)
class Iterate:
    """One accepted inner step."""

    y: np.ndarray
    energy: float
    deviation: float  #: g = (V - V_target) / V_ref
    step: int  #: inner steps so far at this level
    outer: int
    sigma: float
    lam: float


Objective = Callable[[np.ndarray], tuple[float, np.ndarray, tuple[float, float]]]


def lbfgs(
    fun: Objective, x0: np.ndarray, *, gtol: float, max_iter: int, memory: int = 12
) -> Generator[tuple[np.ndarray, tuple[float, float]], None, tuple[np.ndarray, int, bool]]:
    """Minimise ``fun`` from ``x0``; yields ``(x, aux)`` after every accepted step.

    ``fun(x)`` returns ``(f, grad, aux)``. Returns ``(x, steps, converged)``.
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
    f, g, _ = evaluate(x)
    s_hist: deque[np.ndarray] = deque(maxlen=memory)
    y_hist: deque[np.ndarray] = deque(maxlen=memory)
    f_old = None
    for it in range(max_iter):
        if not np.all(np.isfinite(g)):
            raise FloatingPointError("the objective gradient is not finite")
        if np.max(np.abs(g)) <= gtol:
            return x, it, True
        d = _two_loop(g, s_hist, y_hist)
        if g @ d >= 0:  # not a descent direction: restart from steepest descent
            s_hist.clear()
            y_hist.clear()
            d = -g
        if not s_hist:  # first step: a move of at most 1% of the object size
            d = d * min(1.0, 0.01 / max(np.max(np.abs(d)), 1e-300))
        slope = g @ d
        alpha = None
        if s_hist:  # the quasi-Newton step usually fits: take it when it decreases enough
            f_try, g_try, _ = evaluate(x + d)
            if f_try <= f + 1e-4 * slope and abs(g_try @ d) <= 0.9 * abs(slope):
                alpha = 1.0
        if alpha is None:
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", "The line search algorithm")
                alpha, *_ = line_search(
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
        x_new = x + alpha * d
        f_new, g_new, aux = evaluate(x_new)
        s, yv = x_new - x, g_new - g
        if s @ yv > 1e-12 * np.sqrt((s @ s) * (yv @ yv)):
            s_hist.append(s)
            y_hist.append(yv)
        f_old, x, f, g = f, x_new, f_new, g_new
        yield x, aux
        if f_old - f <= 1e-15 * max(1.0, abs(f)):  # no measurable progress left
            return x, it + 1, np.max(np.abs(g)) <= 10 * gtol
    return x, max_iter, False


def _two_loop(g: np.ndarray, s_hist: deque, y_hist: deque) -> np.ndarray:
    """L-BFGS search direction -H g from the stored correction pairs."""
    q = g.copy()
    rhos = [1.0 / (y @ s) for s, y in zip(s_hist, y_hist)]
    alphas = []
    for s, y, rho in zip(reversed(s_hist), reversed(y_hist), reversed(rhos)):
        a = rho * (s @ q)
        q -= a * y
        alphas.append(a)
    if s_hist:
        s, y = s_hist[-1], y_hist[-1]
        q *= (s @ y) / (y @ y)
    for s, y, rho, a in zip(s_hist, y_hist, rhos, reversed(alphas)):
        b = rho * (y @ q)
        q += (a - b) * s
    return -q


class LevelProblem:
    """Energy and volume deviation of one level as functions of the free nodes ``y``.

    Parameters
    ----------
    nodes : (n, 3) current node positions; the fixed ones stay as given
    free : (n,) bool, the nodes the solver may move
    energy_grad : ``X -> (E, dE/dX)`` in world units
    volume_grad : ``X -> (V, dV/dX)`` in world units
    center, size : the normalisation of lengths
    v_target, v_ref : target volume and the reference volume that scales the deviation
    """

    def __init__(self, nodes, free, energy_grad, volume_grad, center, size, v_target, v_ref):
        self.template = np.array(nodes, dtype=np.float64)
        self.free = np.asarray(free, dtype=bool)
        self.energy_grad, self.volume_grad = energy_grad, volume_grad
        self.center, self.size = np.asarray(center, dtype=np.float64), float(size)
        self.v_target, self.v_ref = float(v_target), float(v_ref)

    def to_y(self, nodes: np.ndarray) -> np.ndarray:
        return ((nodes[self.free] - self.center) / self.size).ravel()

    def to_nodes(self, y: np.ndarray) -> np.ndarray:
        out = self.template.copy()
        out[self.free] = self.center + self.size * y.reshape(-1, 3)
        return out

    def terms(self, y: np.ndarray) -> tuple[float, np.ndarray, float, np.ndarray]:
        """Normalised energy, its gradient, deviation g and its gradient, all in ``y``."""
        x = self.to_nodes(y)
        e, de = self.energy_grad(x)
        v, dv = self.volume_grad(x)
        s = self.size
        g = (v - self.v_target) / self.v_ref
        return (
            e / s**2,
            (de[self.free] / s).ravel(),
            g,
            (dv[self.free] * (s / self.v_ref)).ravel(),
        )

    def deviation(self, y: np.ndarray) -> float:
        v, _ = self.volume_grad(self.to_nodes(y))
        return (v - self.v_target) / self.v_ref

    def lagrangian(self, lam: float, sigma: float) -> Objective:
        """``y -> (La, dLa/dy, (E, g))`` for fixed multiplier and penalty (Eq 19)."""

        def fun(y: np.ndarray):
            e, de, g, dg = self.terms(y)
            la = e + 0.5 * sigma * g * g - lam * g
            return la, de + (sigma * g - lam) * dg, (e, g)

        return fun


@dataclass(frozen=True)
class ALResult:
    y: np.ndarray
    lam: float
    sigma: float
    deviation: float
    energy: float
    steps: int
    outer: int
    converged: bool


def augmented_lagrangian(
    problem: LevelProblem, y0: np.ndarray, lam: float, sigma: float, options: SolverOptions
) -> Generator[Iterate, None, ALResult]:
    """Fig 3: minimise La, update lambda, raise sigma when |g| does not halve; repeat."""
    tol = options.volume_margin * options.tol_volume
    y = np.array(y0, dtype=np.float64)
    g_prev = abs(problem.deviation(y))
    steps = 0
    energy = g = float("nan")
    for outer in range(options.max_outer):
        inner = lbfgs(
            problem.lagrangian(lam, sigma),
            y,
            gtol=options.gtol,
            max_iter=options.max_inner,
            memory=options.memory,
        )

        def iterate(record, outer=outer, sigma=sigma, lam=lam):
            nonlocal steps
            steps += 1
            y_k, (energy_k, g_k) = record
            return Iterate(y_k, energy_k, g_k, steps, outer, sigma, lam)

        y, _, _ = yield from relay(inner, iterate)
        energy, _, g, _ = problem.terms(y)
        if abs(g) <= tol:
            return ALResult(y, lam, sigma, g, energy, steps, outer + 1, True)
        lam -= sigma * g
        if abs(g) > 0.5 * g_prev:
            sigma = min(2.0 * sigma, options.sigma_max)
        g_prev = abs(g)
    return ALResult(y, lam, sigma, g, energy, steps, options.max_outer, False)
