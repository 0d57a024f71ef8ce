"""The local release: a small edit re-solved where it reaches, at full resolution.

A node of a local basis (B-spline, Catmull-Rom, ...) moves the points of the 4 x 4 x 4
cells around it only. When a drag ends, or a Session solves again after a small edit, the
edit differs from the last result measured on the full mesh (remembered on the surface,
:class:`Memory`) in a few nodes only. :func:`release` then

1. frees only the nodes whose support meets the changed nodes' (within :data:`REACH` node
   steps of them) and puts every other free node back where the last result had it;
2. solves those at full resolution on the part of the full mesh they move (the faces with
   a corner in a cell they reach): the volume is the remembered volume of the rest of the
   mesh plus that part's, exactly the full mesh's (:class:`Touched`);
3. re-measures det J only at the fold check's samples in those cells and takes the rest
   from the last result (:meth:`isochor.core.goal.folds.FoldCheck.refresh`);
4. asks whether the whole solve would land elsewhere: one step of the whole problem's
   optimality conditions (all free nodes, the full mesh's volume gradient, the shared
   curvature) from the local result, :func:`whole_step`. The spring network is one
   elastic body, so an edit moves nodes far from it a little as well; where that step
   exceeds ``tol_nodes`` of the size, or the region cannot meet the volume, the local
   result is dropped and the whole solve runs as before.

The same step taken at the edit's start, over the nodes outside the region, predicts it:
when the whole problem would move them by more than the tolerance, the local solve is not
tried at all.

It does not apply (the whole solve runs) to a Bernstein lattice, whose every node moves
every point; to a goal other than the total volume (per body, the centroid, handles,
symmetry); to a model of several bodies; to a live frame; and where no converged result
of the same free coordinates is remembered.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..goal.constraints import Constraints, Level
from ..goal.spec import Goal
from ..mesh import TriMesh
from .generators import relay
from .records import LevelStats, Progress, SolveResult
from .solver import Coordinates, Curvatures, LevelProblem, SolverOptions, augmented_lagrangian
from .surface import EmbeddedSurface

#: nodes i and j of a 4-wide window basis move a common point when |i - j| <= 3 on every
#: axis: the nodes within this many steps of a changed one are the local solve's
REACH = 3
#: the key of the remembered result on the surface
MEMORY = "local release"


@dataclass(frozen=True, eq=False)
class Memory:
    """The last result measured on the full mesh: its nodes, the full level's volume there,
    det J at the fold check's samples there, its multipliers and free coordinates."""

    nodes: np.ndarray
    volume: float
    dets: np.ndarray
    lam: np.ndarray
    free: bytes  #: the free coordinates' mask, as bytes


@dataclass(frozen=True, eq=False)
class Released:
    """What a local release ends with (the whole solve's ``Ending``, in its terms)."""

    nodes: np.ndarray
    stats: tuple[LevelStats, ...]
    lam: np.ndarray
    sigma: float
    region: int  #: free nodes solved
    triangles: int  #: triangles re-measured


def applies(surface: EmbeddedSurface, goal: Goal, mirror: Any, system: Any) -> str:
    """Why the local release cannot run on this problem, or "" when it can."""
    if not surface.lattice.local:
        return "a Bernstein lattice: every node moves every point"
    if goal.preserve == "per-body" or goal.keep_centroid:
        return "the goal holds more than the total volume"
    if mirror is not None or system is not None:
        return "symmetry or handles tie the nodes together"
    if surface.body_count > 1:
        return "the model has several bodies"
    return ""


def remember(surface: EmbeddedSurface, result: SolveResult, free: np.ndarray, lam) -> None:
    """Keep ``result`` as the next local release's base when it is a converged result
    measured on the full mesh (its volume and det J are then at hand, memoised)."""
    if not surface.lattice.local or result.preview or not result.converged:
        surface.remember(MEMORY, None)
        return
    x = np.asarray(result.nodes)
    full = surface.level(-1)
    verts, inside = surface.fold_check.determinants(x)
    dets = np.concatenate([verts, inside])
    dets.flags.writeable = False
    memory = Memory(x, full.volume(x), dets, np.array(lam, dtype=np.float64), free.tobytes())
    surface.remember(MEMORY, memory)


