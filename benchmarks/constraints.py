"""The Constraints section: what each constraint beyond the paper's one volume costs in time
and what it buys, every case solved with and without it in the same run.

One row per case. Both variants solve on one surface (the same lattice, pyramid and
tolerances); each is run once untimed (the levels, and the constraint's own setup: the fold
guard's sample gradients, the bodies' shells, the first moment), then the repeats alternate
with / without, so a busy spell hits both alike. The times are medians; "first" is the
untimed solve with the constraint, which holds its setup. The measured quantities come from
the full mesh at the end of the solve (:mod:`isochor.core.solve.outcome`).

This module: the pairs, the rows, timing and measuring a pair, a row in words. The cases
are :mod:`benchmarks.constraint_cases`, the Markdown :mod:`benchmarks.constraints_report`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from benchmarks.cases import run_solve
from benchmarks.timing import Timing
from isochor.core.goal.spec import Goal
from isochor.core.scenario.problem import Problem
from isochor.core.solve.multilevel import EmbeddedSurface, SolveResult
from isochor.core.solve.solver import SolverOptions

HEADING = "## Constraints: what each one costs"
#: the anchor cases: the corner drag, in lattice sizes
DRAG = 0.3
#: the squash cases: the top layer's drop, in lattice heights
SQUASH = 0.2
#: the fold-guard shrink case: target volume ratio
SHRINK = 0.2
#: the constraints in the order of the table
CONSTRAINTS = ("anchor", "fold guard", "per body", "centroid", "axis pins")


@dataclass
class Variant:
    """One side of a pair: what the solve starts from and holds."""

    label: str
    nodes: np.ndarray  #: (n, 3) start node positions
    fixed: np.ndarray  #: (n, 3) bool, the fixed coordinates
    goal: Goal


@dataclass
class Pair:
    """A case solved with (``on``) and without (``off``) one constraint, on one surface."""

    constraint: str  #: one of :data:`CONSTRAINTS`
    key: str  #: short name of the case ("cow-bend", ...)
    case: str  #: what the case is, for the table
    problem: Problem  #: the model, its lattice and pyramid: both variants solve on it
    on: Variant
    off: Variant

    @property
    def surface(self) -> EmbeddedSurface:
        return self.problem.surface

    @property
    def options(self) -> SolverOptions:
        return self.problem.options


@dataclass
class Outcome:
    """What one variant's solve ended with, measured on the full mesh."""

    converged: bool
    message: str
    steps: int
    folded: float  #: folded share of the samples (det J <= 0)
    min_det: float  #: smallest det J over the samples
    target_error: float  #: (V - V_target) / |V_target|, total volume
    centroid_shift: float  #: |C - C0| / size
    body_errors: tuple[float, ...]  #: per body (V - V_target) / |V_target|, when > 1 body
    energy: float  #: spring energy, lengths in object sizes
    far_layer: float  #: anchor: largest move of the far layer's nodes / the drag
    rigid_shift: float  #: anchor: best-fit translation of the full mesh's vertices / size
    rigid_turn: float  #: anchor: best-fit rotation of the full mesh's vertices, degrees
    slide: float  #: largest sideways (x, y) move of the bottom layer's nodes / size


@dataclass
class ConstraintRow:
    """One case's times with and without the constraint, and what each solve ended with."""

    constraint: str
    key: str
    case: str
    labels: tuple[str, str]  #: (with, without)
    triangles: int  #: the full mesh's
    tol_volume: float
    t_with: Timing
    t_without: Timing
    first_with: float  #: seconds, the untimed first solve with the constraint (its setup)
    with_: Outcome
    without: Outcome

    @property
    def ratio(self) -> float:
        """Time with over time without (medians)."""
        return self.t_with.median / self.t_without.median if self.t_without.median else np.nan


# -- measuring -----------------------------------------------------------------------------------
def _far_layer(surface: EmbeddedSurface, v: Variant) -> tuple[np.ndarray, float]:
    """The node layer (lattice face) farthest from the moved nodes at rest, and the drag.

    Each face scores the distance from its plane to the nearest moved node; the highest
    wins (the far-side anchor's own rule, measured here independently of it)."""
    lat = surface.lattice
    rest = lat.rest_nodes
    drag = np.linalg.norm(v.nodes - rest, axis=1)
    moved = v.fixed.any(axis=1) & (drag > 1e-12 * lat.size)
    uvw = lat.grid_parameters()
    if not moved.any():
        return np.zeros(len(rest), dtype=bool), 0.0
    lengths = np.linalg.norm(lat.axes, axis=1)
    faces = [(a, s) for a in range(3) for s in (0.0, 1.0)]
    score = [float(np.min(np.abs(uvw[moved, a] - s))) * lengths[a] for a, s in faces]
    a, s = faces[int(np.argmax(score))]
    return np.isclose(uvw[:, a], s), float(drag[moved].max())


