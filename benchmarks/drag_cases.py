"""What the Display rate section measures (issue 9): a drag's frames, the solve at its end,
the first progress record, the solver's own work per step, the dense lattice.

Each function takes a built :class:`isochor.core.scenario.problem.Problem` and returns timings in
seconds; :mod:`benchmarks.display` turns them into rows with targets.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from benchmarks.scale import ARMADILLO
from benchmarks.timing import Timing
from isochor.core.goal.constraints import Constraints
from isochor.core.goal.folds import FoldGuard
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build, default_lattice_shape, load_model
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import EmbeddedSurface

#: a drag frame moves the dragged node by this much of the lattice size
FRAME_MOVE = 0.003
BIG = "armadillo_1383k.ply"


def big_armadillo(models: Path) -> Path | None:
    """The 1.38M-triangle armadillo (one midpoint subdivision of the 346k one, every
    triangle into four), made once into the cache folder; None without the 346k one."""
    src = models / ARMADILLO
    if not src.is_file():
        return None
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "isochor"
    out = cache / BIG
    if not out.is_file():
        import trimesh

        mesh = trimesh.load(src, process=False)
        v, f = trimesh.remesh.subdivide(mesh.vertices, mesh.faces)
        cache.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(".tmp.ply")
        trimesh.Trimesh(v, f, process=False).export(tmp)
        tmp.replace(out)
    return out


def model_problem(path: Path):
    """The model file's problem on its default lattice, nothing moved."""
    model = load_model(path)
    shape = default_lattice_shape(model.levels[-1])
    return build(Scenario({"path": str(path)}, lattice_nodes=shape), model=model)


def dragged(problem) -> tuple[np.ndarray, np.ndarray, int]:
    """Nodes, fixed coordinates and the dragged row: the problem's first moved node, or
    its top corner moved by a tenth of the lattice size."""
    lattice = problem.surface.lattice
    x, fixed = problem.nodes.copy(), problem.fixed.copy()
    moved = np.flatnonzero(fixed.all(axis=1) & np.any(x != lattice.rest_nodes, axis=1))
    r = int(moved[0]) if len(moved) else lattice.index(*(s - 1 for s in lattice.shape))
    fixed[r] = True
    if not len(moved):
        x[r] += 0.1 * lattice.size
    return x, fixed, r


@dataclass(frozen=True)
class Drag:
    """A drag measured as the window runs it."""

    frames: Timing  #: each frame's live solve (``solve(..., live=True)``)
    release: Timing  #: the full solve when the drag ends, from the last frame
    frames_ok: bool  #: every frame met the volume on its preview level
    release_ok: bool  #: every release solve converged (measured on the full mesh)
    preview_level: int
    preview_triangles: int


def drag(problem, repeats: int, frames: int = 10, options=None) -> Drag:
    """``repeats`` drags: each ``frames`` live frames (the dragged node moved by
    :data:`FRAME_MOVE` of the size, re-solved from the frame before) and the solve on
    release. Every drag starts from the same solved edit, as when the user undoes a drag
    and makes it again, a little further each time (1% more per repeat): the same drag
    would end where the one before did, and the full mesh's volume there would come from
    the last solve's memo instead of being measured. The first drag (which sets the
    levels up) is not counted."""
    surface, opts = problem.surface, options or problem.options
    size = surface.lattice.size
    x, fixed, r = dragged(problem)
    start = run_to_end(problem.solve(x, fixed, options=opts))
    frame_t, release_t, frames_ok, release_ok, level = [], [], True, True, 0
    for rep in range(repeats + 1):
        result = start  # every repeat is the same drag, from the same solved edit
        for _ in range(frames):
            x = np.array(result.nodes)
            x[r] += FRAME_MOVE * size * (1.0 + 0.01 * rep)
            t0 = time.perf_counter()
            result = run_to_end(problem.solve(x, fixed, options=opts, live=True))
            if rep:
                frame_t.append(time.perf_counter() - t0)
                frames_ok &= bool(result.converged)
            level = result.terminal_level
        t0 = time.perf_counter()
        result = run_to_end(problem.solve(np.array(result.nodes), fixed, options=opts, near=True))
        if rep:
            release_t.append(time.perf_counter() - t0)
            release_ok &= bool(result.converged)
    tri = surface.levels[level].n_faces
    return Drag(Timing(tuple(frame_t)), Timing(tuple(release_t)), frames_ok, release_ok, level, tri)