def dilate(mask: np.ndarray, low: int, high: int) -> np.ndarray:
    """``out[i] = any(mask[i - low : i + high + 1])`` along every axis of a 3-d bool grid."""
    out = mask
    for axis in range(3):
        n = out.shape[axis]
        moved = np.moveaxis(out, axis, 0)
        grown = np.zeros_like(moved)
        for d in range(-high, low + 1):  # out[i] |= mask[i - d]
            lo, hi = max(0, d), min(n, n + d)
            if lo < hi:
                grown[lo:hi] |= moved[lo - d : hi - d]
        out = np.moveaxis(grown, 0, axis)
    return out


def cells_reached(shape: tuple[int, int, int], nodes: np.ndarray) -> np.ndarray:
    """(l+2, m+2, n+2) bool: the cells (-1 to the node count on each axis, shifted by one)
    a point of which moves with one of the ``nodes`` (n,) bool. A point in cell c of an
    axis moves with the nodes c-1 to c+2 there, clamped to the axis."""
    out = nodes.reshape(shape)
    for axis, n in enumerate(shape):
        rows = [np.clip(np.arange(q - 2, q + 2), 0, n - 1) for q in range(n + 2)]
        out = np.stack([out.take(r, axis=axis).any(axis=axis) for r in rows], axis=axis)
    return out


def point_cells(shape: tuple[int, int, int], uvw_t: np.ndarray) -> np.ndarray:
    """(p,) each point's cell in the grid of :func:`cells_reached`, flat."""
    index = []
    for a, c in enumerate(shape):
        t = np.floor(uvw_t[a] * max(c - 1, 1))
        index.append(np.clip(t, -1, c).astype(np.intp) + 1)
    return np.ravel_multi_index(tuple(index), tuple(s + 2 for s in shape))


class Touched:
    """The full mesh's volume where only the faces in the reached cells move: the part of
    them re-measured, the rest remembered. Stands for the full :class:`Level` in the
    goal's :class:`~isochor.core.goal.constraints.Constraints` (the same rest volume, so the
    same target and scale)."""

    def __init__(self, surface: EmbeddedSurface, faces: np.ndarray, base: Memory) -> None:
        full = surface.full
        used, local_faces = np.unique(full.faces[faces], return_inverse=True)
        part = TriMesh(full.vertices[used], local_faces.reshape(-1, 3).astype(np.int64))
        self.part = Level(surface.lattice, part, surface.center)
        self.center = surface.center
        self.rest_volume = surface.level(-1).rest_volume
        self.triangles = surface.full.n_faces  #: the level it stands for: the full mesh
        self.measured = part.n_faces  #: triangles re-measured
        #: the volume of the faces that do not move, from the remembered result
        self.rest_part = base.volume - self.part.volume(base.nodes)

    def volume(self, nodes: np.ndarray) -> float:
        return self.rest_part + self.part.volume(nodes)

    def volume_and_gradient(self, nodes: np.ndarray) -> tuple[float, np.ndarray]:
        v, dv = self.part.volume_and_gradient(nodes)
        return self.rest_part + v, dv


def whole_step(
    surface: EmbeddedSurface,
    goal: Goal,
    nodes: np.ndarray,
    coords: Coordinates,
    energy_grad: Callable,
    curvatures: Curvatures,
    lam: np.ndarray,
) -> np.ndarray:
    """(count,) the step towards the whole problem's optimum from ``nodes``, in object
    sizes: ``H d + J^T m = -(dE - lam J)``, ``J d = -c`` over all free coordinates, with the
    shared curvature for ``H`` and the full mesh's volume gradient for ``J`` (first order:
    the distance to the whole solve's nodes, to within the curvature's error)."""
    cons = surface.constraints(-1, goal)
    problem = LevelProblem(
        nodes, coords, energy_grad, cons.values_and_jacobian, surface.center, surface.size
    )
    y = problem.to_y(nodes)
    _, de, c, dc = problem.terms(y)
    g = de - float(lam[0]) * dc[0]
    curvature = curvatures.at(y, lambda: nodes)
    if not curvature.ok:
        return np.full(coords.count, np.inf)
    both = curvature.solve(np.stack([g, dc[0]], axis=1))
    a, b = both[:, 0], both[:, 1]
    jb = float(dc[0] @ b)
    if not abs(jb) > 0:
        return np.full(coords.count, np.inf)
    m = (float(c[0]) - float(dc[0] @ a)) / jb
    return -a - b * m


