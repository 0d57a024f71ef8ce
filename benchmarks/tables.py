"""The paper's Tables 1 and 2 on this machine, the start-level sweep and the first record."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from benchmarks.cases import Case, Run, median_run, nearest_level, run_solve
from benchmarks.timing import Timing


@dataclass(frozen=True)
class PaperRow:
    """One row of the paper's Table 1 (SGI Onyx2, 195 MHz R10000)."""

    t1_ms: float
    t2_ms: float
    speedup: float
    n_tri: int
    dv: float  #: |dV| / V0


PAPER_TABLE1 = {
    "torus-compression": PaperRow(21000, 1760, 12, 4096, 0.0005),
    "torus-stretch": PaperRow(677400, 11080, 61, 65536, 0.0008),
    "club-compression": PaperRow(40990, 3530, 12, 16384, 0.0007),
    "cow-bend": PaperRow(15810, 2240, 7, 5804, 0.0007),
}


class LevelRow(NamedTuple):
    """One row of Table 2."""

    k: int  #: level
    n_tri: int
    dx: float  #: largest node coordinate change against the previous level, / object size
    steps: int
    t: float  #: seconds on this level
    t_cum: float  #: seconds on this level and the ones before it


#: Table 2 of the paper as far as our copy of the text has it (T and T_c in ms)
PAPER_TABLE2 = [
    LevelRow(0, 16, 0.25, 90, 120, 120),
    LevelRow(1, 64, 0.079, 15, 60, 180),
    LevelRow(2, 256, 0.033, 19, 290, 470),
    LevelRow(3, 1024, 0.004, 13, 700, 1170),
]


@dataclass
class Table1Row:
    """T1 and T2 of one example, with the accuracy of both."""

    case: str
    variant: str  #: "estimate" (the solver's own terminal) or "paper size"
    terminal_tri: int
    finest_tri: int  #: finest level of the pyramid the multi-level solve had
    t1: Timing
    t2: Timing
    t2_cold: float  #: seconds, the first solve on a fresh surface
    steps1: int
    steps2: int
    dv_full: float  #: T2 result, (V - V_target) / V0 on the finest mesh it had
    dv_terminal: float  #: T2, on the terminal level's own mesh
    dv_t1: float  #: T1 result
    node_change: float  #: T2, largest node change at the terminal level / size
    converged1: bool
    converged2: bool
    paper: PaperRow | None
    t2_runs: list[Run] = field(default_factory=list, repr=False)
    t1_runs: list[Run] = field(default_factory=list, repr=False)

    @property
    def speedup(self) -> float:
        """T1 / T2 (medians)."""
        return self.t1.median / self.t2.median if self.t2.median > 0 else float("nan")


def table1_row(
    case: Case, repeats: int, variant: str = "estimate", level: int | None = None
) -> Table1Row:
    """T1 and T2 of one case.

    ``variant="paper size"`` cuts the pyramid at ``level`` and solves every level up to it
    (no early stop). T1 and T2 runs are interleaved, so a busy spell hits both alike.
    """
    if variant == "estimate":
        problem, options = case.on(), case.options
    else:
        problem = case.on(upto=level)
        options = dataclasses.replace(case.options, tol_nodes=0.0)
    surface = problem.surface
    cold2 = run_solve(problem, case.nodes, case.fixed, options)
    res = cold2.result
    terminal = res.terminal_level if res.terminal_level >= 0 else len(surface.levels) - 1
    term_stats = {s.level: s for s in res.levels}.get(terminal)
    single = case.on(only=terminal)
    run_solve(single, case.nodes, case.fixed, case.options)  # set the level up
    runs1, runs2 = [], []
    for _ in range(max(1, repeats)):
        runs2.append(run_solve(problem, case.nodes, case.fixed, options))
        runs1.append(run_solve(single, case.nodes, case.fixed, case.options))
    r1 = runs1[0].result
    nan = float("nan")
    return Table1Row(
        case=case.key,
        variant=variant,
        terminal_tri=case.levels[terminal].n_faces,
        finest_tri=surface.levels[-1].n_faces,
        t1=Timing(tuple(r.wall for r in runs1)),
        t2=Timing(tuple(r.wall for r in runs2)),
        t2_cold=cold2.wall,
        steps1=sum(s.steps for s in r1.levels),
        steps2=sum(s.steps for s in res.levels),
        dv_full=res.rel_volume_error,
        dv_terminal=term_stats.rel_volume_error if term_stats else nan,
        dv_t1=r1.rel_volume_error,
        node_change=term_stats.max_node_change if term_stats else nan,
        converged1=r1.converged,
        converged2=res.converged,
        paper=PAPER_TABLE1.get(case.key),
        t2_runs=runs2,
        t1_runs=runs1,
    )