def first_record(problem) -> tuple[float, float]:
    """Seconds to the first progress record after a drag: on the surface as the loader
    leaves it (the first solve after opening: ``build`` and nothing else) and after
    :meth:`EmbeddedSurface.prepare` (what the window's loading thread does)."""
    fresh = EmbeddedSurface(problem.surface.lattice, problem.surface.levels)
    x, fixed, _ = dragged(problem)
    out = []
    for surface in (fresh, EmbeddedSurface(fresh.lattice, fresh.levels).prepare()):
        t0 = time.perf_counter()
        run = replace(problem, surface=surface).solve(x, fixed)
        next(run)
        out.append(time.perf_counter() - t0)
        run.close()
    return out[0], out[1]


class _Clock:
    """Adds up the time spent in the wrapped methods while installed (a call within
    another wrapped call counts once, in the outer one)."""

    def __init__(self, *methods) -> None:
        self.methods, self.seconds, self.saved, self.depth = methods, 0.0, [], 0

    def __enter__(self):
        for cls, name in self.methods:
            fn = getattr(cls, name)
            self.saved.append((cls, name, fn))
            setattr(cls, name, self._timed(fn))
        return self

    def _timed(self, fn):
        def timed(*args, **kwargs):
            self.depth += 1
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.depth -= 1
                if not self.depth:
                    self.seconds += time.perf_counter() - t0

        return timed

    def __exit__(self, *exc) -> None:
        for cls, name, fn in self.saved:
            setattr(cls, name, fn)


def step_overhead(problem, repeats: int, options=None) -> Timing:
    """The solver's own work per inner step (seconds): the levels' time minus the time in
    the evaluations (the constraints and their gradients on the level meshes, the fold
    guard's penalty and its det J, also where the preconditioner asks for it), over the
    steps: the L-BFGS recursion, the line search, the preconditioner, the spring energy
    and the glue. Measured on the problem's fresh solve, ``repeats`` times."""
    x, fixed, _ = dragged(problem)
    opts = options or problem.options
    watched = (
        (Constraints, "values"),
        (Constraints, "values_and_jacobian"),
        (FoldGuard, "value_and_gradient"),
        (FoldGuard, "_evaluate"),
    )
    run_to_end(problem.solve(x, fixed, options=opts))  # set-up
    per_step = []
    for _ in range(repeats):
        with _Clock(*watched) as clock:
            result = run_to_end(problem.solve(x, fixed, options=opts))
        steps = sum(s.steps for s in result.levels)
        level_s = sum(s.time_s for s in result.levels)
        per_step.append(max(level_s - clock.seconds, 0.0) / max(steps, 1))
    return Timing(tuple(per_step))


def dense_problem(problem, n: int = 8):
    """The problem's model on an n x n x n lattice, its bottom layer pinned, nothing moved
    (what :func:`drag` and :func:`dense_drag` take)."""
    scenario = problem.scenario.with_(lattice_nodes=(n, n, n), moves=(), pins=(), axis_pins=())
    dense = build(scenario, model=problem.model)
    fixed = dense.fixed.copy()
    fixed[dense.surface.lattice.grid_parameters()[:, 1] == 0] = True
    return replace(dense, fixed=fixed)


def dense_drag(problem) -> tuple[float, bool, str]:
    """8x8x8 on the model, bottom layer pinned, one top corner dragged by 15% of the size
    (one solve): seconds, converged, message."""
    dense = dense_problem(problem)
    lattice = dense.surface.lattice
    x, fixed = dense.nodes.copy(), dense.fixed.copy()
    r = lattice.index(7, 7, 7)
    x[r] += 0.15 * lattice.size
    fixed[r] = True
    t0 = time.perf_counter()
    result = run_to_end(dense.solve(x, fixed))
    return time.perf_counter() - t0, bool(result.converged), result.message


def plain(problem):
    """The problem's solver options as before issue 9: no preconditioner (a scaled identity
    starts each L-BFGS run)."""
    return replace(problem.options, precondition=False)
