"""Multi-level optimisation (paper Sec 4.3, Fig 4, Eq 27-29).

A pyramid of versions of the same surface, coarse to fine, each about 4 times finer than
the last; the last is the full-resolution mesh. The constrained minimisation runs on the
coarsest level first; node positions X, penalty sigma and multiplier lambda are inherited by
the next level. Each level measures its deviation against its own rest volume (Eq 27), but
all deviations are divided by one reference volume (the full mesh's), so the inherited
sigma means the same on every level.

The solve ends at level k when
  * the largest node change between level k-1 and k is below epsilon (``tol_nodes`` of the
    object size), and level k meets the volume tolerance,
  * the discretisation error of level k estimated by Eq 29 (applied to the deviation, with
    the measured triangle ratio between levels) is within the tolerance, and
  * the deviation measured on the full-resolution mesh is within the tolerance,
or when the full-resolution level itself has been solved.

:func:`solve` is a generator: it yields an immutable :class:`Progress` record every inner
step and at each level's end, and returns a :class:`SolveResult`. Closing it stops the work
at once. The window, the command line, the benchmark and the tests all drive the same one.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from .. import blas, kernels
from ..errors import IsochorError
from ..goal.anchor import held_face
from ..goal.constraints import Constraints
from ..goal.handles import Handle, HandleSystem, handle_rows
from ..goal.spec import Goal
from ..goal.symmetry import Mirror
from ..lattice import Lattice
from ..springs import sparse_hessian
from .generators import relay
from .outcome import outcome, preview
from .plan import Ending, Iterate, Plan, Request
from .records import LevelStats, Progress, SolveResult, frozen_copy
from .solver import (
    Coordinates,
    Curvatures,
    LevelProblem,
    SolverOptions,
    augmented_lagrangian,
    worst,
)
from .surface import FOLD_MARGIN, EmbeddedSurface, live_level

__all__ = ["EmbeddedSurface", "Progress", "SolveResult", "live_level", "solve"]


#: a live frame of a dense local lattice (above :data:`isochor.core.springs.SPARSE_VARIABLES`
#: coordinates) solves only the free nodes within this many node steps of the moved ones
LIVE_REACH = 4


def live_reach(lattice: Lattice, nodes: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """(n,) bool: the nodes a live frame may move. Every node, except on a dense lattice of
    a local basis: there each point moves with its 4x4x4 nearest nodes only, and a frame
    that solved all of them (12k coordinates at 16x16x16) would take a sparse solve per
    step; it moves the nodes within :data:`LIVE_REACH` steps of the moved ones (fixed away
    from rest) instead, enough to hold the volume on the preview level. The solve when the
    drag ends moves them all."""
    everything = np.ones(lattice.n_nodes, dtype=bool)
    if not (lattice.local and sparse_hessian(lattice.n_nodes)):
        return everything
    away = np.any(np.abs(nodes - lattice.rest_nodes) > 1e-12 * lattice.size, axis=1)
    moved = np.flatnonzero(fixed.any(axis=1) & away)
    if len(moved) == 0:
        return everything
    ijk = np.indices(lattice.shape).reshape(3, -1).T
    near = np.zeros(lattice.n_nodes, dtype=bool)
    for r in moved:
        near |= np.abs(ijk - ijk[r]).max(axis=1) <= LIVE_REACH
    return near


@kernels.one_path
@blas.per_step
def solve(
    surface: EmbeddedSurface,
    nodes: np.ndarray,
    fixed: np.ndarray,
    *,
    target_ratio: float = 1.0,
    goal: Goal | None = None,
    handles: Sequence[Handle] = (),
    options: SolverOptions | None = None,
    start_level: int | None = None,
    near: bool = False,
    live: bool = False,
) -> Generator[Progress, None, SolveResult]:
    """Move the free nodes to the least spring energy that meets the goal.

    Parameters
    ----------
    surface : the embedded surface pyramid
    nodes : (n, 3) current node positions (moved nodes where the user put them)
    fixed : (n,) bool, True for pinned and moved nodes, or (n, 3) bool per coordinate
    target_ratio : target volume over the rest volume, when no ``goal`` is given
    goal : what to hold (:class:`isochor.core.goal.spec.Goal`); by default the volume at
        ``target_ratio``, with the far-side anchor and the fold guard
    handles : points of the model that must land at given places
        (:class:`isochor.core.goal.handles.Handle`); under symmetry each gets its mirror image
    start_level : first pyramid level to solve on; by default the coarsest level with at
        least ``options.start_triangles`` triangles
    near : ``nodes`` solve a nearby problem (the frame before, in a sequence): start on the
        coarsest level whose constraints agree with the full mesh's there, with the
        least-squares multipliers, as a re-solve does, even though the goal is not met yet
    live : a frame of a live drag (implies ``near``): solve only up to the finest level with
        at most ``options.live_triangles`` triangles and never touch the full mesh; the
        result is measured on that level and marked ``preview`` (the solve when the drag
        ends gives the measured one)

    Yields
    ------
    Progress: one at once with the start state (step 0), then every inner step and at
    each level's end.

    Returns
    -------
    SolveResult, with the volumes, the folds and the centroid measured on the
    full-resolution mesh (on the preview level, with ``live``).
    """
    request = Request(
        goal or Goal(target_ratio=target_ratio),
        tuple(handles),
        options or SolverOptions(),
        start_level,
        near,
        live,
    )
    plan = prepare(surface, nodes, fixed, request, time.perf_counter())
    if not plan.coords.count:
        nothing = Ending(
            plan.nodes, (), -1, np.zeros(1), 0.0, True, "no free node: nothing to solve"
        )
        return _result(plan, nothing)
    yield _start_record(plan)
    objective = _objective(plan)
    level, start = _starting_point(plan, objective)
    ending = yield from _run_levels(plan, objective, level, start)
    return _result(plan, ending)


def prepare(
    surface: EmbeddedSurface, nodes: np.ndarray, fixed: np.ndarray, request: Request, t0: float
) -> Plan:
    """The solve's set-up: the start nodes checked and made symmetric, the handles
    mirrored, the far-side face held, the free coordinates, the levels to run and the
    handles' system."""
    lattice, goal = surface.lattice, request.goal
    x, fixed = _start_nodes(surface, nodes, fixed)
    handles = request.handles
    mirror = Mirror.of(lattice, goal.symmetry)
    if mirror is not None:
        x, fixed = mirror.symmetric(x, fixed)
        handles += tuple(mirror.handle(h) for h in handles)
    equations = handle_rows(lattice, handles) if handles else None
    held, face = np.zeros(len(x), bool), ""
    if goal.anchor == "far-side":
        held, face = held_face(
            lattice,
            x,
            fixed,
            rows=equations[0] if equations else None,
            points=np.array([h.at for h in handles]).reshape(-1, 3),
            targets=np.array([h.to for h in handles]).reshape(-1, 3),
            mirror_axis=None if mirror is None else mirror.axis,
        )
    fixed[held] = True
    if request.live and mirror is None and not handles:
        fixed |= ~live_reach(lattice, x, fixed)[:, None]
    coords = _coordinates(surface, ~fixed, mirror)
    start_level, top = _levels_to_run(surface, request)
    system = None
    if handles and coords.count:
        spare = surface.constraints(start_level, goal).own
        system = HandleSystem(lattice, handles, x, coords.reduce, spare, surface.size, equations)
    return Plan(
        surface=surface,
        goal=goal,
        options=request.options,
        nodes=x,
        coords=coords,
        held=held,
        face=face,
        mirror=mirror,
        system=system,
        start_level=start_level,
        top=top,
        near=request.near or request.live,
        live=request.live,
        t0=t0,
    )


