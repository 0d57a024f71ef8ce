"""The inner minimisation's preconditioner: the augmented Lagrangian's Hessian, roughly.

``La = E + sigma/2 |c|^2 - lambda . c`` (:mod:`isochor.core.solver`). Its Hessian in the
solver's variables is ``H_E + sigma J^T J + sum_i (sigma c_i - lambda_i) H_ci``. The first
two terms are known cheaply and dominate: the springs' Hessian
(:meth:`isochor.core.springs.SpringNetwork.hessian`, positive semi-definite) and the
Gauss-Newton term of the penalty, from the constraints' gradients ``J`` (one row per
constraint). The constraints' own curvature (the last term) is left to the L-BFGS
correction pairs.

Without it, every L-BFGS run starts from a scaled identity, and a lattice whose springs
are stiff along some directions and the volume stiff along one other needs 50-70 steps to
learn that, even when the start is a small move away from the optimum (each frame of a
live drag). With it, the first step is already close to a Newton step.

The curvature is taken where a level's solve starts and inverted once per penalty factor
(a dense Cholesky: a lattice has at most a few thousand free coordinates), a tiny multiple
of its mean diagonal added so that free rigid motions (zero spring energy) stay
invertible.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg as la

#: added to the diagonal, relative to its mean: keeps rigid motions (zero energy) invertible
RIDGE = 1e-6


class Preconditioner:
    """``v -> M^-1 v`` for ``M = H + sigma J^T J + ridge``, one ``sigma`` at a time.

    The curvature is taken once, where a level's solve starts: the L-BFGS correction pairs
    follow the change along the way, and a new factor is made only when sigma changes.

    Parameters
    ----------
    hessian : (count, count) the energy's Hessian over the variables (the node-coordinate
        Hessian restricted by :meth:`isochor.core.solver.Coordinates.restrict`), in the
        solver's units (energy / size^2 per (coordinate / size)^2)
    jacobian : (m, count) constraint gradients in the variables
    """

    def __init__(self, hessian: np.ndarray, jacobian: np.ndarray) -> None:
        self._h = np.array(hessian, dtype=np.float64)
        jac = np.atleast_2d(np.asarray(jacobian, dtype=np.float64))
        self._jtj = jac.T @ jac if jac.size else np.zeros_like(self._h)
        self._sigma, self._inv = None, None

    def at(self, sigma: float) -> Callable[[np.ndarray], np.ndarray] | None:
        """``v -> M^-1 v`` for this ``sigma``, or None where ``M`` is not positive definite
        (non-finite numbers): the solver then keeps the plain L-BFGS scaling."""
        if sigma != self._sigma:
            m = self._h + sigma * self._jtj
            ridge = RIDGE * max(float(np.trace(m)) / max(len(m), 1), 1e-12)
            m[np.diag_indices_from(m)] += ridge
            try:
                # the explicit inverse: one matrix-vector product a step (a lattice has at
                # most a few thousand free coordinates)
                factor = la.cho_factor(m, lower=True, check_finite=False)
                self._inv = la.cho_solve(factor, np.eye(len(m)), check_finite=False)
            except (la.LinAlgError, ValueError):
                self._inv = None
            if self._inv is not None and not np.all(np.isfinite(self._inv)):
                self._inv = None
            self._sigma = sigma
        inv = self._inv
        return None if inv is None else inv.__matmul__
