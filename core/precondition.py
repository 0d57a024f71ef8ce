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

The matrix is factored once per inner run (a dense Cholesky: a lattice has at most a few
thousand free coordinates), a tiny multiple of its mean diagonal added so that free
rigid motions (zero spring energy) stay invertible.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

#: added to the diagonal, relative to its mean: keeps rigid motions (zero energy) invertible
RIDGE = 1e-6


class Preconditioner:
    """``v -> M^-1 v`` for ``M = P H P^T + sigma J^T J + ridge``.

    Parameters
    ----------
    hessian : (3n, 3n) sparse, the energy's Hessian over all node coordinates, in the
        solver's units (energy / size^2 per (coordinate / size)^2)
    reduce : (count, 3n) sparse, the variables' share of each node coordinate
        (:attr:`isochor.core.solver.Coordinates.matrix`)
    jacobian : (m, count) constraint gradients in the variables
    sigma : the penalty factor
    """

    def __init__(self, hessian, reduce, jacobian: np.ndarray, sigma: float) -> None:
        h = reduce @ hessian @ reduce.T
        m = h.toarray() if sp.issparse(h) else np.array(h)
        jac = np.atleast_2d(np.asarray(jacobian, dtype=np.float64))
        if jac.size:
            m += sigma * (jac.T @ jac)
        ridge = RIDGE * max(float(np.trace(m)) / max(len(m), 1), 1e-12)
        m[np.diag_indices_from(m)] += ridge
        self._factor = la.cho_factor(m, lower=True, check_finite=False)

    def __call__(self, v: np.ndarray) -> np.ndarray:
        return la.cho_solve(self._factor, v, check_finite=False)


def preconditioner(hessian, reduce, jacobian, sigma) -> Preconditioner | None:
    """A :class:`Preconditioner`, or None where the matrix is not positive definite
    (non-finite numbers): the solver then falls back to the plain L-BFGS scaling."""
    try:
        return Preconditioner(hessian, reduce, jacobian, sigma)
    except (la.LinAlgError, ValueError):
        return None
