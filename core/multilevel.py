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
from collections.abc import Generator, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .errors import IsochorError
from .generators import relay
from .lattice import Lattice, PointBasis
from .mesh import TriMesh
from .records import LevelStats, Progress, SolveResult, frozen_copy
from .solver import LevelProblem, SolverOptions, augmented_lagrangian
from .springs import SpringNetwork
from .volume import VolumeOperator, signed_volume


class _Level:
    """What one pyramid level needs for fast evaluations, computed once."""

    def __init__(self, lattice: Lattice, mesh: TriMesh, center: np.ndarray) -> None:
        self.mesh = mesh
        self.triangles = mesh.n_faces
        self.basis: PointBasis = lattice.basis(mesh.vertices)
        self.volume_op = VolumeOperator(mesh.faces, mesh.n_vertices)
        self.center = center
        self._last: tuple[bytes | None, float] = (None, 0.0)
        self.rest_volume = self.volume(lattice.rest_nodes)

    def volume(self, nodes: np.ndarray) -> float:
        # One-entry memo: the stopping test and the result ask the full mesh for the
        # volume of the same nodes, and on a big mesh that is the costliest call there is.
        key = nodes.tobytes()
        if self._last[0] != key:
            self._last = (key, self.volume_op(self.basis.apply(nodes), self.center))
        return self._last[1]

    def volume_and_gradient(self, nodes: np.ndarray) -> tuple[float, np.ndarray]:
        v, dv_dp = self.volume_op.value_and_gradient(self.basis.apply(nodes), self.center)
        return v, self.basis.apply_transpose(dv_dp)


@dataclass(eq=False)
class EmbeddedSurface:
    """A surface pyramid embedded in a lattice, with per-level caches.

    Build one per document and reuse it for every solve: the bases of the levels are
    computed the first time a level is used and kept.

    Parameters
    ----------
    lattice : the FFD lattice; its rest nodes define X_org
    levels : coarse to fine versions of one closed surface; the last is full resolution
    """

    lattice: Lattice
    levels: Sequence[TriMesh]
    _cache: dict[int, _Level] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not self.levels:
            raise IsochorError("A surface needs at least one mesh level.")
        self.levels = tuple(self.levels)

    @cached_property
    def springs(self) -> SpringNetwork:
        return SpringNetwork.for_lattice(self.lattice.shape, self.lattice.rest_nodes)

    @property
    def full(self) -> TriMesh:
        return self.levels[-1]

    @cached_property
    def size(self) -> float:
        """Object size: the largest bounding-box extent of the full mesh."""
        return self.full.size

    @cached_property
    def center(self) -> np.ndarray:
        """Centre of the full mesh's bounding box."""
        return self.full.center

    def level(self, k: int) -> _Level:
        k = k % len(self.levels)
        if k not in self._cache:
            self._cache[k] = _Level(self.lattice, self.levels[k], self.center)
        return self._cache[k]

    @cached_property
    def rest_volume(self) -> float:
        """Volume of the full-resolution mesh as given (the FFD of the rest lattice is the
        identity), computed without building the full level's basis."""
        return signed_volume(self.full.vertices, self.full.faces)

    def volume(self, nodes: np.ndarray, level: int = -1) -> float:
        return self.level(level).volume(np.asarray(nodes, dtype=np.float64))

    def deform(self, nodes: np.ndarray, level: int = -1) -> np.ndarray:
        """(m, 3) vertices of a level deformed by ``nodes``."""
        return self.level(level).basis.apply(np.asarray(nodes, dtype=np.float64))


