"""The inner minimisation's preconditioner: the augmented Lagrangian's Hessian, roughly.

``La = E + sigma/2 |c|^2 - lambda . c`` (:mod:`isochor.core.solve.solver`). Its Hessian in the
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

The curvature ``A = H_E + ridge`` is taken where a solve starts (its levels share it: the
springs and the fold guard are the same on every level) and factored once (a dense
Cholesky: a lattice has at most a few thousand free coordinates), a tiny multiple of its
mean diagonal added so that free rigid motions (zero spring energy) stay invertible. Each
level adds its own ``sigma J^T J`` by the Woodbury identity, so a new penalty factor costs
an ``m x m`` solve instead of a new factorisation:

    M^-1 = A^-1 - U (I / sigma + J U)^-1 U^T,   U = A^-1 J^T.

Up to :data:`EXPLICIT` variables ``M^-1`` is kept as a matrix (one product a step); above
it, ``A^-1`` is applied by two triangular solves a step and never formed: the inverse of
2700 variables (a 10x10x10 lattice) costs 0.8 s, the solves 3 ms a step. A dense lattice
of a local basis (thousands of nodes) hands over sparse matrices
(:data:`core.springs.SPARSE_VARIABLES`): ``A`` is then factored by SciPy's sparse LU
(SuperLU in single precision, no pivoting on the symmetric positive definite matrix,
in the nested-dissection order of the lattice's grid, :func:`dissection`), each step two
sparse triangular solves; above :data:`NODE_FACTOR` variables on the nodes alone (each
3x3 block by a third of its trace: three times fewer unknowns, a far cheaper factor, more
but cheaper steps). Up to
:data:`core.kernels.step.SMALL_INVERSE` variables ``A^-1`` is one compiled call (SciPy's
wrappers cost more than the arithmetic there), and with one constraint (the volume alone)
the Woodbury term is a scalar.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import blas

from ..kernels import step as stepkernels

#: added to the diagonal, relative to its mean: keeps rigid motions (zero energy) invertible
RIDGE = 1e-6
#: up to this many variables the inverses are explicit matrices (see the module notes)
EXPLICIT = 400
#: above this many variables (whole nodes) a sparse curvature is factored on the nodes
#: (:meth:`Curvature._node_factor`); below it exactly, which saves steps where a factor is
#: cheap (a live frame's 1215 variables: 3 steps against 8)
NODE_FACTOR = 6000


class Product:
    """``v -> matrix @ v``: an explicit inverse Hessian, which the compiled L-BFGS
    recursion takes as the matrix itself (:func:`isochor.core.kernels.step.two_loop`)."""

    __slots__ = ("matrix",)

    def __init__(self, matrix: np.ndarray) -> None:
        self.matrix = np.ascontiguousarray(matrix, dtype=np.float64)

    def __call__(self, v: np.ndarray) -> np.ndarray:
        return self.matrix @ v


def dissection(shape: tuple[int, int, int]) -> np.ndarray:
    """(nodes,) the nodes of a lattice in nested-dissection order: the grid is cut at the
    middle plane of its longest side, the two halves come first (each cut the same way) and
    the plane last. Factoring a lattice's curvature in this order fills in far less than
    SuperLU's own orderings (16x16x16: 7.7M entries against 9.9M, and faster)."""
    out: list[np.ndarray] = []

    def cut(block: np.ndarray) -> None:
        if block.size <= 8:
            out.append(block.ravel())
            return
        axis = int(np.argmax(block.shape))
        c = block.shape[axis] // 2
        cut(np.take(block, range(c), axis=axis))
        cut(np.take(block, range(c + 1, block.shape[axis]), axis=axis))
        out.append(np.take(block, [c], axis=axis).ravel())

    cut(np.arange(int(np.prod(shape))).reshape(shape))
    return np.concatenate(out)


