"""Where a solve's time goes, measured with cProfile; nothing in the core is replaced.

One multi-level solve runs under :mod:`cProfile`, with a fresh profiler for each *segment*:
from the start to the first progress record (the start checks), from there to the record
that closes the first level, from that to the record that closes the next level, and so
on, and from the last level's record to the result. Per segment and for the whole solve
the profiler's call counts and cumulative times of a few public functions are read
(:data:`WATCHED`), matched by their code objects. Per-level steps and level times come from
the :class:`~isochor.core.solve.multilevel.LevelStats` of the result.

A segment holds a level's own work and, before it, what the solve does between two levels
(the stopping test of the level before, the setup of this level's problem): a coarser
split than timing each call by the level that made it. cProfile adds a little time to every
Python call it sees, so profiled times are above the plain T2 (both are reported).
"""

from __future__ import annotations

import cProfile
import inspect
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import scipy.optimize

from benchmarks.cases import Case, run_solve
from isochor.core.lattice import PointBasis
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import Progress, SolveResult
from isochor.core.solve.solver import SolverOptions
from isochor.core.springs import SpringNetwork
from isochor.core.volume import VolumeOperator

#: name -> the public function whose calls and cumulative time are read from the profile
WATCHED: dict[str, Callable] = {
    "volume+gradient": VolumeOperator.node_gradient,  # its basis products inside
    "volume only": VolumeOperator.__call__,
    "basis apply": PointBasis.apply,
    "basis transpose": PointBasis.apply_transpose,
    "springs": SpringNetwork.energy_and_gradient,
    "line search": scipy.optimize.line_search,
}

Key = tuple[str, int, str]  # pstats' (file name, first line, function name)
Row = tuple[int, int, float, float, dict]  # pstats' (primitive calls, calls, own, cum, callers)


def code_key(fn: Callable) -> Key | None:
    """pstats' key of a Python function (None for one without Python code)."""
    code = getattr(inspect.unwrap(fn), "__code__", None)
    return None if code is None else (code.co_filename, code.co_firstlineno, code.co_name)


@dataclass(frozen=True)
class CallStat:
    """Calls of one function and the time spent in them (callees included)."""

    calls: int = 0
    cum_s: float = 0.0

    @property
    def us_per_call(self) -> float:
        return 1e6 * self.cum_s / self.calls if self.calls else 0.0


def watched_stats(stats: Mapping[Key, Row]) -> dict[str, CallStat]:
    """The :data:`WATCHED` functions' entries of one profile's ``stats``."""
    out = {}
    for name, fn in WATCHED.items():
        row = stats.get(code_key(fn))
        out[name] = CallStat(row[1], row[3]) if row else CallStat()
    return out


@dataclass
class LevelProfile:
    """The segment of a solve that ends with one level's closing record."""

    level: int
    triangles: int
    steps: int
    level_s: float  #: LevelStats.time_s (under the profiler)
    segment_s: float  #: wall time of the segment (the level and what came before it)
    calls: dict[str, CallStat]

    @property
    def evals(self) -> int:
        """Volume + gradient evaluations (objective and line-search trials)."""
        return self.calls["volume+gradient"].calls

    @property
    def eval_s(self) -> float:
        """Volume + gradient to the nodes (with the basis products they take: one
        compiled pass, or apply, the vertex gradient and the transpose), seconds."""
        return self.calls["volume+gradient"].cum_s

    @property
    def other_s(self) -> float:
        """The segment minus evaluations, volume-only calls and springs, seconds."""
        c = self.calls
        return self.segment_s - self.eval_s - c["volume only"].cum_s - c["springs"].cum_s


@dataclass
class SolveProfile:
    """One profiled solve."""

    levels: list[LevelProfile]
    start_s: float  #: to the first record: start checks, the first evaluation
    finish_s: float  #: after the last level's record: the stopping test and the result
    total_s: float  #: the whole profiled solve
    plain_s: float  #: the same solve without the profiler
    totals: dict[str, CallStat]  #: the whole solve
    #: the functions with the most own time: (name, calls, own seconds, cumulative seconds)
    top: list[tuple[str, int, float, float]] = field(default_factory=list)
    result: SolveResult | None = None


def _label(key: Key) -> str:
    path, line, name = key
    if path == "~":  # a built-in
        return name
    parts = path.replace(os.sep, "/").split("/")
    for anchor in ("core", "scipy", "numpy", "benchmarks"):
        if anchor in parts:
            i = len(parts) - 1 - parts[::-1].index(anchor)
            return f"{'/'.join(parts[i:])}:{line}({name})"
    return f"{parts[-1]}:{line}({name})"


def _merge(stats: list[Mapping[Key, Row]]) -> dict[Key, tuple[int, float, float]]:
    """(calls, own seconds, cumulative seconds) per function over several profiles."""
    out: dict[Key, tuple[int, float, float]] = {}
    for s in stats:
        for key, (_, nc, tt, ct, _) in s.items():
            c, t, cum = out.get(key, (0, 0.0, 0.0))
            out[key] = (c + nc, t + tt, cum + ct)
    return out


def profile_solve(
    case: Case, upto: int | None = None, options: SolverOptions | None = None, top: int = 8
) -> SolveProfile:
    """Profile one multi-level solve of ``case`` on a set-up surface (levels ``0..upto``)."""
    problem = case.on(upto=upto)
    options = options or case.options
    run_solve(problem, case.nodes, case.fixed, options)  # set the levels up
    closed: list[tuple[Progress | None, cProfile.Profile, float]] = []
    prof = cProfile.Profile()
    t_seg = 0.0

    def on_record(rec: Progress) -> None:
        nonlocal prof, t_seg
        if closed and not rec.level_done:
            return
        prof.disable()
        closed.append((rec, prof, time.perf_counter() - t_seg))
        prof = cProfile.Profile()
        t_seg = time.perf_counter()
        prof.enable()

    gen = problem.solve(case.nodes, case.fixed, options=options)
    t0 = t_seg = time.perf_counter()
    prof.enable()
    try:
        result = run_to_end(gen, on_record)
    finally:
        prof.disable()
    t_end = time.perf_counter()
    closed.append((None, prof, t_end - t_seg))
    plain = run_solve(problem, case.nodes, case.fixed, options).wall

    stats = []
    for _, p, _ in closed:
        p.create_stats()
        stats.append(p.stats)
    by_level = {s.level: s for s in result.levels}
    levels = []
    for (rec, _, seg_s), st in zip(closed, stats, strict=True):
        if rec is None or not rec.level_done or rec.level not in by_level:
            continue
        s = by_level[rec.level]
        levels.append(
            LevelProfile(s.level, s.triangles, s.steps, s.time_s, seg_s, watched_stats(st))
        )
    first_is_start = bool(closed) and closed[0][0] is not None and not closed[0][0].level_done
    merged = _merge(stats)
    ranked = sorted(merged.items(), key=lambda kv: kv[1][1], reverse=True)[:top]
    totals = {}
    for name, fn in WATCHED.items():
        calls, _, cum = merged.get(code_key(fn), (0, 0.0, 0.0))
        totals[name] = CallStat(calls, cum)
    return SolveProfile(
        levels=levels,
        start_s=closed[0][2] if first_is_start else 0.0,
        finish_s=closed[-1][2],
        total_s=t_end - t0,
        plain_s=plain,
        totals=totals,
        top=[(_label(k), c, tt, ct) for k, (c, tt, ct) in ranked],
        result=result,
    )