def _start_nodes(
    surface: EmbeddedSurface, nodes: np.ndarray, fixed: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The nodes as an (n, 3) float array and ``fixed`` as (n, 3) bool, both the solve's
    own copies; a non-finite node or a model without volume is refused."""
    x = np.array(nodes, dtype=np.float64).reshape(surface.lattice.n_nodes, 3)
    fixed = np.asarray(fixed, dtype=bool)
    fixed = np.array(np.broadcast_to(fixed.reshape(-1, 1) if fixed.ndim == 1 else fixed, x.shape))
    if not np.all(np.isfinite(x)):
        raise IsochorError("A lattice node has a non-finite position.")
    if abs(surface.rest_volume) <= 0:
        raise IsochorError("The model encloses no volume, so there is no volume to preserve.")
    return x, fixed


def _coordinates(surface: EmbeddedSurface, free: np.ndarray, mirror: Mirror | None) -> Coordinates:
    """The solver's variables: the free coordinates, the high side tied to the low side
    under a mirror."""
    if mirror is None:
        return Coordinates(free, surface.center, surface.size)
    own, *ties = mirror.ties(free)
    return Coordinates(own, surface.center, surface.size, tuple(ties))


def _levels_to_run(surface: EmbeddedSurface, request: Request) -> tuple[int, int]:
    """The first level to solve on and the last: the full mesh, or the preview level of a
    live frame (where the solve starts no finer)."""
    n_levels = len(surface.levels)
    start_level = request.start_level
    if start_level is None:
        start_level = next(
            (
                k
                for k, m in enumerate(surface.levels)
                if m.n_faces >= request.options.start_triangles
            ),
            n_levels - 1,
        )
    start_level = start_level % n_levels
    top = n_levels - 1
    if request.live:
        top = live_level(surface, request.options.live_triangles)
        start_level = min(start_level, top)
    return start_level, top


def _start_record(plan: Plan) -> Progress:
    """The record of the start state, step 0: it comes before any work on the fine
    levels, so a window can redraw the user's edit at once. A solve whose free nodes
    cannot change the volume is refused here."""
    x, size = plan.nodes, plan.size
    first = plan.constraints(plan.start_level)
    c, dc = first.values_and_jacobian(x)
    if np.max(np.abs(plan.coords.reduce(dc[: first.own]))) * size < 1e-9:
        raise IsochorError(
            "The free nodes cannot change the model's volume: choose free nodes that influence "
            "the model, or pin fewer nodes."
        )
    return Progress(
        frozen_copy(x),
        plan.start_level,
        plan.n_levels,
        first.level.triangles,
        0,
        worst(c),
        plan.options.sigma0,
        0.0,
        plan.surface.springs.energy(x) / size**2,
        time.perf_counter() - plan.t0,
    )


@dataclass(frozen=True, eq=False)
class Objective:
    """What every level minimises: the springs' energy (with the fold guard's penalty),
    its gradient and Hessian, and the preconditioner's curvature the levels share."""

    energy_and_gradient: Callable[[np.ndarray], tuple[float, np.ndarray]]
    hessian: Callable[[np.ndarray], Any]
    curvatures: Curvatures