def solve(
    surface: EmbeddedSurface,
    nodes: np.ndarray,
    fixed: np.ndarray,
    *,
    target_ratio: float = 1.0,
    options: SolverOptions | None = None,
    start_level: int | None = None,
) -> Generator[Progress, None, SolveResult]:
    """Move the free nodes to the least spring energy at the target volume.

    Parameters
    ----------
    surface : the embedded surface pyramid
    nodes : (n, 3) current node positions (moved nodes where the user put them)
    fixed : (n,) bool, True for pinned and moved nodes
    target_ratio : target volume over the rest volume (1 preserves it)
    start_level : first pyramid level to solve on; by default the coarsest level with at
        least ``options.start_triangles`` triangles

    Yields
    ------
    Progress: one at once with the start state (step 0), then every inner step and at
    each level's end.

    Returns
    -------
    SolveResult, with the volumes measured on the full-resolution mesh.
    """
    opts = options or SolverOptions()
    t0 = time.perf_counter()
    lattice = surface.lattice
    x = np.array(nodes, dtype=np.float64).reshape(lattice.n_nodes, 3)
    fixed = np.asarray(fixed, dtype=bool).reshape(lattice.n_nodes)
    free = ~fixed
    if not np.all(np.isfinite(x)):
        raise IsochorError("A lattice node has a non-finite position.")
    if not (0.0 < target_ratio < np.inf):
        raise IsochorError(f"The target volume ratio must be positive, got {target_ratio}.")
    v_ref = abs(surface.rest_volume)
    if v_ref <= 0:
        raise IsochorError("The model encloses no volume, so there is no volume to preserve.")
    size, center = surface.size, surface.center
    n_levels = len(surface.levels)
    if start_level is None:
        start_level = next(
            (k for k, m in enumerate(surface.levels) if m.n_faces >= opts.start_triangles),
            n_levels - 1,
        )
    start_level = start_level % n_levels

    def result(x, stats, terminal, lam, sigma, converged, message=""):
        full = surface.level(-1)
        v_final = full.volume(x)
        target = target_ratio * full.rest_volume
        energy = surface.springs.energy(x) / size**2
        if not (np.all(np.isfinite(x)) and np.isfinite(v_final) and np.isfinite(energy)):
            # never a result made of overflowed numbers, whatever the caller does with it
            raise IsochorError(
                "The solve broke down: its numbers overflowed. The moves or the target "
                "volume are too extreme for this lattice."
            )
        err = (v_final - target) / v_ref
        ok = converged and abs(err) <= opts.tol_volume
        if converged and not ok:
            message = message or f"volume error {err:.2e} on the full mesh exceeds the tolerance"
        return SolveResult(
            frozen_copy(x),
            tuple(stats),
            terminal,
            full.rest_volume,
            target,
            v_final,
            err,
            energy,
            int(free.sum()),
            time.perf_counter() - t0,
            ok,
            message,
            lam,
            sigma,
        )

    if not free.any():
        return result(x, [], -1, 0.0, 0.0, True, "no free node: nothing to solve")

    first = surface.level(start_level)
    v, dv = first.volume_and_gradient(x)
    if np.max(np.abs(dv[free])) * size / v_ref < 1e-9:
        raise IsochorError(
            "The free nodes cannot change the model's volume: choose free nodes that influence "
            "the model, or pin fewer nodes."
        )
    # The first record comes before any work on the fine levels, so a window can redraw
    # the user's edit at once.
    yield Progress(
        frozen_copy(x),
        start_level,
        n_levels,
        first.triangles,
        0,
        (v - target_ratio * first.rest_volume) / v_ref,
        opts.sigma0,
        0.0,
        surface.springs.energy(x) / size**2,
        time.perf_counter() - t0,
    )

    lam, sigma = 0.0, opts.sigma0
    warm = _warm_start(surface, x, free, target_ratio, v_ref, opts)
    x_prev = x
    if warm is not None:  # already at the volume: skip the coarse levels whose optimum differs
        start_level, lam = max(start_level, warm[0]), warm[1]
    elif opts.symmetry_break > 0:
        # An exactly symmetric start stays on the symmetric manifold under any gradient
        # method and can end on a saddle (the torus stretch does). A tiny fixed-seed
        # nudge of the free nodes lets the minimiser leave it; results stay reproducible.
        nudge = np.random.default_rng(0).standard_normal((int(free.sum()), 3))
        x = x.copy()
        x[free] += opts.symmetry_break * size * nudge
    stats: list[LevelStats] = []
    terminal = n_levels - 1
    converged_level = False
    for k in range(start_level, n_levels):
        t_level = time.perf_counter()
        level = surface.level(k)
        problem = LevelProblem(
            x,
            free,
            surface.springs.energy_and_gradient,
            level.volume_and_gradient,
            center,
            size,
            target_ratio * level.rest_volume,
            v_ref,
        )
        run = augmented_lagrangian(problem, problem.to_y(x), lam, sigma, opts)

        def progress(it, k=k, level=level, problem=problem):
            return Progress(
                frozen_copy(problem.to_nodes(it.y)),
                k,
                n_levels,
                level.triangles,
                it.step,
                it.deviation,
                it.sigma,
                it.lam,
                it.energy,
                time.perf_counter() - t0,
            )

        try:
            al = yield from relay(run, progress)
        except FloatingPointError:
            raise IsochorError(
                f"The solve broke down on level {k}: the lattice is folded so far that the "
                "volume has no usable gradient. Undo the last move or pin fewer nodes."
            ) from None
        x = problem.to_nodes(al.y)
        lam, sigma = al.lam, al.sigma
        change = float(np.max(np.abs(x - x_prev))) / size
        estimate = None
        if k > 0:  # Eq 29 on the deviation, between this level and the next coarser one
            prev = surface.level(k - 1)
            g_prev = (prev.volume(x) - target_ratio * prev.rest_volume) / v_ref
            ratio = level.triangles / prev.triangles
            estimate = abs(g_prev - al.deviation) / max(ratio - 1.0, 1e-9)
        stats.append(
            LevelStats(
                k,
                level.triangles,
                al.steps,
                time.perf_counter() - t_level,
                change,
                al.deviation,
                estimate,
            )
        )
        yield Progress(
            frozen_copy(x),
            k,
            n_levels,
            level.triangles,
            al.steps,
            al.deviation,
            sigma,
            lam,
            al.energy,
            time.perf_counter() - t0,
            True,
            change,
        )
        if not al.converged:
            return result(
                x,
                stats,
                k,
                lam,
                sigma,
                False,
                f"the volume constraint did not converge on level {k}",
            )
        if k == n_levels - 1:
            converged_level = True
            break
        if change < opts.tol_nodes and estimate is not None and estimate <= opts.tol_volume:
            full = surface.level(-1)
            g_full = (full.volume(x) - target_ratio * full.rest_volume) / v_ref
            if abs(g_full) <= opts.tol_volume:
                terminal, converged_level = k, True
                break
        x_prev = x
    return result(x, stats, terminal, lam, sigma, converged_level)


