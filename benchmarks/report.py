"""docs/BENCHMARKS.md: the Markdown report and Figures 5-8 (matplotlib, imported lazily)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from benchmarks.cases import FIGURES, TITLES, Run, median_run, node_error
from benchmarks.constraints import ConstraintRow
from benchmarks.constraints_report import PEAK_LINE
from benchmarks.constraints_report import section as constraints_section
from benchmarks.profiling import SolveProfile
from benchmarks.scale import ROOT, ScaleRow
from benchmarks.tables import PAPER_TABLE2, LevelRow, SweepRow, Table1Row
from benchmarks.targets import Target
from benchmarks.timing import Timing, peak_rss_mb
from isochor.core.io.atomic import atomic_write_text

DEFAULT_OUT = ROOT / "docs" / "BENCHMARKS.md"
#: a hand-written part of BENCHMARKS.md after this line is kept when the file is rewritten
KEEP_MARKER = "<!-- hand-written below: kept by `python -m benchmarks` -->"
#: the markers earlier versions wrote, recognised when reading
OLD_MARKERS = ("<!-- hand-written below: kept by `isochor bench` -->",)


@dataclass
class Results:
    """Everything one benchmark run measured."""

    env: dict[str, str]
    quick: bool
    repeats: int
    rows: list[Table1Row]
    t2rows: list[LevelRow] = field(default_factory=list)
    t2paper: list[LevelRow] = field(default_factory=list)
    profile: SolveProfile | None = None
    sweep: list[SweepRow] = field(default_factory=list)
    scale: list[ScaleRow] = field(default_factory=list)
    arma: dict | None = None
    latency: dict[str, tuple[float, float]] = field(default_factory=dict)
    targets: list[Target] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)  #: file names next to the report
    notes: list[str] = field(default_factory=list)
    #: the Constraints section's rows (None: not run) and its skipped cases
    constraints: list[ConstraintRow] | None = None
    constraint_notes: list[str] = field(default_factory=list)
    command: str = ""  #: the command line that produced the run


def draw_figure(row: Table1Row, size: float, path: Path) -> str | None:
    """Figure 5-8 style: node error against cumulative time, log scale.

    Returns None on success or why the figure was skipped.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return "matplotlib is not installed (pip install 'isochor[bench]'): figures skipped"
    run = median_run(row.t2_runs)
    err = np.maximum(node_error(run, size), 1e-7)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    ax.semilogy(
        1e3 * run.times,
        err,
        "-",
        color="C0",
        lw=1.4,
        label=f"multi-level (T2 = {1e3 * run.wall:.0f} ms)",
    )
    n_rec = len(run.levels)
    ends = [i for i in range(n_rec) if i + 1 == n_rec or run.levels[i + 1] != run.levels[i]]
    for n, i in enumerate(ends):
        ax.plot(1e3 * run.times[i], err[i], "o", color="C0", ms=4)
        ax.annotate(
            _level_triangles(run, int(run.levels[i])),
            (1e3 * run.times[i], err[i]),
            textcoords="offset points",
            xytext=(4, 5) if n % 2 == 0 else (4, -11),
            fontsize=7,
            color="C0",
        )
    if row.t1_runs:
        r1 = median_run(row.t1_runs)
        ax.semilogy(
            1e3 * r1.times,
            np.maximum(node_error(r1, size), 1e-7),
            "--",
            color="C3",
            lw=1.2,
            label=f"single level, {row.terminal_tri} triangles (T1 = {1e3 * r1.wall:.0f} ms)",
        )
    ax.axhline(1e-3, color="0.6", lw=0.8, ls=":")
    ax.text(ax.get_xlim()[1], 1e-3, " 0.1%", va="center", fontsize=7, color="0.4")
    ax.set_xlabel("cumulative time (ms)")
    ax.set_ylabel("max node error / object size")
    ax.set_title(
        f"Figure {FIGURES.get(row.case, '')}: {TITLES.get(row.case, row.case)} "
        f"(terminal {row.terminal_tri} triangles)",
        fontsize=10,
    )
    ax.set_ylim(1e-7 * 0.8, 2.0)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return None


def _level_triangles(run: Run, k: int) -> str:
    for s in run.result.levels:
        if s.level == k:
            return str(s.triangles)
    return f"k={k}"


def _pct(x: float) -> str:
    """abs(x) in percent, 2 significant digits (at least 3 decimals)."""
    v = 100 * abs(x)
    return f"{v:.3f}%" if v >= 0.01 or v == 0 else f"{v:.2g}%"


