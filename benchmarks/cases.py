"""The paper's examples made ready to solve, and one solve drained with every record kept."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from isochor.core.lattice import Lattice
from isochor.core.mesh import TriMesh
from isochor.core.scenario.problem import Problem
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import EmbeddedSurface, Progress, SolveResult
from isochor.core.solve.solver import SolverOptions

#: the examples of the paper's Table 1 that ship with Isochor (the cow needs a model file)
EXAMPLES = ("torus-compression", "torus-stretch", "club-compression")
TITLES = {
    "torus-compression": "Torus compression",
    "torus-stretch": "Torus stretch",
    "club-compression": "Club partial compression",
    "cow-bend": "Cow bending",
}
#: the paper's convergence figure of each example
FIGURES = {"torus-compression": 5, "torus-stretch": 6, "club-compression": 7, "cow-bend": 8}


@dataclass
class Run:
    """One drained solve."""

    result: SolveResult
    wall: float  #: seconds from the first next() to the result
    first_record: float  #: seconds from the first next() to the first Progress record
    times: np.ndarray  #: (r,) Progress.elapsed of every record, seconds
    nodes: np.ndarray  #: (r, n, 3) node positions of every record
    levels: np.ndarray  #: (r,) level of every record


def run_solve(
    problem: Problem,
    nodes: np.ndarray,
    fixed: np.ndarray,
    options: SolverOptions,
    **kwargs,
) -> Run:
    """Drain the problem's solve (:meth:`Problem.solve`, keyword arguments passed on) and
    keep every record.

    Parameters
    ----------
    problem : the problem; its surface's levels are set up by the first solve on it
    nodes : (n, 3) start node positions
    fixed : (n,) bool, pinned and moved nodes
    options : the solver's options
    """
    records: list[Progress] = []
    first: list[float] = []

    def keep(record: Progress) -> None:
        if not first:
            first.append(time.perf_counter() - t0)
        records.append(record)

    gen = problem.solve(nodes, fixed, options=options, **kwargs)
    t0 = time.perf_counter()
    result = run_to_end(gen, keep)
    wall = time.perf_counter() - t0
    n = len(nodes)
    return Run(
        result,
        wall,
        first[0] if first else wall,
        np.array([r.elapsed for r in records]),
        np.array([r.nodes for r in records]).reshape(-1, n, 3),
        np.array([r.level for r in records], dtype=int),
    )


def node_error(run: Run, size: float) -> np.ndarray:
    """(r,) largest node distance from the run's final nodes at every record, / ``size``."""
    if not len(run.nodes):
        return np.zeros(0)
    d = np.linalg.norm(run.nodes - run.result.nodes[None], axis=2)
    return d.max(axis=1) / size


def median_run(runs: Sequence[Run]) -> Run:
    """The run with the median wall time (the upper one of an even count)."""
    order = np.argsort([r.wall for r in runs])
    return runs[int(order[len(order) // 2])]


@dataclass
class Case:
    """A paper example made ready to solve: the problem (its lattice and goal), the
    pyramid it is solved on, the edit."""

    key: str
    problem: Problem
    levels: list[TriMesh]  #: the pyramid the case solves on (the problem's, or a cut of it)
    nodes: np.ndarray  #: (n, 3) start node positions
    fixed: np.ndarray  #: (n,) bool
    options: SolverOptions
    note: str = ""

    @property
    def title(self) -> str:
        return TITLES.get(self.key, self.key)

    @property
    def lattice(self) -> Lattice:
        return self.problem.surface.lattice

    def surface(self, upto: int | None = None, only: int | None = None) -> EmbeddedSurface:
        """A fresh surface: levels ``0..upto``, or the single level ``only``."""
        if only is not None:
            return EmbeddedSurface(self.lattice, [self.levels[only]])
        levels = self.levels if upto is None else self.levels[: upto + 1]
        return EmbeddedSurface(self.lattice, levels)

    def on(self, upto: int | None = None, only: int | None = None) -> Problem:
        """The problem on a fresh surface (see :meth:`surface`): solves on it share its
        set-up caches."""
        return replace(self.problem, surface=self.surface(upto, only))

    @property
    def size(self) -> float:
        """Object size of the full mesh (largest bounding-box extent)."""
        return float(self.levels[-1].size)


def example_case(name: str) -> Case:
    """One of the built-in examples (``isochor.core.scenario.examples``)."""
    from isochor.core.scenario.examples import example_scenario
    from isochor.core.scenario.problem import build

    p = build(example_scenario(name))
    return Case(name, p, list(p.surface.levels), p.nodes, p.fixed, p.options)


def cow_case(models: Path) -> tuple[Case | None, str]:
    """The paper's cow bending from ``models/cow.obj``, or None and why not."""
    if not (models / "cow.obj").is_file():
        return None, f"cow row skipped: {models / 'cow.obj'} not found"
    try:
        from isochor.core.scenario.paper_models import cow_bend_scenario
        from isochor.core.scenario.problem import build
    except ImportError as exc:
        return None, f"cow row skipped: {exc} (isochor.core.scenario.paper_models)"
    p = build(cow_bend_scenario(models))
    note = "levels " + ", ".join(str(m.n_faces) for m in p.surface.levels)
    case = Case("cow-bend", p, list(p.surface.levels), p.nodes, p.fixed, p.options, note)
    return case, ""


def nearest_level(levels: Sequence[TriMesh], n_tri: int) -> int:
    """Index of the level whose triangle count is nearest ``n_tri`` (by ratio)."""
    return int(np.argmin([abs(np.log(m.n_faces / n_tri)) for m in levels]))