def _objective(plan: Plan) -> Objective:
    """The spring energy, with the fold guard's penalty when the goal asks for it. The
    guard's samples (points inside the model: a second on a big model the first time) are
    found here, after the first record."""
    surface, goal, size = plan.surface, plan.goal, plan.size
    springs = surface.springs
    margin = None
    if goal.fold_guard:
        guard = surface.fold_guard(FOLD_MARGIN * min(1.0, goal.target_ratio))
        margin = guard.margin

        def energy_grad(x):
            e, de = springs.energy_and_gradient(x)
            p, dp = guard.value_and_gradient(x)
            if p == 0.0:  # no sample within the margin: no penalty, no force
                return e, de
            return e + p * size**2, de + dp * size**2

        def hessian(x):
            h, near = springs.hessian(x), guard.gauss_newton(x)
            if sp.issparse(near):  # a dense local lattice: both sparse
                return h + near * size**2 if near.nnz else h
            if near.any():  # (zero where no sample is within the margin)
                h += near * size**2
            return h
    else:
        energy_grad, hessian = springs.energy_and_gradient, springs.hessian
    # The preconditioner's curvature, shared by the levels. A solve near the one before (a
    # drag's frame, its release) takes it from there while the nodes stayed near (a new
    # factorisation costs 50 ms at 8x8x8); any other solve takes its own, so that its
    # result never depends on what was solved before.
    curvatures = surface.shared(
        ("curvatures", plan.coords.key, margin),
        lambda: Curvatures(hessian, plan.coords, surface.lattice.shape),
        reuse=plan.near,
    )
    return Objective(energy_grad, hessian, curvatures)


def _starting_point(plan: Plan, objective: Objective) -> tuple[int, Iterate]:
    """The level to start on and the nodes and multipliers to start from: a warm start
    where the nodes already meet the goal, else the coarsest level with lambda 0 (and the
    symmetric start nudged)."""
    opts, x = plan.options, plan.nodes
    level = plan.start_level
    lam, sigma = np.zeros(plan.constraints(level).count), opts.sigma0
    warm = _warm_start(plan, objective.energy_and_gradient)
    if warm is not None:  # already at the volume: skip the coarse levels whose optimum differs
        level, lam = max(level, warm[0]), warm[1]
        if opts.precondition:  # the multipliers are right already: hold the volume firmly
            sigma = max(sigma, opts.sigma_warm)
    elif opts.symmetry_break > 0:
        # An exactly symmetric start stays on the symmetric manifold under any gradient
        # method and can end on a saddle (the torus stretch does). A tiny fixed-seed
        # nudge of the free coordinates lets the minimiser leave it; results stay
        # reproducible.
        coords = plan.coords
        nudge = np.random.default_rng(0).standard_normal(coords.count)
        x = x.copy()
        x[coords.free] += opts.symmetry_break * plan.size * nudge
        x = coords.tied(x)
    return level, Iterate(x, lam, sigma)


