"""What a solve works from, and where its levels stop.

- :class:`Request`: what the caller asks of :func:`isochor.core.solve.multilevel.solve`
  besides the surface and the nodes: the goal, the handles, the options, how to start.
- :class:`Plan`: what the solve derives from the request before any level runs: the start
  nodes, the free coordinates, the held face, the mirror, the handles' system and the
  levels to run. It does not change while the levels run.
- :class:`Iterate`: the nodes and the multipliers between two levels.
- :class:`Ending`: where the levels stopped, and whether they converged there.

The result (:mod:`.outcome`) is measured from a plan and its ending.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..goal.constraints import Constraints
from ..goal.handles import Handle, HandleSystem
from ..goal.spec import Goal
from ..goal.symmetry import Mirror
from .records import LevelStats
from .solver import Coordinates, SolverOptions
from .surface import EmbeddedSurface


@dataclass(frozen=True)
class Request:
    """What a solve is asked.

    goal : what to hold
    handles : points of the model that must land at given places
    options : the solver's tolerances and settings
    start_level : the first pyramid level to solve on; None for the coarsest level with at
        least ``options.start_triangles`` triangles
    near : the nodes solve a problem near the one before (a sequence's frame, a release)
    live : a drag's frame: solve up to the preview level only, never on the full mesh
    """

    goal: Goal
    handles: tuple[Handle, ...] = ()
    options: SolverOptions = field(default_factory=SolverOptions)
    start_level: int | None = None
    near: bool = False
    live: bool = False


@dataclass(frozen=True, eq=False)
class Plan:
    """A solve's set-up, fixed before the first level runs.

    nodes : (n, 3) start nodes (mirror-symmetric under a mirror); never written to
    coords : the solver's variables: the free coordinates, tied under a mirror
    held : (n,) bool, the nodes the far-side anchor holds
    face : which lattice face they are ("x min", ...), "" for none
    mirror : the symmetry, or None
    system : the handles' equations (their mirror images included), or None
    start_level : the first level to solve on, before a warm start moves it up
    top : the level the solve ends on at the latest (the full mesh, or the preview level
        of a live frame)
    near : start from the multipliers of a nearby problem (always with ``live``)
    t0 : ``time.perf_counter()`` when the solve started
    """

    surface: EmbeddedSurface
    goal: Goal
    options: SolverOptions
    nodes: np.ndarray
    coords: Coordinates
    held: np.ndarray
    face: str
    mirror: Mirror | None
    system: HandleSystem | None
    start_level: int
    top: int
    near: bool
    live: bool
    t0: float

    @property
    def n_levels(self) -> int:
        return len(self.surface.levels)

    @property
    def size(self) -> float:
        return self.surface.size

    @property
    def n_free(self) -> int:
        """Nodes with at least one free coordinate."""
        return int(self.coords.moving.any(axis=1).sum())

    def constraints(self, k: int) -> Constraints:
        """The goal's constraints on level ``k``, with the handles'."""
        return self.surface.constraints(k, self.goal, self.system)


@dataclass(frozen=True, eq=False)
class Iterate:
    """The nodes and the multipliers a level starts from (and the last one ends with)."""

    nodes: np.ndarray  #: (n, 3)
    lam: np.ndarray  #: the Lagrange multipliers, one per constraint
    sigma: float  #: the penalty


@dataclass(frozen=True, eq=False)
class Ending:
    """Where the levels stopped."""

    nodes: np.ndarray  #: (n, 3) the last level's nodes
    stats: tuple[LevelStats, ...]  #: one per level solved
    terminal: int  #: the level the solve stopped on (-1: nothing was solved)
    lam: np.ndarray
    sigma: float
    converged: bool  #: the last level's constraint converged (not yet the full mesh's check)
    message: str = ""