def _level_table(lines: list[str], rows: list[LevelRow], paper: bool = False) -> None:
    lines.append("| k | N_tri | dX | N_step | T ms | T_c ms |")
    lines.append("|---:|---:|---:|---:|---:|---:|")
    for k, n, dx, st, t, tc in rows:
        if paper:
            lines.append(f"| {k} | {n} | {100 * dx:.1f}% | {st} | {t} | {tc} |")
        else:
            lines.append(f"| {k} | {n} | {100 * dx:.2f}% | {st} | {1e3 * t:.2f} | {1e3 * tc:.2f} |")


def _header(r: Results, lines: list[str]) -> None:
    env = r.env
    lines.append("# Benchmarks\n")
    lines.append(
        "Written by `python -m benchmarks"
        + (" --quick" if r.quick else "")
        + "` (benchmarks/). Do not edit above the hand-written marker: the next run "
        "rewrites it.\n"
    )
    lines.append(f"- date: {env['date']}")
    lines.append(f"- CPU: {env['cpu']} ({env['platform']})")
    lines.append(f"- Python {env['python']}, NumPy {env['numpy']}, SciPy {env['scipy']}")
    lines.append(f"- BLAS threads: {env['blas']}")
    lines.append(f"- evaluation kernels: {env['kernels']}")
    if env.get("unit"):
        lines.append(
            f"- {env['unit']}; 'u' is that unit: a time in units compares across machines "
            "(benchmarks/machine.py)"
        )
    lines.append(
        f"- every time is the median of {r.repeats} runs, (min-max) beside it; the "
        "machine is shared, so single runs can be slower\n"
    )
    for n in r.notes:
        lines.append(f"> {n}\n")
    lines.append("## Targets\n")
    lines.append("| target | measured | machine units | |")
    lines.append("|---|---|---|---|")
    for t in r.targets:
        mark = {"MET": "MET", "MISSED": "**MISSED**"}.get(t.status, t.status)
        lines.append(f"| {t.name} | {t.measured} | {t.units or '-'} | {mark} |")
    missed = [t for t in r.targets if t.met is False and t.why]
    if missed:
        lines.append("\nWhy missed, and what was tried:\n")
        for t in missed:
            lines.append(f"- *{t.name}*: {t.why}")
    lines.append("")