def _run_levels(
    plan: Plan, objective: Objective, first: int, start: Iterate
) -> Generator[Progress, None, Ending]:
    """Solve level after level from ``first``, each from the last one's nodes and
    multipliers, until a level meets the stopping test (see the module's docstring), the
    top level is solved, or a level does not converge."""
    opts = plan.options
    at, x_prev = start, plan.nodes
    stats: list[LevelStats] = []
    for k in range(first, plan.top + 1):
        t_level = time.perf_counter()
        cons = plan.constraints(k)
        al, x = yield from _solve_level(plan, objective, k, cons, at)
        at = Iterate(x, al.lam, al.sigma)
        change = float(np.max(np.abs(x - x_prev))) / plan.size
        estimate = None
        if k > 0:
            coarse = plan.constraints(k - 1)
            estimate = _discretisation_error(coarse.values(x), cons.values(x), coarse, cons)
        triangles = cons.level.triangles
        elapsed = time.perf_counter() - t_level
        stats.append(LevelStats(k, triangles, al.steps, elapsed, change, al.deviation, estimate))
        yield _level_record(plan, k, cons, al, x, change)
        if not al.converged:
            message = f"the volume constraint did not converge on level {k}"
            return _ending(at, stats, k, False, message)
        if k == plan.top:
            return _ending(at, stats, k, True)
        settled = change < opts.tol_nodes and estimate is not None and estimate <= opts.tol_volume
        if settled and _full_mesh_met(plan, x):
            return _ending(at, stats, k, True)
        x_prev = x
    return _ending(at, stats, plan.top, False)


def _solve_level(
    plan: Plan, objective: Objective, k: int, cons: Constraints, at: Iterate
) -> Generator[Progress, None, tuple[Any, np.ndarray]]:
    """Level ``k``'s augmented Lagrangian from ``at``, a record every inner step; returns
    its end and the nodes there."""
    problem = LevelProblem(
        at.nodes,
        plan.coords,
        objective.energy_and_gradient,
        cons.values_and_jacobian,
        plan.surface.center,
        plan.size,
        objective.curvatures,
    )
    run = augmented_lagrangian(problem, problem.to_y(at.nodes), at.lam, at.sigma, plan.options)

    def progress(it):
        return Progress(
            problem.nodes_of(it.y),
            k,
            plan.n_levels,
            cons.level.triangles,
            it.step,
            it.deviation,
            it.sigma,
            it.lam,
            it.energy,
            time.perf_counter() - plan.t0,
        )

    try:
        al = yield from relay(run, progress)
    except FloatingPointError:
        raise IsochorError(
            f"The solve broke down on level {k}: the lattice is folded so far that the "
            "volume has no usable gradient. Undo the last move or pin fewer nodes."
        ) from None
    return al, problem.to_nodes(al.y)


def _level_record(
    plan: Plan, k: int, cons: Constraints, al, x: np.ndarray, change: float
) -> Progress:
    """The record that closes level ``k``."""
    return Progress(
        frozen_copy(x),
        k,
        plan.n_levels,
        cons.level.triangles,
        al.steps,
        al.deviation,
        al.sigma,
        float(al.lam[0]),
        al.energy,
        time.perf_counter() - plan.t0,
        True,
        change,
    )


def _full_mesh_met(plan: Plan, x: np.ndarray) -> bool:
    """The stopping test's last question, asked once a level's nodes settled and its
    discretisation error is within the tolerance: does the top level meet the goal? (The
    full mesh's volume, and its folds for the result, are surveyed in one pass first.)"""
    if not plan.live:
        plan.surface.survey(x)
    c_full = plan.constraints(plan.top).values(x)
    return bool(np.max(np.abs(c_full)) <= plan.options.tol_volume)


def _ending(
    at: Iterate, stats: list[LevelStats], k: int, converged: bool, message: str = ""
) -> Ending:
    return Ending(at.nodes, tuple(stats), k, at.lam, at.sigma, converged, message)


def _result(plan: Plan, ending: Ending) -> SolveResult:
    """The result: measured on the full mesh, or on the preview level of a live frame."""
    return (preview if plan.live else outcome)(plan, ending)