def table1_rows(
    case: Case,
    repeats: int,
    paper_size: bool = True,
    max_paper_tri: int | None = None,
    log: Callable[[str], object] = print,
) -> list[Table1Row]:
    """The estimate row of a case and, unless it is already there, its paper-size row
    (skipped above ``max_paper_tri`` triangles)."""
    rows = [table1_row(case, repeats)]
    log(fmt_row(rows[-1]))
    paper = PAPER_TABLE1.get(case.key)
    if paper_size and paper is not None:
        k = nearest_level(case.levels, paper.n_tri)
        n_tri = case.levels[k].n_faces
        if n_tri == rows[0].terminal_tri and k == len(case.levels) - 1:
            rows[0].variant = "estimate = paper size"
            log(f"  {case.key}: the solver's terminal is the paper's size")
        elif max_paper_tri is None or n_tri <= max_paper_tri:
            rows.append(table1_row(case, repeats, "paper size", k))
            log(fmt_row(rows[-1]))
        else:
            log(f"  {case.key}: paper-size row ({n_tri} triangles) skipped")
    return rows


def fmt_row(r: Table1Row) -> str:
    """One Table 1 row as a console line."""
    return (
        f"  {r.case:18s} {r.variant:10s} N_tri {r.terminal_tri:7d}  T1 {r.t1.ms()} ms  "
        f"T2 {r.t2.ms()} ms  T1/T2 {r.speedup:5.1f}  |dV|/V0 {abs(r.dv_full):.2e}"
    )


def table2(row: Table1Row | Sequence[Run]) -> list[LevelRow]:
    """Table 2 of the median T2 run of a Table 1 row (or of the given runs)."""
    run = median_run(row.t2_runs if isinstance(row, Table1Row) else row)
    out, cum = [], 0.0
    for s in run.result.levels:
        cum += s.time_s
        out.append(LevelRow(s.level, s.triangles, s.max_node_change, s.steps, s.time_s, cum))
    return out


def table2_paper_schedule(case: Case, repeats: int) -> list[LevelRow]:
    """Table 2 with the paper's schedule: every level from the coarsest (``start_level=0``)."""
    problem = case.on()
    run_solve(problem, case.nodes, case.fixed, case.options, start_level=0)  # set up
    runs = [
        run_solve(problem, case.nodes, case.fixed, case.options, start_level=0)
        for _ in range(max(1, repeats))
    ]
    return table2(runs)


def fmt_level_row(r: LevelRow) -> str:
    """One Table 2 row as a console line."""
    return (
        f"  k {r.k}  N_tri {r.n_tri:6d}  dX {100 * r.dx:7.3f}%  N_step {r.steps:4d}  "
        f"T {1e3 * r.t:7.2f} ms  T_c {1e3 * r.t_cum:7.2f} ms"
    )


class SweepRow(NamedTuple):
    """One start level of the sweep."""

    start: int
    n_tri: int  #: triangles of the start level
    t2: Timing
    terminal_tri: int
    steps: int  #: all levels
    dv: float  #: (V - V_target) / V0 on the full mesh


def start_level_sweep(
    case: Case, repeats: int, max_start: int = 5, log: Callable[[str], object] = print
) -> list[SweepRow]:
    """T2 with ``solve(..., start_level=k)`` for the first ``max_start`` levels."""
    out = []
    for k in range(min(max_start, len(case.levels))):
        problem = case.on()
        run_solve(problem, case.nodes, case.fixed, case.options, start_level=k)  # set up
        runs = [
            run_solve(problem, case.nodes, case.fixed, case.options, start_level=k)
            for _ in range(max(1, repeats))
        ]
        res = runs[0].result
        term = case.levels[res.terminal_level].n_faces if res.terminal_level >= 0 else 0
        t = Timing(tuple(r.wall for r in runs))
        steps = sum(s.steps for s in res.levels)
        out.append(SweepRow(k, case.levels[k].n_faces, t, term, steps, res.rel_volume_error))
        log(f"  start {k} ({case.levels[k].n_faces} tri): T2 {t.ms()} ms, terminal {term}")
    return out


def first_record_latency(case: Case, rows: Sequence[Table1Row]) -> tuple[float, float]:
    """Seconds to the first progress record: (fresh surface, set-up surface).

    The fresh one is a new solve; the set-up one is the median over the T2 runs of the
    case's estimate row in ``rows``.
    """
    cold = run_solve(case.on(), case.nodes, case.fixed, case.options).first_record
    row = next(r for r in rows if r.case == case.key and r.variant.startswith("estimate"))
    warm = float(np.median([r.first_record for r in row.t2_runs]))
    return cold, warm
