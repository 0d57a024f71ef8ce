"""The records a solve yields and returns: immutable, safe to hand to another thread.

:func:`isochor.core.solve.multilevel.solve` yields a :class:`Progress` every inner step and at each
level's end, and returns a :class:`SolveResult` with one :class:`LevelStats` per level solved
(a row of the paper's Table 2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


def frozen_copy(a: np.ndarray) -> np.ndarray:
    """A read-only float64 copy of ``a``."""
    a = np.array(a, dtype=np.float64)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class Progress:
    """A snapshot of a running solve. ``nodes`` is a read-only copy."""

    nodes: np.ndarray  #: (n, 3) node positions, world units
    level: int  #: index in the pyramid, 0 = coarsest
    n_levels: int
    triangles: int  #: triangles of this level
    step: int  #: inner steps so far at this level
    rel_volume_error: float  #: (V - V_target) / V0 on this level
    sigma: float
    lam: float
    energy: float  #: spring energy with lengths in units of the object size
    elapsed: float  #: seconds since the solve started
    level_done: bool = False  #: True for the record that closes a level
    max_node_change: float | None = None  #: at a level's end: vs the previous level, / size

    @property
    def fraction(self) -> float:
        """About how far the solve is, 0 to 1: the levels closed of all (a solve that
        stops early on a coarser level ends at 1 all the same)."""
        return min(1.0, (self.level + (1 if self.level_done else 0)) / max(self.n_levels, 1))


@dataclass(frozen=True)
class LevelStats:
    """One row of the paper's Table 2."""

    level: int
    triangles: int
    steps: int
    time_s: float
    max_node_change: float  #: largest node coordinate change vs the previous level, / size
    rel_volume_error: float  #: on this level's own mesh
    error_estimate: float | None  #: Eq 29 estimate of this level's discretisation error


@dataclass(frozen=True)
class BodyVolume:
    """One solid body's volumes (a shell with the cavities inside it)."""

    original: float
    target: float
    final: float

    @property
    def error(self) -> float:
        """(final - target) / |target|"""
        return (self.final - self.target) / abs(self.target)


@dataclass(frozen=True)
class SolveResult:
    nodes: np.ndarray  #: (n, 3) final node positions
    levels: tuple[LevelStats, ...]
    terminal_level: int
    volume_original: float  #: full-resolution mesh, rest lattice
    volume_target: float
    volume_final: float  #: full-resolution mesh, final nodes
    rel_volume_error: float  #: (volume_final - volume_target) / volume_original
    energy: float
    free_nodes: int
    elapsed: float
    converged: bool
    message: str = ""
    lam: float = 0.0  #: the first multiplier (the total volume's, or the first body's)
    sigma: float = 0.0
    target_error: float = 0.0  #: (volume_final - volume_target) / |volume_target|
    #: the worst constraint residual on the full mesh, in the units of ``tol_volume``
    constraint_error: float = 0.0
    held: tuple[int, ...] = ()  #: node rows the far-side anchor held
    held_face: str = ""  #: which lattice face they are ("x min", ...), "" for none
    folds: Any = None  #: :class:`isochor.core.goal.folds.Folds` on the full mesh
    bodies: tuple[BodyVolume, ...] = ()  #: per body, when there are several or per-body
    centroid_shift: float | None = None  #: |C - C0| / size, with keep_centroid
    #: where each handle's point ended (:class:`isochor.core.goal.handles.HandleResult`)
    handles: tuple = ()
    #: under symmetry: the largest node's distance from its partner's mirror image, / size
    asymmetry: float | None = None
    #: a live drag's frame: measured on ``terminal_level``, not on the full mesh; no folds
    preview: bool = False

    @property
    def handles_met(self) -> bool:
        """Every handle landed within :data:`isochor.core.goal.handles.HANDLE_MET` of its target."""
        return all(h.met for h in self.handles)