#: a solve ``near`` the one before (not a live frame) on a full mesh of at least this many
#: triangles takes the level below the full mesh as the reference of
#: :func:`_warm_start`: evaluating the full mesh where the solve starts was a third of the
#: release solve at 1.38M triangles (its volume about 30 ms of 90), and a level with a
#: quarter of the triangles differs from it by about a quarter of what separates the two
#: levels below (Eq 29). Where that start is too coarse the stopping test, which asks the
#: full mesh, sends the solve on to the finer levels: the result is measured on the full
#: mesh as ever.
NEAR_REFERENCE_TRIANGLES = 200_000


def _reference_level(plan: Plan) -> int:
    """The level that stands for the full mesh where the warm start looks: the level
    below it for a solve ``near`` the one before on a big full mesh (see
    :data:`NEAR_REFERENCE_TRIANGLES`), else the top level."""
    top = plan.top
    big = top > 0 and plan.surface.levels[top].n_faces >= NEAR_REFERENCE_TRIANGLES
    return top - 1 if plan.near and not plan.live and big else top


def _warm_start(plan: Plan, energy_grad) -> tuple[int, np.ndarray] | None:
    """Where to start when the plan's nodes already meet the goal (a re-solve, a small edit).

    Returns the coarsest level whose own constraints at the nodes agree with the top
    level's to within the tolerance, and the least-squares Lagrange multipliers there, or
    None when the nodes do not meet the goal (then the solve starts at the coarsest level
    with lambda 0). A converged result restarted this way stops after one level and no
    steps, instead of re-deriving a different equilibrium from the coarse levels (the
    paper's Plate 6). With ``plan.near`` the goal need not be met: the level is the
    coarsest whose constraints differ from the reference's (:func:`_reference_level`) by
    at most the tolerance. Without it, the levels from ``plan.start_level`` up are asked
    first (:func:`_missed`): a drag that changed the volume is seen there, and the full
    mesh is not evaluated at all.
    """
    constraints, n, x, coords, opts = (
        plan.constraints,
        plan.top + 1,
        plan.nodes,
        plan.coords,
        plan.options,
    )
    near = plan.near
    if not near and _missed(constraints, n, x, opts, plan.start_level):
        return None
    last = _reference_level(plan) if near else n - 1
    c_full = constraints(last).values(x)
    if np.max(np.abs(c_full)) > opts.tol_volume and not near:
        return None

    def agrees(k):
        c = constraints(k).values(x)
        met = near or np.max(np.abs(c)) <= opts.volume_margin * opts.tol_volume
        return met and np.max(np.abs(c - c_full)) <= opts.tol_volume

    k = next(k for k in range(n) if k == last or agrees(k))
    _, dc = constraints(k).values_and_jacobian(x)
    _, de = energy_grad(x)
    de, dc = coords.reduce(de) / coords.size, coords.reduce(dc) * coords.size
    lam, *_ = np.linalg.lstsq(dc.T, de, rcond=None)
    return k, lam


#: a level's deviation proves the goal missed on the full mesh when it is beyond the
#: tolerance by more than this many times the level's discretisation error (Eq 29)
MISS_SAFETY = 4.0


def _missed(constraints, n, x, opts, first: int) -> bool:
    """True when a level below the full mesh shows that ``x`` misses the goal there too.

    Level k's constraints differ from the full mesh's by its discretisation error, which
    Eq 29 estimates from levels k-1 and k (the deviations' difference over the triangle
    ratio minus one). When ``|c_k|`` exceeds the tolerance by more than ``MISS_SAFETY`` of
    those estimates, the full mesh misses the goal as well. The levels are asked from
    ``first`` (at least the second level) up to the one below the full mesh, and the answer
    comes from the first that proves it; False means not proven (the full mesh decides).
    Handles' constraints are the same on every level, so their misses show on the first.
    """
    below = max(first, 1) - 1
    if below + 1 >= n - 1:
        return False
    previous = constraints(below)
    c_prev = previous.values(x)
    for k in range(below + 1, n - 1):
        cons = constraints(k)
        c = cons.values(x)
        error = _discretisation_error(c_prev, c, previous, cons)
        if np.max(np.abs(c)) > opts.tol_volume + MISS_SAFETY * error:
            return True
        previous, c_prev = cons, c
    return False


def _discretisation_error(c_coarse, c_fine, coarse, fine) -> float:
    """Eq 29 on the constraints: the error of the ``fine`` level's constraint values
    ``c_fine``, estimated from the next ``coarse`` level's ``c_coarse`` at the same nodes
    (their largest difference over the measured triangle ratio minus one)."""
    ratio = fine.level.triangles / coarse.level.triangles
    return float(np.max(np.abs(c_coarse - c_fine))) / max(ratio - 1.0, 1e-9)