def _table1(r: Results, lines: list[str]) -> None:
    lines.append("## Table 1: multi-level against single-level\n")
    lines.append(
        "T1: the solve on the terminal mesh only; T2: multi-level; both with the levels set "
        "up (T2 cold: the first solve on a fresh surface, setup included). |dV|/V0 is "
        "measured on the finest mesh the solve had; node change: the largest node change at "
        "the terminal level against the level before, over the object size (the solver stops "
        "below 0.1%; paper-size rows stop by force). Paper: SGI Onyx2, 195 MHz R10000.\n"
    )
    lines.append(
        "| example | terminal | N_tri | T1 ms | T2 ms | T1/T2 | T2 cold ms | steps T1 / T2 "
        "| abs(dV)/V0 | node change | paper T1 / T2 ms | paper T1/T2 | paper N_tri "
        "| paper dV/V0 |"
    )
    lines.append("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for row in r.rows:
        p = row.paper
        conv = "" if (row.converged1 and row.converged2) else " (not converged)"
        paper = (
            f"{p.t1_ms:.0f} / {p.t2_ms:.0f} | {p.speedup:.0f} | {p.n_tri} | {_pct(p.dv)} |"
            if p
            else "| | | |"
        )
        lines.append(
            f"| {TITLES.get(row.case, row.case)} | {row.variant} (of {row.finest_tri}) | "
            f"{row.terminal_tri} | {row.t1.ms()} | {row.t2.ms()} | {row.speedup:.1f} | "
            f"{1e3 * row.t2_cold:.1f} | {row.steps1} / {row.steps2}{conv} | "
            f"{_pct(row.dv_full)} | {_pct(row.node_change)} | " + paper
        )
    lines.append("")
    if r.t2rows:
        lines.append("## Table 2: torus compression level by level\n")
        lines.append(
            "The median T2 run of the torus compression (estimate row), with the solver's "
            "default schedule (it starts at the first level with at least "
            "`SolverOptions.start_triangles` triangles). dX: largest node coordinate change "
            "against the previous level (the first level: against the start), over the "
            "object size.\n"
        )
        _level_table(lines, r.t2rows)
        if r.t2paper:
            lines.append("\nThe paper's schedule, from the 16-triangle level (`start_level=0`):\n")
            _level_table(lines, r.t2paper)
        lines.append(
            "\nThe paper's Table 2 (195 MHz R10000; our copy of the text ends at "
            "k = 3, the total is 1760 ms at 4096 triangles):\n"
        )
        _level_table(lines, PAPER_TABLE2, paper=True)
        lines.append("")


def _profile(p: SolveProfile, lines: list[str]) -> None:
    lines.append("## Where the time goes (torus compression)\n")
    lines.append(
        "One multi-level solve under cProfile, a fresh profiler per segment: a level's "
        "segment runs from the record that closed the level before (or the first record) to "
        "the record that closes this level, so it also holds what the solve does between the "
        "two levels (the stopping test of the level before, this level's setup). Call counts "
        "and cumulative times are cProfile's, of the public functions "
        "`VolumeOperator.value_and_gradient` (evals, volume), `PointBasis.apply` and "
        "`.apply_transpose` (basis; the volume-only calls' `apply` included), "
        "`SpringNetwork.energy_and_gradient` (springs), `VolumeOperator.__call__` "
        "(volume-only) and scipy's `line_search` (its evaluations included). other: the "
        "segment minus evals, basis, volume-only and springs (L-BFGS two-loop, progress "
        "records, Python). Steps and level ms are the result's `LevelStats`. cProfile adds "
        f"time to every Python call: this solve took {1e3 * p.total_s:.1f} ms profiled, "
        f"{1e3 * p.plain_s:.1f} ms without.\n"
    )
    lines.append(
        "| k | N_tri | steps | evals | evals/step | us/eval | level ms | segment ms "
        "| eval ms | line search ms | springs ms | other ms | volume-only calls (ms) |"
    )
    lines.append("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for lv in p.levels:
        c = lv.calls
        lines.append(
            f"| {lv.level} | {lv.triangles} | {lv.steps} | {lv.evals} | "
            f"{lv.evals / max(lv.steps, 1):.2f} | {1e6 * lv.eval_s / max(lv.evals, 1):.0f} | "
            f"{1e3 * lv.level_s:.2f} | {1e3 * lv.segment_s:.2f} | {1e3 * lv.eval_s:.2f} | "
            f"{1e3 * c['line search'].cum_s:.2f} | {1e3 * c['springs'].cum_s:.2f} | "
            f"{1e3 * lv.other_s:.2f} | {c['volume only'].calls} "
            f"({1e3 * c['volume only'].cum_s:.2f}) |"
        )
    lines.append(
        f"\nBefore the first record (start checks, the first evaluation) "
        f"{1e3 * p.start_s:.1f} ms; after the last level's record (stopping test, "
        f"final volume on the full mesh, result) {1e3 * p.finish_s:.1f} ms.\n"
    )
    lines.append("The whole solve:\n")
    lines.append("| function | calls | cumulative ms | us/call | share |")
    lines.append("|---|---:|---:|---:|---:|")
    for name, s in p.totals.items():
        share = s.cum_s / p.total_s if p.total_s > 0 else 0.0
        lines.append(
            f"| {name} | {s.calls} | {1e3 * s.cum_s:.2f} | {s.us_per_call:.0f} | "
            f"{100 * share:.0f}% |"
        )
    if p.top:
        lines.append("\nMost own time (cProfile's tottime):\n")
        lines.append("| function | calls | own ms | cumulative ms |")
        lines.append("|---|---:|---:|---:|")
        for name, calls, own, cum in p.top:
            lines.append(f"| `{name}` | {calls} | {1e3 * own:.2f} | {1e3 * cum:.2f} |")
    lines.append("")


def _sweep_and_figures(r: Results, lines: list[str]) -> None:
    if r.sweep:
        lines.append("## Start level (torus compression)\n")
        lines.append(
            "`solve(..., start_level=k)` skips the levels below k: where should the "
            "bootstrapping start?\n"
        )
        lines.append("| start level | N_tri | T2 ms | terminal N_tri | steps | abs(dV)/V0 |")
        lines.append("|---:|---:|---:|---:|---:|---:|")
        for k, n, t, term, steps, dv in r.sweep:
            lines.append(f"| {k} | {n} | {t.ms()} | {term} | {steps} | {_pct(dv)} |")
        lines.append("")
    if r.figures:
        lines.append("## Figures 5-8: convergence\n")
        lines.append(
            "Largest node distance from the final position over the object size, "
            "against cumulative time, for the median T2 run (dots: level ends, "
            "labelled with their triangles) and the single-level solve at the "
            "terminal size (dashed).\n"
        )
        for f in r.figures:
            lines.append(f"![{f}]({f})\n")


def _scale(r: Results, lines: list[str]) -> None:
    if r.scale:
        lines.append("## Scale: one volume + gradient evaluation\n")
        lines.append(
            "Torus meshes (`core.scenario.shapes.torus`), random node positions. eval: basis "
            "apply, volume and gradient, basis transpose (what one solver step costs on that "
            "level); volume: the vertex-space part alone; reference: the straightforward "
            "NumPy version Isochor had before (per-face `np.cross`, sparse gather), same "
            "numbers to 1e-10.\n"
        )
        lines.append(
            "| N_tri | nodes | basis | setup ms (one run) | eval ms | volume ms "
            "| reference ms | speed-up |"
        )
        lines.append("|---:|---:|---|---:|---:|---:|---:|---:|")
        for s in r.scale:
            ref = s.t_reference.ms() if s.t_reference else ""
            gain = f"{s.t_reference.median / s.t_eval.median:.1f}x" if s.t_reference else ""
            lines.append(
                f"| {s.triangles} | {s.nodes} | {s.form} | {1e3 * s.setup_s:.0f} | "
                f"{s.t_eval.ms(2)} | {s.t_volume.ms(2)} | {ref} | {gain} |"
            )
        lines.append("")
    a = r.arma
    if a:
        lines.append("## Scale: the 346k-triangle armadillo, 5x5x5 lattice, a bend\n")
        lines.append(
            "Child process: `core.io.meshio.load_mesh`, `core.solve.pyramid.build_pyramid`, "
            "then the bend (first node layer along the longest axis pinned, the last "
            "turned 30 degrees). Peak memory is the child's peak RSS.\n"
        )
        solves, firsts = Timing(tuple(a["solve_s"])), Timing(tuple(a["first_record_s"]))
        lines.append(f"- levels: {', '.join(map(str, a['levels']))} triangles")
        lines.append(f"- load {a['load_s']:.2f} s, pyramid {a['pyramid_s']:.2f} s")
        lines.append(
            f"- first solve (level setup included) {a['solve_cold_s']:.3f} s, later "
            f"solves {solves.ms()} ms"
        )
        lines.append(
            f"- terminal {a['terminal_tri']} triangles, |dV|/V0 {_pct(a['dv'])}, "
            f"converged {a['converged']}, steps per level {a['steps']}, ms per level "
            f"{[round(t, 1) for t in a['level_ms']]}"
        )
        lines.append(
            f"- first progress record: first solve "
            f"{1e3 * a['first_record_cold_s']:.1f} ms, later {firsts.ms()} ms"
        )
        lines.append(
            f"- peak RSS {a['peak_rss_mb']:.0f} MB (interpreter and imports "
            f"{a['rss_start_mb']:.0f} MB)\n"
        )
    if r.latency:
        lines.append("## First progress record\n")
        lines.append(
            "From the first `next()` on the solve generator to the first record: on "
            "a fresh surface (nothing set up: the first solve after loading) and on a "
            "set-up surface (every later edit).\n"
        )
        lines.append("| model | fresh surface ms | set up ms |")
        lines.append("|---|---:|---:|")
        for k, (cold, warm) in r.latency.items():
            lines.append(f"| {TITLES.get(k, k)} | {1e3 * cold:.2f} | {1e3 * warm:.2f} |")
        lines.append("")


def render(results: Results, kept: str = "") -> str:
    """The report as Markdown; ``kept`` (the hand-written part) follows the marker."""
    lines: list[str] = []
    _header(results, lines)
    _table1(results, lines)
    if results.profile:
        _profile(results.profile, lines)
    _sweep_and_figures(results, lines)
    _scale(results, lines)
    if results.constraints is not None:
        command = results.command or "python -m benchmarks" + (" --quick" * results.quick)
        lines += constraints_section(
            results.constraints, results.constraint_notes, command, results.env, results.repeats
        )
    lines.append(f"{PEAK_LINE}: {peak_rss_mb():.0f} MB.\n")
    lines.append(KEEP_MARKER)
    return "\n".join(lines) + "\n\n" + kept.lstrip("\n")


def kept_part(path: Path) -> str:
    """What follows the hand-written marker in ``path`` ("" without a file or marker)."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        return ""
    for marker in (KEEP_MARKER, *OLD_MARKERS):
        i = text.find(marker)
        if i >= 0:
            return text[i + len(marker) :]
    return ""


def write_report(results: Results, out: Path) -> None:
    """Write the report to ``out``, keeping the hand-written part of the file there."""
    text = render(results, kept_part(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, text)
