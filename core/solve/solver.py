"""Augmented Lagrangian over the free nodes (paper Eq 15-21, Fig 3).

``La = E + sigma/2 |c|^2 - lambda . c`` where ``c`` are the constraints, each made
scale-free (the volume deviation ``(V(X) - V_target) / V_ref``, one per body, the centroid:
:mod:`isochor.core.goal.constraints`), and ``E`` is the spring energy of node positions measured
in units of the object size. The optimisation variables are the free node coordinates in
those units, ``y = (X_free - centre) / size`` (a node pinned on some axes only is free on
the others), so a model in millimetres and the same model in metres take the same steps
with the same sigma.

The inner unconstrained minimisation is limited-memory BFGS (:mod:`isochor.core.solve.lbfgs`),
a generator, so that the editor sees every iterate as it comes and can stop the work at
once.

Outer loop (Fig 3): ``lambda <- lambda - sigma c``; sigma doubles whenever the worst
``|c_i|`` did not fall to half its previous value (Powell's rule), up to ``sigma_max``.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass
from functools import cached_property, partial
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..defaults import TOL_NODES, TOL_VOLUME
from .generators import relay
from .lbfgs import Objective, lbfgs
from .precondition import Curvature, Preconditioner, dissection


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances and limits; every length is relative to the object size, every volume to
    the reference volume, so the defaults suit any model."""

    tol_volume: float = TOL_VOLUME  #: |dV| / V0 that counts as preserved
    tol_nodes: float = TOL_NODES  #: epsilon: largest node change between levels (Sec 4.3)
    sigma0: float = 10.0  #: first penalty factor, at the least
    #: each level's penalty factor is at least this times the energy's stiffness against
    #: the constraints (:meth:`isochor.core.solve.precondition.Preconditioner.stiffness`):
    #: the multiplier update's linear rate is about ``kappa / (kappa + sigma)``, so 9 gains
    #: a digit of the volume an outer iteration. A fixed ``sigma0`` suits no model: kappa
    #: is 0.8 on the club compression and 72 on the torus compression, where sigma 10 took
    #: 10 outer iterations (rate 0.85, then 0.45). 0: ``sigma0`` alone (the paper's).
    #: Needs ``precondition``.
    stiffness_ratio: float = 9.0
    #: an inner run stops early while the constraints are far from met, once its gradient
    #: is below this share of the change the next multiplier update makes to it
    #: (:func:`isochor.core.solve.solver._loose`); 0: every run to ``gtol`` (the paper's).
    #: 0.01 cut the torus compression's first level from 28 steps to 19 and the squashed
    #: cow's from 70 to 56, with the same energies to six digits; 0.1 changed them in the
    #: fourth
    inexact: float = 0.01
    #: first penalty factor of a warm start (a re-solve, a drag's frame), preconditioned:
    #: its multipliers come from the start point, so a firm penalty only speeds it up
    #: (a live frame on the torus example: 23 steps at sigma 10, 11 at 1000)
    sigma_warm: float = 1000.0
    sigma_max: float = 1e8  #: cap on the penalty factor (paper: "an upper bound for sigma")
    #: inner minimisation stops when max |dLa/dy| is below this (1e-6 cost 7-40% more time
    #: for no gain in the results' accuracy; 1e-4 lets the cow's node change reach 0.1%)
    gtol: float = 1e-5
    max_inner: int = 500  #: inner steps per outer iteration at most
    max_outer: int = 60  #: Lagrange-multiplier updates per level at most
    #: inner steps per level at most, over all outer iterations: an edit that cannot be
    #: met (a node dragged a thousand sizes away against the fold guard) stops as not
    #: converged in seconds instead of spending max_outer * max_inner steps
    max_steps: int = 5000
    memory: int = 12  #: L-BFGS correction pairs
    volume_margin: float = 0.5  #: a level is solved at ``volume_margin * tol_volume``
    #: size of the start nudge of free nodes, / object size. The preconditioned solver
    #: converges so fast that a 1e-4 nudge leaves it on the torus stretch's symmetric
    #: saddle (spring energy 0.3137 against the minimum's 0.3111); 1e-2 does not.
    symmetry_break: float = 1e-2
    #: A fresh solve starts on the coarsest level with at least this many triangles. Below
    #: a few hundred triangles a step costs as much as on a mid-sized level (fixed call
    #: overhead) and the level's optimum is far from the real one (a 16-triangle torus has
    #: 14% of the torus's volume), so those levels cost time without earning it: measured
    #: on the paper's examples, starting at 16 or 20 triangles was up to 2x slower than
    #: starting near 1000 (docs/BENCHMARKS.md, start-level sweep). 0 gives the paper's
    #: schedule.
    start_triangles: int = 1000
    #: start each inner minimisation from the springs' Hessian and the penalty's
    #: Gauss-Newton term (:mod:`isochor.core.solve.precondition`) instead of a scaled identity
    precondition: bool = True
    #: a live drag's frames are solved up to the finest level with at most this many
    #: triangles (:func:`isochor.core.solve.multilevel.solve` with ``live``)
    live_triangles: int = 6000