class Curvature:
    """``A = H + ridge``, factored once; :meth:`solve` applies ``A^-1``.

    Parameters
    ----------
    hessian : (count, count) the energy's Hessian over the variables (the node-coordinate
        Hessian restricted by :meth:`isochor.core.solve.solver.Coordinates.restrict`), in the
        solver's units (energy / size^2 per (coordinate / size)^2)
    order : (count,) the order to factor a sparse ``hessian`` in (a permutation of the
        variables: :func:`dissection` of the lattice); None: SuperLU's own
    whole_nodes : the variables are whole nodes, x, y, z of each in a row: a sparse
        ``hessian`` of more than :data:`NODE_FACTOR` of them is then factored on the nodes
        alone (:meth:`_node_factor`)
    """

    def __init__(self, hessian, order: np.ndarray | None = None, whole_nodes=False) -> None:
        self._factor: Any  # cho_factor's (c, lower) once made
        self._factor, self.inverse, self._sparse = None, None, None
        self._order: np.ndarray | None
        self._order, self._nodes = None, False
        if sp.issparse(hessian):
            if whole_nodes and hessian.shape[0] % 3 == 0 and hessian.shape[0] > NODE_FACTOR:
                self._node_factor(hessian, order)
            else:
                self._sparse_factor(hessian, order)
            return
        a = np.array(hessian, dtype=np.float64)
        self.count = len(a)
        ridge = RIDGE * max(float(a.trace()) / max(self.count, 1), 1e-12)
        # compiled, for small matrices only (None otherwise; False: not positive definite)
        small = stepkernels.spd_inverse(a, ridge) if self.count <= EXPLICIT else None
        if small is not None:
            self.inverse = small if isinstance(small, np.ndarray) else None
            return
        a.flat[:: self.count + 1] += ridge  # the diagonal
        try:
            factor = la.cho_factor(a, lower=True, check_finite=False)
        except (la.LinAlgError, ValueError):
            return
        if not _finite(factor[0]):
            return
        self._factor = factor
        if self.count <= EXPLICIT:
            self.inverse = la.cho_solve(factor, np.eye(self.count), check_finite=False)

    def _sparse_factor(self, hessian, order: np.ndarray | None) -> None:
        """The sparse path (see the module): SuperLU of ``A``, kept when it is positive
        definite (every pivot positive, no pivoting)."""
        a = sp.csr_matrix(hessian, dtype=np.float64)
        self.count = a.shape[0]
        ridge = RIDGE * max(float(a.diagonal().sum()) / max(self.count, 1), 1e-12)
        a = a + ridge * sp.identity(self.count, format="csr")
        if order is not None and len(order) == self.count:
            self._order = np.asarray(order, dtype=np.int64)
            a = a[self._order][:, self._order]
        # single precision: the factor only preconditions (the L-BFGS pairs correct it),
        # and SuperLU factors and solves about 1.5x faster in it
        self._lu(a)

    def _node_factor(self, hessian, order: np.ndarray | None) -> None:
        """The sparse path on whole nodes: ``A``'s 3x3 blocks replaced by a third of their
        trace (positive semi-definite as ``A`` is: a weighted graph of the nodes), one
        factor for the three coordinates. Three times fewer unknowns: the factorisation
        of a 16x16x16 lattice is many times cheaper; the L-BFGS pairs learn the
        directions it leaves out (a dense lattice's solve takes about 3x the steps, each
        cheaper, and ends 25% sooner)."""
        a = sp.coo_matrix(hessian, dtype=np.float64)
        self.count = a.shape[0]
        n = self.count // 3
        same = a.row % 3 == a.col % 3
        nodes = sp.csr_matrix(
            (a.data[same] / 3.0, (a.row[same] // 3, a.col[same] // 3)), shape=(n, n)
        )
        ridge = RIDGE * max(float(nodes.diagonal().sum()) / max(n, 1), 1e-12)
        nodes = nodes + ridge * sp.identity(n, format="csr")
        if order is not None and len(order) == self.count:
            self._order = np.asarray(order[::3] // 3, dtype=np.int64)
            nodes = nodes[self._order][:, self._order]
        self._nodes = True
        self._lu(nodes)

    def _lu(self, a) -> None:
        """SuperLU of the (ordered) matrix ``a`` in single precision, kept when every pivot
        is positive."""
        a = sp.csc_matrix(a, dtype=np.float32)
        if not _finite(a.data):
            return
        try:
            lu = spla.splu(
                a,
                permc_spec="MMD_AT_PLUS_A" if self._order is None else "NATURAL",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except (RuntimeError, ValueError):
            return
        pivots = lu.U.diagonal()
        if _finite(pivots) and bool(np.all(pivots > 0)):
            self._sparse = lu

    @property
    def sparse(self) -> bool:
        """Whether ``A`` was factored as a sparse matrix."""
        return self._sparse is not None

    @property
    def ok(self) -> bool:
        """``A`` is positive definite (with finite numbers)."""
        return self._factor is not None or self.inverse is not None or self._sparse is not None

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` for ``b`` (count,) or (count, k)."""
        if self._sparse is not None and self._nodes:  # x, y, z (and columns) side by side
            b = np.asarray(b, dtype=np.float64)
            rows = b.reshape(self.count // 3, -1)
            out = np.empty_like(rows)
            if self._order is None:
                out[:] = self._sparse.solve(rows.astype(np.float32))
            else:
                out[self._order] = self._sparse.solve(rows[self._order].astype(np.float32))
            return out.reshape(b.shape)
        if self._sparse is not None:
            b = np.asarray(b, dtype=np.float64)
            if self._order is None:
                return self._sparse.solve(b.astype(np.float32)).astype(np.float64)
            out = np.empty_like(b)
            out[self._order] = self._sparse.solve(b[self._order].astype(np.float32))
            return out
        if self.inverse is not None:
            return self.inverse @ b
        if b.ndim == 1 and b.dtype == np.float64:
            # a step's product: BLAS's two triangular solves on the (Fortran-ordered)
            # factor; SciPy's cho_solve checks and copies as much again (1341 variables,
            # an 8x8x8 lattice: 0.46 against 0.87 ms)
            low = self._factor[0]
            return blas.dtrsv(low, blas.dtrsv(low, b, lower=1), lower=1, trans=1)
        return la.cho_solve(self._factor, b, check_finite=False)


class Preconditioner:
    """``v -> M^-1 v`` for ``M = A + sigma J^T J``, one ``sigma`` at a time.

    Parameters
    ----------
    curvature : the energy's :class:`Curvature` (shared by the levels of a solve)
    jacobian : (m, count) constraint gradients in the variables
    """

    def __init__(self, curvature: Curvature, jacobian: np.ndarray) -> None:
        self.curvature = curvature
        jac = np.atleast_2d(np.asarray(jacobian, dtype=np.float64))
        self._jac: np.ndarray | None = jac if jac.size else None
        self._u = curvature.solve(jac.T) if curvature.ok and jac.size else None
        self._sigma: float | None = None
        self._apply: Callable[[np.ndarray], np.ndarray] | None = None

    def stiffness(self) -> float:
        """The energy's stiffness against the constraints, ``kappa = 1 / lambda_min(J A^-1
        J^T)``: on the quadratic model, moving the constraints by ``t`` (their gradients'
        directions, the rest free) costs at most ``kappa |t|^2 / 2`` of energy. The
        multiplier update's linear rate is about ``kappa / (kappa + sigma)``
        (:func:`isochor.core.solve.solver.augmented_lagrangian`). Combinations of the
        constraints that the free variables cannot move (dependent constraints: an
        eigenvalue within rounding of 0) are left out; 0.0 where nothing is known (no
        constraint, a curvature that is not positive definite)."""
        if self._u is None or not _finite(self._u):
            return 0.0
        w = np.linalg.eigvalsh(np.atleast_2d(self._jac @ self._u))
        moved = w[w > len(w) * np.finfo(float).eps * max(float(w[-1]), 0.0)]
        return 1.0 / float(moved[0]) if moved.size else 0.0

    def at(self, sigma: float) -> Callable[[np.ndarray], np.ndarray] | None:
        """``v -> M^-1 v`` for this ``sigma``, or None where ``M`` is not positive definite
        (non-finite numbers): the solver then keeps the plain L-BFGS scaling."""
        if sigma != self._sigma:
            self._sigma, self._apply = sigma, self._make(float(sigma))
        return self._apply

    def _make(self, sigma: float) -> Callable[[np.ndarray], np.ndarray] | None:
        a, u, jac = self.curvature, self._u, self._jac
        if not a.ok:
            return None
        if u is None or jac is None or not sigma > 0:
            return a.solve if a.inverse is None else Product(a.inverse)
        if len(jac) == 1:  # the usual case, the volume alone: a scalar, no inverse
            s_inv = np.array([[1.0 / (1.0 / sigma + float(jac[0] @ u[:, 0]))]])
        else:
            try:
                s_inv = np.linalg.inv(np.eye(len(jac)) / sigma + jac @ u)
            except np.linalg.LinAlgError:
                return None
        if not _finite(s_inv):
            return None
        if a.inverse is not None:
            m_inv = a.inverse - (u @ s_inv) @ u.T
            return Product(m_inv) if _finite(m_inv) else None

        def apply(v: np.ndarray) -> np.ndarray:
            return a.solve(v) - u @ (s_inv @ (u.T @ v))

        return apply


def _finite(a: np.ndarray) -> bool:
    """Every number of ``a`` finite."""
    return bool(np.isfinite(a).all())