def _warm_start(surface, x, free, target_ratio, v_ref, opts) -> tuple[int, float] | None:
    """Where to start when ``x`` already has the target volume (a re-solve, a small edit).

    Returns the coarsest level whose own deviation at ``x`` agrees with the full mesh's to
    within the tolerance, and the least-squares Lagrange multiplier there, or None when ``x``
    is not at the target volume (then the solve starts at the coarsest level with lambda 0).
    A converged result restarted this way stops after one level and no steps, instead of
    re-deriving a different equilibrium from the coarse levels (the paper's Plate 6).
    """

    def deviation(k):
        lvl = surface.level(k)
        return (lvl.volume(x) - target_ratio * lvl.rest_volume) / v_ref

    g_full = deviation(-1)
    if abs(g_full) > opts.tol_volume:
        return None
    n = len(surface.levels)
    k = next(
        k
        for k in range(n)
        if k == n - 1
        or (
            abs(deviation(k)) <= opts.volume_margin * opts.tol_volume
            and abs(deviation(k) - g_full) <= opts.tol_volume
        )
    )
    _, dv = surface.level(k).volume_and_gradient(x)
    _, de = surface.springs.energy_and_gradient(x)
    de, dv = de[free].ravel() / surface.size, dv[free].ravel() * surface.size / v_ref
    return k, float(de @ dv) / float(dv @ dv)