#: the preconditioner's curvature is taken again once the variables moved this far
#: (/ object size) from where it was taken; a drag's frame and a level that starts near its
#: optimum keep one
CURVATURE_MOVE = 1e-2
#: the same for a sparse curvature (a dense lattice of a local basis), whose factorisation
#: costs most of a solve (16x16x16: 0.4-0.8 s): taken again only after a larger move; the
#: L-BFGS pairs correct the older curvature meanwhile
SPARSE_CURVATURE_MOVE = 0.25


class Curvatures:
    """The preconditioner's curvature (:class:`~isochor.core.solve.precondition.Curvature`) of
    one solve, shared by its levels (the springs and the fold guard are the same on every
    level; each level adds its own constraints), and by the solves of a drag that follow
    it (:meth:`isochor.core.solve.surface.EmbeddedSurface.shared`): taken at the first variables
    asked for, again once they moved more than :data:`CURVATURE_MOVE` from there.

    Parameters
    ----------
    hessian : ``X -> (3n, 3n)`` the energy's Hessian over the node coordinates
    coords : the solve's :class:`Coordinates`
    shape : the lattice's node counts: a sparse curvature is factored in the nested
        dissection order of its grid (:func:`~isochor.core.solve.precondition.dissection`)
    """

    def __init__(self, hessian, coords: Coordinates, shape=None) -> None:
        self.hessian, self.coords = hessian, coords
        self._order = None if shape is None else coords.ordered(dissection(tuple(shape)))
        #: (y, its curvature): one tuple, so that a solver thread that is being stopped
        #: and the next solve's thread never see half of an update
        self._taken: tuple[np.ndarray, Curvature] | None = None

    def at(self, y: np.ndarray, nodes) -> Curvature:
        """The curvature for variables ``y``; ``nodes()`` gives their node positions."""
        taken = self._taken
        far = CURVATURE_MOVE if taken is None or not taken[1].sparse else SPARSE_CURVATURE_MOVE
        if taken is None or np.abs(y - taken[0]).max() > far:
            h = self.coords.restrict(self.hessian(nodes()))
            if sp.issparse(h):
                curvature = Curvature(h, self._order, self.coords.whole_nodes)
            else:
                curvature = Curvature(h)
            taken = (np.array(y), curvature)
            self._taken = taken
        return taken[1]

    def renew(self, y: np.ndarray, nodes) -> Curvature | None:
        """A sparse curvature taken again at ``y`` (``nodes()`` their node positions), or
        None where the curvature is dense or not taken yet (it stays as it is)."""
        taken = self._taken
        if taken is None or not taken[1].sparse:
            return None
        h = self.coords.restrict(self.hessian(nodes()))
        curvature = Curvature(h, self._order, self.coords.whole_nodes)
        if not curvature.ok:
            return None
        self._taken = (np.array(y), curvature)
        return curvature


@dataclass(frozen=True)
class Iterate:
    """One accepted inner step."""

    y: np.ndarray
    energy: float
    deviation: float  #: the worst constraint residual
    step: int  #: inner steps so far at this level
    outer: int
    sigma: float
    lam: float  #: the first multiplier (the total volume's, or the first body's)