def _rigid_fit(before: np.ndarray, after: np.ndarray) -> tuple[np.ndarray, float]:
    """Best-fit rigid motion (least squares, Kabsch) taking ``before`` to ``after``: the
    translation of the centroid and the rotation angle in degrees."""
    c0, c1 = before.mean(axis=0), after.mean(axis=0)
    u, _, vt = np.linalg.svd((before - c0).T @ (after - c1))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    cos = np.clip((np.trace(rot) - 1) / 2, -1.0, 1.0)
    return c1 - c0, float(np.degrees(np.arccos(cos)))


def measure(pair: Pair, v: Variant, res: SolveResult) -> Outcome:
    """What ``res`` (a solve of variant ``v``) bought, on the full mesh."""
    surface, x = pair.surface, np.asarray(res.nodes)
    size = surface.size
    full = surface.level(-1)
    m, _ = full.moment_and_gradient(x)
    shift = float(np.linalg.norm(m / full.volume(x) - full.rest_centroid)) / size
    rest = surface.lattice.rest_nodes
    layer, drag = _far_layer(surface, v)
    far = float(np.linalg.norm(x[layer] - rest[layer], axis=1).max()) / drag if drag else np.nan
    move, turn = _rigid_fit(surface.full.vertices, surface.deform(x))
    bottom = np.isclose(surface.lattice.grid_parameters()[:, 2], 0.0)
    slide = float(np.linalg.norm(x[bottom, :2] - rest[bottom, :2], axis=1).max()) / size
    folds = res.folds
    return Outcome(
        converged=bool(res.converged),
        message=res.message,
        steps=sum(s.steps for s in res.levels),
        folded=float(folds.fraction),
        min_det=float(folds.min_det),
        target_error=float(res.target_error),
        centroid_shift=shift,
        body_errors=tuple(float(b.error) for b in res.bodies),
        energy=float(res.energy),
        far_layer=far,
        rigid_shift=float(np.linalg.norm(move)) / size,
        rigid_turn=turn,
        slide=slide,
    )


def time_pair(pair: Pair, repeats: int) -> ConstraintRow:
    """Time both variants of ``pair``: one untimed solve each, then ``repeats`` alternating."""

    def once(v: Variant):
        return run_solve(pair.problem, v.nodes, v.fixed, pair.options, goal=v.goal)

    once(pair.off)  # sets the levels up
    first = once(pair.on)  # and the constraint's own parts
    runs: dict[str, list] = {"on": [], "off": []}
    for i in range(max(1, repeats)):
        order = ("on", "off") if i % 2 == 0 else ("off", "on")
        for side in order:
            runs[side].append(once(getattr(pair, side)))
    return ConstraintRow(
        pair.constraint,
        pair.key,
        pair.case,
        (pair.on.label, pair.off.label),
        pair.surface.full.n_faces,
        pair.options.tol_volume,
        Timing(tuple(r.wall for r in runs["on"])),
        Timing(tuple(r.wall for r in runs["off"])),
        first.wall,
        measure(pair, pair.on, runs["on"][-1].result),
        measure(pair, pair.off, runs["off"][-1].result),
    )


# -- in words -----------------------------------------------------------------------------------
def _pct(x: float, digits: int = 2) -> str:
    return f"{100 * x:.{digits}g}%"


def measured(row: ConstraintRow, o: Outcome) -> str:
    """What one solve of ``row`` bought, in words."""
    c = row.constraint
    if c == "anchor":
        return (
            f"far layer {o.far_layer:.3f} of the drag; rigid shift {_pct(o.rigid_shift)} of "
            f"the size, turn {o.rigid_turn:.1f} deg"
        )
    if c == "fold guard":
        return f"folded {_pct(o.folded)}, min det J {o.min_det:.3f}"
    if c == "per body":
        return "bodies off target " + ", ".join(f"{100 * e:+.3f}%" for e in o.body_errors)
    if c == "centroid":
        return f"centroid shift {o.centroid_shift:.1e} of the size"
    return f"bottom layer slid {_pct(o.slide)} of the size; spring energy {o.energy:.3g}"


def converged_text(o: Outcome) -> str:
    """Yes, or no and whether the result is folded."""
    if o.converged:
        return "yes"
    return "**no** (folded)" if o.folded > 0 else "**no**"


def console_line(row: ConstraintRow) -> str:
    """One row for the console, as it is measured."""
    on, off = row.labels
    return (
        f"  {row.constraint:10s} {row.key:12s} {on} {row.t_with.ms()} ms / {off} "
        f"{row.t_without.ms()} ms = {row.ratio:.2f}x, first {1e3 * row.first_with:.0f} ms; "
        f"{on}: {measured(row, row.with_)} ({converged_text(row.with_)}); "
        f"{off}: {measured(row, row.without)} ({converged_text(row.without)})"
    )
