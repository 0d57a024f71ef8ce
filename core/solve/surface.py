"""A surface pyramid embedded in a lattice, with what every solve needs computed once.

:class:`EmbeddedSurface` holds the lattice and the levels (coarse to fine, the last at full
resolution) and, made on first use and kept: each level's basis and volume operator, the
spring network, the full mesh's bodies and rest volume, the points inside the model and the
fold guard and fold check built on them. :meth:`EmbeddedSurface.prepare` makes them all at
once, where waiting does not hurt (a loading thread).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import IsochorError
from ..goal.constraints import Bodies, Constraints, Level
from ..goal.folds import FoldCheck, FoldGuard, interior_points
from ..goal.handles import HandleSystem
from ..goal.spec import Goal
from ..lattice import Lattice
from ..mesh import TriMesh
from ..springs import SpringNetwork
from ..volume import signed_volume
from .solver import SolverOptions

#: the fold guard keeps det J above this fraction of min(1, target ratio) ...
FOLD_MARGIN = 0.05
#: ... with this weight: a sample point at det J = 0 costs FOLD_WEIGHT / samples (the spring
#: energy of a bent model is 0.01 to 1)
FOLD_WEIGHT = 100
#: the fold guard's samples are taken on the coarsest level with at least this many
#: triangles per cell of a local basis's lattice
PROBE_PER_CELL = 2


@dataclass(eq=False)
class EmbeddedSurface:
    """A surface pyramid embedded in a lattice, with per-level caches.

    Build one per document and reuse it for every solve: the bases of the levels are
    computed the first time a level is used and kept.

    Parameters
    ----------
    lattice : the FFD lattice; its rest nodes define X_org
    levels : coarse to fine versions of one closed surface; the last is full resolution
    n_bodies : how many separate bodies the full mesh has, when loading counted them
        (None: they are counted here when needed)
    """

    lattice: Lattice
    levels: Sequence[TriMesh]
    n_bodies: int | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not self.levels:
            raise IsochorError("A surface needs at least one mesh level.")
        self.levels = tuple(self.levels)
        _ = self.rest_volume  # measured when the surface is made, not by the first solve

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

    def level(self, k: int) -> Level:
        k = k % len(self.levels)
        if k not in self._cache:
            # the full mesh's rest volume is measured already (:attr:`rest_volume`)
            rest = self.rest_volume if k == len(self.levels) - 1 else None
            self._cache[k] = Level(self.lattice, self.levels[k], self.center, rest)
        return self._cache[k]

    @cached_property
    def bodies(self) -> Bodies:
        """The full mesh's solid bodies (shells with their cavities)."""
        return Bodies.of(self.full, self.n_bodies)

    @property
    def body_count(self) -> int:
        """How many bodies the full mesh has: as loading counted them, else from
        :attr:`bodies` (which measures each one's volume)."""
        return self.n_bodies if self.n_bodies is not None else self.bodies.count

    def constraints(self, k: int, goal: Goal, extra: HandleSystem | None = None) -> Constraints:
        """The goal's constraints on level ``k`` (and the handles', when given)."""
        bodies = self.bodies if goal.preserve == "per-body" else None
        return Constraints(self.level(k), goal, bodies, self.rest_volume, self.size, extra)

    @cached_property
    def _probe(self) -> TriMesh:
        """The coarsest level with at least 1000 triangles: where samples are taken."""
        least = max(1000, PROBE_PER_CELL * self.lattice_cells)
        return next((m for m in self.levels if m.n_faces >= least), self.full)

    @cached_property
    def lattice_cells(self) -> int:
        """Cells of a local basis's lattice (each point moves with its own window); 0 for
        the Bernstein basis, whose every node moves every point."""
        if not self.lattice.local:
            return 0
        return int(np.prod([max(c - 1, 1) for c in self.lattice.shape]))

    @cached_property
    def interior(self) -> np.ndarray:
        """About 2000 grid points inside the model (found on the probe level)."""
        return interior_points(self._probe)

    @cached_property
    def fold_check(self) -> FoldCheck:
        """det J over the full mesh's vertices and points inside the model (the vertices'
        lattice coordinates from the full level's basis)."""
        full = self.level(-1)
        return FoldCheck(
            self.lattice, self.full.vertices, self.interior, self.full.faces, full.parameters()
        )

    def survey(self, nodes: np.ndarray) -> None:
        """Measure the full mesh at ``nodes`` in one pass where it can: its volume from the
        vertices that the fold check's pass over them moves as it finds det J
        (:meth:`isochor.core.goal.folds.FoldCheck.survey`, the NumPy path of a Bernstein
        lattice). The full level's :meth:`~isochor.core.goal.constraints.Level.volume` and
        the fold check at the same nodes then read the results. Elsewhere, or when the
        volume there is known, nothing is done. A solve calls it where it is about to
        measure the full mesh (the stopping test, the result): separate passes took 2 of
        the torus compression's 27 ms."""
        full = self.level(-1)
        if full.knows(nodes):
            return
        points = self.fold_check.survey(nodes, self.center)
        if points is not None:
            full.volume_of(nodes, points)

    def fold_guard(self, margin: float) -> FoldGuard:
        """The fold penalty at the probe level's vertices and interior points."""
        key = ("guard", margin)
        if key not in self._cache:
            points = np.concatenate([self._probe.vertices, self.interior])
            self._cache[key] = FoldGuard(self.lattice, points, margin, FOLD_WEIGHT / margin**3)
        return self._cache[key]

    def shared(self, key, make, reuse: bool = True):
        """The object the solves on this surface share under ``key`` (the last one made):
        ``make()`` when the key differs from the last one's (or without ``reuse``; it is
        then shared from now on). A drag's frames and the solve when it ends share the
        preconditioner's curvature this way (:class:`isochor.core.solve.solver.Curvatures`)."""
        last = self._cache.get("shared")  # one tuple: threads swap it whole
        if last is None or last[0] != key or not reuse:
            last = (key, make())
            self._cache["shared"] = last
        return last[1]

    def remember(self, key: str, value) -> None:
        """Keep ``value`` under ``key`` for a later solve on this surface (None forgets it):
        the local release's last full-mesh result (:mod:`isochor.core.solve.local`)."""
        self._cache[("remembered", key)] = value

    def recall(self, key: str):
        """What :meth:`remember` kept under ``key``, or None."""
        return self._cache.get(("remembered", key))

    @cached_property
    def rest_volume(self) -> float:
        """Volume of the full-resolution mesh as given (the FFD of the rest lattice is the
        identity), computed without building the full level's basis."""
        return signed_volume(self.full.vertices, self.full.faces)

    def prepare(self, options: SolverOptions | None = None) -> EmbeddedSurface:
        """Compute now what every solve needs, so that the first solve after opening the
        model yields its first record at once: the springs, the rest volume, the bodies,
        the bases of the levels a solve starts on and the live levels, the full level (the
        display and the result), the interior samples and the fold check. Run it where
        waiting does not hurt (a loading thread). Returns ``self``."""
        opts = options or SolverOptions()
        _ = self.springs, self.rest_volume, self.bodies, self.interior
        for k, mesh in enumerate(self.levels):
            if mesh.n_faces <= max(opts.live_triangles, 4 * opts.start_triangles):
                self.level(k)
        self.level(-1)
        self.fold_guard(FOLD_MARGIN)
        _ = self.fold_check
        return self

    def volume(self, nodes: np.ndarray, level: int = -1) -> float:
        return self.level(level).volume(np.asarray(nodes, dtype=np.float64))

    def deform(self, nodes: np.ndarray, level: int = -1) -> np.ndarray:
        """(m, 3) vertices of a level deformed by ``nodes``."""
        return self.level(level).deform(np.asarray(nodes, dtype=np.float64))


def live_level(surface: EmbeddedSurface, triangles: int) -> int:
    """The finest level with at most ``triangles`` triangles (the coarsest when none has):
    where a live drag's frames are solved."""
    fits = [k for k, m in enumerate(surface.levels) if m.n_faces <= triangles]
    return fits[-1] if fits else 0