class Coordinates:
    """The solver's variables ``y``: the free node coordinates in object sizes about the
    centre, and the coordinates tied to them (under symmetry the high side of the lattice
    follows the low side: ``x.flat[dst] = sign * x.flat[src] + offset``, see
    :meth:`isochor.core.goal.symmetry.Mirror.ties`).

    Parameters
    ----------
    free : (n, 3) bool, the coordinates that are variables (an (n,) mask frees whole nodes)
    center, size : the normalisation of lengths
    ties : ``(dst, src, sign, offset)`` flat arrays, or None
    """

    def __init__(self, free, center, size, ties: tuple | None = None) -> None:
        free = np.asarray(free, dtype=bool)
        self.free = free[:, None].repeat(3, axis=1) if free.ndim == 1 else free.copy()
        self.center, self.size = np.asarray(center, dtype=np.float64), float(size)
        self._origin = np.broadcast_to(self.center, self.free.shape)[self.free]
        empty: np.ndarray = np.zeros(0, dtype=int)
        self.dst, self.src, self.sign, self.offset = ties or (empty, empty, 0.0, 0.0)
        self._columns = np.flatnonzero(self.free.ravel())
        self.count = len(self._columns)

    @cached_property
    def key(self) -> tuple:
        """What the variables are: equal keys, the same variables (see :class:`Curvatures`)."""
        ties = (self.dst, self.src, self.sign, self.offset)
        return (self.free.tobytes(), self.center.tobytes(), self.size) + tuple(
            np.asarray(t, dtype=np.float64).tobytes() for t in ties
        )

    @cached_property
    def matrix(self) -> sp.csr_matrix:
        """(count, 3n) sparse: :meth:`reduce` as a matrix, ``reduce(g) = matrix @ g.ravel()``."""
        n = self.free.size
        rows = np.full(n, -1)
        rows[self._columns] = np.arange(self.count)
        r, c, v = [np.arange(self.count)], [self._columns], [np.ones(self.count)]
        if len(self.dst):
            src, dst = np.asarray(self.src), np.asarray(self.dst)
            sign = np.broadcast_to(np.asarray(self.sign, dtype=np.float64), src.shape)
            keep = rows[src] >= 0
            r.append(rows[src][keep])
            c.append(dst[keep])
            v.append(sign[keep])
        return sp.csr_matrix(
            (np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(self.count, n)
        )

    def restrict(self, h: Any) -> np.ndarray:
        """A (3n, 3n) matrix over the node coordinates (a Hessian) as one over the
        variables, ``matrix @ h @ matrix.T``: a plain selection without ties."""
        if sp.issparse(h):  # a dense local lattice (core.springs.SPARSE_VARIABLES)
            if len(self.dst):
                return (self.matrix @ (self.matrix @ h).T).tocsr()
            return h.tocsr()[self._columns][:, self._columns]
        if len(self.dst):
            return np.asarray(self.matrix @ (self.matrix @ h).T)
        return h.take(self._columns, axis=0).take(self._columns, axis=1)

    @cached_property
    def whole_nodes(self) -> bool:
        """Whether the variables are whole nodes (x, y, z of each, in a row) with no ties."""
        cols = self._columns
        if len(self.dst) or len(cols) % 3:
            return False
        triples = cols.reshape(-1, 3)
        return bool(np.all(triples[:, 0] % 3 == 0) and np.all(np.diff(triples, axis=1) == 1))

    def ordered(self, node_order: np.ndarray) -> np.ndarray:
        """(count,) the variables sorted by their node's place in ``node_order`` (a
        permutation of the nodes), coordinates x, y, z of a node together."""
        rank = np.empty(len(node_order), dtype=np.int64)
        rank[np.asarray(node_order)] = np.arange(len(node_order))
        key = rank[self._columns // 3] * 3 + self._columns % 3
        return np.argsort(key, kind="stable")

    @property
    def moving(self) -> np.ndarray:
        """(n, 3) bool: every coordinate the solve changes (variables and tied ones)."""
        out = self.free.copy()
        out.reshape(-1)[self.dst] = True
        return out

    def to_y(self, nodes: np.ndarray) -> np.ndarray:
        return (np.asarray(nodes, dtype=np.float64)[self.free] - self._origin) / self.size

    def to_nodes(self, y: np.ndarray, template: np.ndarray) -> np.ndarray:
        out = np.array(template, dtype=np.float64)
        out.reshape(-1)[self._columns] = self._origin + self.size * y
        return self.tied(out)

    def tied(self, nodes: np.ndarray) -> np.ndarray:
        """``nodes`` (changed in place) with the tied coordinates set from their variables."""
        if len(self.dst):
            flat = nodes.reshape(-1)
            flat[self.dst] = self.sign * flat[self.src] + self.offset
        return nodes

    def reduce(self, g: np.ndarray) -> np.ndarray:
        """A gradient over the nodes ``(..., n, 3)`` as one over the variables
        ``(..., count)`` (a tied coordinate's part goes to the variable it follows)."""
        g = np.asarray(g, dtype=np.float64)
        flat = g.reshape(*g.shape[:-2], -1)
        if len(self.dst):
            flat = flat.copy()
            flat[..., self.src] += self.sign * flat[..., self.dst]
        return flat.take(self._columns, axis=-1)


class LevelProblem:
    """Energy and constraints of one level as functions of the variables ``y``.

    Parameters
    ----------
    nodes : (n, 3) current node positions; the fixed coordinates stay as given
    free : :class:`Coordinates`, or an (n, 3) bool mask of the coordinates the solver may
        move (an (n,) mask frees whole nodes)
    energy_grad : ``X -> (E, dE/dX)`` in world units
    constraint_grad : ``X -> (c, dc/dX)``, ``(m,)`` and ``(m, n, 3)``, already scale-free
        (see :mod:`isochor.core.goal.constraints`)
    center, size : the normalisation of lengths
    curvatures : the :class:`Curvatures` the levels of a solve share; None: no
        preconditioner
    """

    def __init__(self, nodes, free, energy_grad, constraint_grad, center, size, curvatures=None):
        self.template = np.array(nodes, dtype=np.float64)
        self.coords = free if isinstance(free, Coordinates) else Coordinates(free, center, size)
        self.energy_grad, self.constraint_grad = energy_grad, constraint_grad
        self.curvatures: Curvatures | None = curvatures
        self._preconditioner: Preconditioner | None = None
        self._last: tuple[bytes, tuple] | None = None  # (y's bytes, its terms)
        self._evaluated: tuple[np.ndarray, np.ndarray] | None = None  # (y, its nodes)
        self.size = self.coords.size

    def preconditioner(self, y: np.ndarray, sigma: float):
        """``v -> M^-1 v``, the approximate inverse Hessian of the augmented Lagrangian
        (:mod:`isochor.core.solve.precondition`): the shared curvature (see :class:`Curvatures`)
        with this level's constraint gradients, taken where the level first asks after the
        curvature was (re)taken; None without an energy Hessian."""
        pre = self._taken(y)
        return None if pre is None else pre.at(sigma)

    def stiffness(self, y: np.ndarray) -> float:
        """The energy's stiffness against this level's constraints where :meth:`preconditioner`
        takes its curvature (:meth:`isochor.core.solve.precondition.Preconditioner.stiffness`),
        0.0 without an energy Hessian."""
        pre = self._taken(y)
        return 0.0 if pre is None else pre.stiffness()

    def renewed(self, y: np.ndarray, sigma: float):
        """``v -> M^-1 v`` made again at ``y`` (the shared curvature taken there) where the
        curvature is sparse (:meth:`Curvatures.renew`), else None: an L-BFGS run that is
        still going after :data:`isochor.core.solve.lbfgs.PRECONDITIONED_STEPS` steps
        takes it instead of going on with the scaled identity."""
        if self.curvatures is None:
            return None
        curvature = self.curvatures.renew(y, lambda: self.to_nodes(y))
        if curvature is None:
            return None
        pre = self._preconditioner = Preconditioner(curvature, self.terms(y)[3])
        return pre.at(sigma)

    def _taken(self, y: np.ndarray) -> Preconditioner | None:
        """The :class:`Preconditioner` for ``y``: made again when the shared curvature was."""
        if self.curvatures is None:
            return None
        curvature = self.curvatures.at(y, lambda: self.to_nodes(y))
        pre = self._preconditioner
        if pre is None or pre.curvature is not curvature:
            jac = self.terms(y)[3]  # (where the run starts: its first evaluation, memoised)
            pre = self._preconditioner = Preconditioner(curvature, jac)
        return pre

    def to_y(self, nodes: np.ndarray) -> np.ndarray:
        return self.coords.to_y(nodes)

    def to_nodes(self, y: np.ndarray) -> np.ndarray:
        return self.coords.to_nodes(y, self.template)

    def terms(self, y: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """Normalised energy, its gradient, the constraints c (m,) and their gradients
        (m, len(y)), all in ``y``. The last ``y``'s are remembered: the solver asks for
        them again where an inner run ends and where the next one starts."""
        key = np.asarray(y, dtype=np.float64).tobytes()
        last = self._last
        if last is not None and last[0] == key:
            return last[1]
        x = self.to_nodes(y)
        x.flags.writeable = False  # (handed on by nodes_of)
        e, de = self.energy_grad(x)
        c, dc = self.constraint_grad(x)
        s, reduce = self.size, self.coords.reduce
        out = e / s**2, reduce(de) / s, np.asarray(c, dtype=np.float64), reduce(dc) * s
        self._last = (key, out)
        self._evaluated = (y, x)
        return out

    def nodes_of(self, y: np.ndarray) -> np.ndarray:
        """Read-only (n, 3) nodes for ``y``: those its evaluation used when ``y`` is the
        array evaluated last (an accepted step's, for its progress record), else new."""
        last = self._evaluated
        if last is not None and last[0] is y:
            return last[1]
        nodes = self.to_nodes(y)
        nodes.flags.writeable = False
        return nodes

    def deviation(self, y: np.ndarray) -> np.ndarray:
        return self.terms(y)[2]

    def lagrangian(self, lam: np.ndarray, sigma: float) -> Objective:
        """``y -> (La, dLa/dy, (E, worst c))`` for fixed multipliers and penalty (Eq 19)."""

        lam0 = float(lam[0]) if len(lam) == 1 else None

        def fun(y: np.ndarray):
            e, de, c, dc = self.terms(y)
            if lam0 is not None:  # the usual case, the volume alone: scalars, same numbers
                c0 = float(c[0])
                return e + c0 * (0.5 * sigma * c0 - lam0), de + (sigma * c0 - lam0) * dc[0], (e, c0)
            la = e + float(c @ (0.5 * sigma * c - lam))
            return la, de + (sigma * c - lam) @ dc, (e, worst(c))

        return fun


def worst(c: np.ndarray) -> float:
    """The constraint residual of largest magnitude, with its sign."""
    c = np.asarray(c, dtype=np.float64)
    if c.size <= 1:  # the usual case: the volume alone
        return float(c[0]) if c.size else 0.0
    return float(c[np.abs(c).argmax()])


@dataclass(frozen=True)
class ALResult:
    y: np.ndarray
    lam: np.ndarray  #: (m,) multipliers
    sigma: float
    deviation: float  #: the worst constraint residual
    energy: float
    steps: int
    outer: int
    converged: bool


def _loose(problem: LevelProblem, y: np.ndarray, sigma: float, tol: float, inexact: float):
    """The inner run's looser stopping test while the constraints are far from met: ``aux
    -> inexact * sigma * |c| * max |dc/dy|`` (0 once ``|c|`` is within ten tolerances), or
    None for none.

    The multiplier update that follows an inner run, ``lambda -= sigma c``, changes the
    Lagrangian's gradient by ``sigma c dc/dy``. Solving the inner problem much finer than
    that only polishes a point the update moves away from (the torus compression's first
    run spent 16 of its 22 steps there). The last runs, near the constraints, still stop at
    ``gtol`` alone, so a converged level ends as before (Conn, Gould and Toint's inexact
    augmented Lagrangian, with this tolerance tied to the infeasibility)."""
    if not inexact > 0 or not len(y):
        return None
    reach = float(np.max(np.abs(problem.terms(y)[3])))
    near = 10.0 * tol

    def loose(aux: tuple[float, float]) -> float:
        c = abs(aux[1])
        return inexact * sigma * c * reach if c > near else 0.0

    return loose


def augmented_lagrangian(
    problem: LevelProblem,
    y0: np.ndarray,
    lam: np.ndarray,
    sigma: float,
    options: SolverOptions,
) -> Generator[Iterate, None, ALResult]:
    """Fig 3: minimise La, update lambda, raise sigma when the worst |c| does not halve;
    repeat. The penalty factor starts at ``sigma`` or at ``options.stiffness_ratio`` times
    the energy's stiffness against the constraints, whichever is larger."""
    tol = options.volume_margin * options.tol_volume
    y = np.array(y0, dtype=np.float64)
    lam = np.array(lam, dtype=np.float64)
    g_prev = float(np.max(np.abs(problem.deviation(y))))
    if options.precondition and options.stiffness_ratio > 0:
        stiff = options.stiffness_ratio * problem.stiffness(y)
        sigma = min(max(sigma, stiff), options.sigma_max)
    steps = 0
    energy = g = float("nan")
    for outer in range(options.max_outer):
        inner = lbfgs(
            problem.lagrangian(lam, sigma),
            y,
            gtol=options.gtol,
            max_iter=options.max_inner,
            memory=options.memory,
            h0=problem.preconditioner(y, sigma) if options.precondition else None,
            loose=_loose(problem, y, sigma, tol, options.inexact),
            renew=partial(problem.renewed, sigma=sigma) if options.precondition else None,
        )

        def iterate(record, outer=outer, sigma=sigma, lam=lam):
            nonlocal steps
            steps += 1
            y_k, (energy_k, g_k) = record
            return Iterate(y_k, energy_k, g_k, steps, outer, sigma, float(lam[0]))

        y, _, _ = yield from relay(inner, iterate)
        energy, _, c, _ = problem.terms(y)
        g = float(np.max(np.abs(c)))
        if g <= tol:
            return ALResult(y, lam, sigma, worst(c), energy, steps, outer + 1, True)
        if steps >= options.max_steps:
            break
        lam = lam - sigma * c
        if g > 0.5 * g_prev:
            sigma = min(2.0 * sigma, options.sigma_max)
        g_prev = g
    return ALResult(y, lam, sigma, worst(c), energy, steps, outer + 1, False)