def release(
    surface: EmbeddedSurface,
    goal: Goal,
    opts: SolverOptions,
    nodes: np.ndarray,
    coords: Coordinates,
    energy_grad: Callable,
    hessian: Callable,
    curvatures: Curvatures,
    t0: float,
) -> Generator[Progress, None, Released | None]:
    """The local release of the edit ``nodes`` (see the module); None where it does not
    apply or cannot meet the tolerance (the whole solve then runs from ``nodes``). The
    caller checks :func:`applies` first. Yields the local solve's records (on the full
    mesh's level)."""
    memory: Memory | None = surface.recall(MEMORY)
    lattice = surface.lattice
    if memory is None or memory.free != coords.free.tobytes() or len(coords.dst):
        return None
    x = np.array(nodes, dtype=np.float64)
    changed = np.any(x != memory.nodes, axis=1)
    if not changed.any():
        return None
    fixed_nodes = ~coords.free.any(axis=1)
    near = dilate(changed.reshape(lattice.shape), REACH, REACH).ravel()
    region = near & ~fixed_nodes
    far = coords.free & ~region[:, None]
    x[far] = memory.nodes[far]  # the free nodes out of reach go back to the last result
    changed = np.any(x != memory.nodes, axis=1)
    # predicted: would the whole problem move the nodes out of reach beyond the tolerance?
    step = whole_step(surface, goal, x, coords, energy_grad, curvatures, memory.lam)
    outside = far[coords.free]
    if outside.any() and np.max(np.abs(step[outside])) > opts.tol_nodes:
        return None
    moving = changed | region
    cells = cells_reached(lattice.shape, moving).ravel()
    full = surface.level(-1)
    faces = np.flatnonzero(
        cells[point_cells(lattice.shape, full.parameters())][surface.full.faces].any(axis=1)
    )
    touched = Touched(surface, faces, memory)
    cons = Constraints(touched, goal, None, surface.rest_volume, surface.size)  # type: ignore[arg-type]
    local = Coordinates(coords.free & region[:, None], surface.center, surface.size)
    if not local.count:
        return None
    curvature = Curvatures(hessian, local, lattice.shape)
    problem = LevelProblem(
        x, local, energy_grad, cons.values_and_jacobian, surface.center, surface.size, curvature
    )
    sigma = max(opts.sigma0, opts.sigma_warm) if opts.precondition else opts.sigma0
    top, n_levels = len(surface.levels) - 1, len(surface.levels)
    t_level = time.perf_counter()
    run = augmented_lagrangian(problem, problem.to_y(x), memory.lam, sigma, opts)

    def progress(it):
        return Progress(
            problem.nodes_of(it.y), top, n_levels, touched.triangles, it.step, it.deviation,
            it.sigma, it.lam, it.energy, time.perf_counter() - t0,
        )  # fmt: skip

    try:
        al = yield from relay(run, progress)
    except FloatingPointError:
        return None
    if not al.converged:
        return None
    result = problem.to_nodes(al.y)
    # confirmed: from the local result, the whole problem's step stays within the tolerance
    step = whole_step(surface, goal, result, coords, energy_grad, curvatures, al.lam)
    if not np.max(np.abs(step)) <= opts.tol_nodes:
        return None
    # det J at the result: the remembered one but in the reached cells (the full mesh's
    # volume there is known: the confirming step measured it)
    check = surface.fold_check
    rows = np.flatnonzero(cells[point_cells(lattice.shape, check.parameters)])
    check.refresh(result, memory.dets, rows)
    change = float(np.max(np.abs(result - x))) / surface.size
    stats = (
        LevelStats(top, touched.triangles, al.steps, time.perf_counter() - t_level, change,
                   al.deviation, None),
    )  # fmt: skip
    return Released(result, stats, al.lam, al.sigma, int(region.sum()), touched.measured)
