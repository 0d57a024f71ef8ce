"""The benchmark's command line and the order it measures in; numbers are printed as they come.

Start it with ``python -m benchmarks`` (which pins BLAS to one thread before NumPy is
imported), not by importing this module.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from benchmarks.caps import HEADING as CAPS_HEADING
from benchmarks.caps import run_caps
from benchmarks.caps import section as caps_section
from benchmarks.cases import EXAMPLES, FIGURES, Case, cow_case, example_case
from benchmarks.constraint_cases import run_constraints
from benchmarks.constraints_report import section, write_section
from benchmarks.display import HEADING as DISPLAY_HEADING
from benchmarks.display import run_display
from benchmarks.display import section as display_section
from benchmarks.first_use import HEADING as FIRST_USE_HEADING
from benchmarks.first_use import run_first_use
from benchmarks.first_use import section as first_use_section
from benchmarks.profiling import SolveProfile, profile_solve
from benchmarks.report import (
    DEFAULT_OUT,
    KEEP_MARKER,
    OLD_MARKERS,
    Results,
    draw_figure,
    write_report,
)
from benchmarks.scale import (
    ROOT,
    SCALE_TORI,
    ScaleRow,
    armadillo_child,
    run_armadillo,
    scale_row,
)
from benchmarks.sequences import HEADING as SEQUENCES_HEADING
from benchmarks.sequences import run_sequences
from benchmarks.sequences import section as sequences_section
from benchmarks.tables import (
    Table1Row,
    first_record_latency,
    fmt_level_row,
    start_level_sweep,
    table1_rows,
    table2,
    table2_paper_schedule,
)
from benchmarks.targets import constraint_targets, evaluate_targets
from benchmarks.timing import environment, limit_blas_threads

DEFAULT_MODELS = ROOT.parent / "shared" / "models"


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Reproduce the paper's Tables 1-2 and Figures 5-8 on this machine, time "
        "the evaluation at scale and the armadillo, check the performance targets.",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="2 repeats, small cases only; writes no file unless --out is given",
    )
    p.add_argument(
        "--repeats", type=int, default=None, help="runs per timing (default 7; 2 with --quick)"
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"the Markdown report (default {DEFAULT_OUT.relative_to(ROOT)}; "
        "figures go next to it)",
    )
    p.add_argument(
        "--models",
        type=Path,
        default=None,
        help="folder with cow.obj and the armadillo (default ../shared/models, or $ISOCHOR_MODELS)",
    )
    p.add_argument("--no-figures", action="store_true", help="do not draw Figures 5-8")
    p.add_argument(
        "--only",
        choices=("constraints", "sequences", "display", "caps", "first-use"),
        default=None,
        help="run one section only; the report keeps its other sections and gets this one replaced",
    )
    p.add_argument("--armadillo-child", metavar="PLY", help=argparse.SUPPRESS)
    return p


def print_profile(profile: SolveProfile) -> None:
    for lv in profile.levels:
        c = lv.calls
        print(
            f"  k {lv.level} N_tri {lv.triangles:6d} steps {lv.steps:4d} evals {lv.evals:4d} "
            f"{1e6 * lv.eval_s / max(lv.evals, 1):6.0f} us/eval  segment "
            f"{1e3 * lv.segment_s:7.2f} ms  eval {1e3 * lv.eval_s:6.2f}  line search "
            f"{1e3 * c['line search'].cum_s:6.2f}  springs {1e3 * c['springs'].cum_s:5.2f}"
        )
    print(
        f"  total {1e3 * profile.total_s:.1f} ms under cProfile ({1e3 * profile.plain_s:.1f}"
        f" ms without); before the first record {1e3 * profile.start_s:.1f} ms, after the "
        f"last level {1e3 * profile.finish_s:.1f} ms"
    )


def figures_for(
    cases: Sequence[Case], rows: Sequence[Table1Row], out: Path, notes: list[str]
) -> list[str]:
    """Draw Figures 5-8 next to ``out``; their file names (a note when matplotlib is absent)."""
    figures: list[str] = []
    for case in cases:
        row = [r for r in rows if r.case == case.key][-1]  # the paper-size row if there is one
        name = f"fig{FIGURES[case.key]}_{case.key.replace('-', '_')}.png"
        why = draw_figure(row, case.size, out.parent / name)
        if why:
            notes.append(why)
            print("  " + why)
            break
        figures.append(name)
    if figures:
        print(f"\nFigures: {', '.join(figures)}")
    return figures


def scale_rows(quick: bool, repeats: int) -> list[ScaleRow]:
    from isochor.core.scenario.shapes import torus

    rows = []
    for n in [4096, 65536] if quick else list(SCALE_TORI):
        mesh = torus(*SCALE_TORI[n])
        for shape in ((3, 3, 3), (5, 5, 5)):
            s = scale_row(mesh, shape, repeats if quick else max(repeats, 5))
            rows.append(s)
            ref = f"reference {s.t_reference.ms(2)} ms" if s.t_reference else ""
            print(
                f"  {s.triangles:8d} tri {s.nodes:4d} nodes {s.form:8s} eval "
                f"{s.t_eval.ms(2)} ms  volume {s.t_volume.ms(2)} ms  {ref}"
            )
        del mesh
    return rows


def only_constraints(
    models: Path, repeats: int, quick: bool, out: Path | None, env: dict, command: str
) -> int:
    """``--only constraints``: the section alone, replaced in place in the report."""
    print("Constraints: what each one costs (with / without, medians)")
    rows, notes = run_constraints(models, repeats, quick)
    targets = constraint_targets(rows)
    print("\nTargets")
    for t in targets:
        print("  " + t.line())
    if out is not None:
        lines = section(rows, notes, command, env, repeats, targets)
        write_section(out, lines, (KEEP_MARKER, *OLD_MARKERS))
        print(f"\nWrote the section into {out}")
    return 0


def only_section(title: str, run, section_lines, heading: str, out: Path | None) -> int:
    """``--only sequences`` / ``--only display``: ``run()`` gives the rows and notes,
    ``section_lines(rows, notes)`` the section, which replaces its namesake in ``out``."""
    print(title)
    rows, notes = run()
    if out is not None:
        write_section(out, section_lines(rows, notes), (KEEP_MARKER, *OLD_MARKERS), heading)
        print(f"\nWrote the section into {out}")
    return 0


def main(
    argv: Sequence[str] | None = None,
    *,
    numpy_first: bool = True,
    user_blas: Mapping[str, str] | None = None,
) -> int:
    """Run the benchmark; ``numpy_first`` and ``user_blas`` come from ``__main__``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser().parse_args(argv)
    user_blas = dict(user_blas or {})
    limit_blas_threads(numpy_first, user_blas)
    if args.armadillo_child:
        print(json.dumps(armadillo_child(args.armadillo_child, args.repeats or 5)))
        return 0
    quick = args.quick
    repeats = args.repeats or (2 if quick else 7)
    out = args.out if args.out is not None else (None if quick else DEFAULT_OUT)
    models = args.models or Path(os.environ.get("ISOCHOR_MODELS", DEFAULT_MODELS))
    env = environment(user_blas, unit=True)
    print(
        f"python -m benchmarks{' --quick' if quick else ''}: {env['cpu']}; Python "
        f"{env['python']}, NumPy {env['numpy']}, SciPy {env['scipy']}; {env['blas']}"
    )
    print(f"evaluation kernels: {env['kernels']}")
    print(env["unit"])
    print(f"{repeats} repeats per timing; medians (min-max)\n")
    command = " ".join(["python -m benchmarks", *argv])
    if args.only == "constraints":
        return only_constraints(models, repeats, quick, out, env, command)
    if args.only == "sequences":
        return run_sequences_section(models, repeats, command, out)
    if args.only == "display":
        return run_display_section(models, repeats, command, out)
    if args.only == "caps":
        return run_caps_section(models, repeats, command, out)
    if args.only == "first-use":
        return run_first_use_section(models, repeats, quick, command, out)
    res = Results(env, quick, repeats, [], command=command)

    print("Table 1")
    cases = [example_case(n) for n in EXAMPLES]
    cow, why = cow_case(models)
    if cow is None:
        res.notes.append(why)
        print("  " + why)
    else:
        cases.append(cow)
        res.notes.append(f"cow: {models / 'cow.obj'}, {cow.note} triangles")
    for case in cases:
        res.rows += table1_rows(case, repeats, max_paper_tri=16384 if quick else None)

    tc_case = cases[0]
    tc_est = next(r for r in res.rows if r.case == tc_case.key and r.variant.startswith("estimate"))
    res.t2rows = table2(tc_est)
    print("\nTable 2 (torus compression)")
    for r in res.t2rows:
        print(fmt_level_row(r))
    res.t2paper = table2_paper_schedule(tc_case, repeats)
    print("  paper schedule (start_level=0):")
    for r in res.t2paper:
        print(fmt_level_row(r))

    print("\nWhere the time goes (torus compression, cProfile)")
    res.profile = profile_solve(tc_case)
    print_profile(res.profile)

    print("\nStart level (torus compression)")
    res.sweep = start_level_sweep(tc_case, repeats)

    print("\nFirst progress record (fresh surface / set up)")
    for case in cases:
        cold, warm = first_record_latency(case, res.rows)
        res.latency[case.key] = (cold, warm)
        print(f"  {case.key:18s} {1e3 * cold:6.2f} ms / {1e3 * warm:6.2f} ms")

    if out is not None and not args.no_figures:
        res.figures = figures_for(cases, res.rows, out, res.notes)

    print("\nScale: volume + gradient evaluation")
    res.scale = scale_rows(quick, repeats)

    arma_why = "--quick skips the armadillo" if quick else ""
    if not quick:
        print("\nArmadillo (child process)")
        res.arma, arma_why = run_armadillo(models, repeats)
        a = res.arma
        if a is None:
            res.notes.append(arma_why)
            print("  " + arma_why)
        else:
            print(
                f"  load {a['load_s']:.2f} s, pyramid {a['pyramid_s']:.2f} s, first solve "
                f"{a['solve_cold_s']:.3f} s, later {np.median(a['solve_s']):.3f} s, peak RSS "
                f"{a['peak_rss_mb']:.0f} MB, levels {a['levels']}"
            )
            res.latency["armadillo"] = (
                a["first_record_cold_s"],
                float(np.median(a["first_record_s"])),
            )

    print("\nConstraints: what each one costs (with / without, medians)")
    res.constraints, res.constraint_notes = run_constraints(models, repeats, quick)

    res.targets = evaluate_targets(
        res.rows,
        res.scale,
        res.arma,
        res.latency,
        quick=quick,
        arma_why=arma_why,
        constraints=res.constraints,
    )
    print("\nTargets")
    for t in res.targets:
        print("  " + t.line())

    if out is not None:
        write_report(res, out)
        print(f"\nWrote {out}")
    if not quick:  # the sections --only measures, into the same report
        run_sequences_section(models, repeats, command, out)
        run_display_section(models, repeats, command, out)
        run_caps_section(models, repeats, command, out)
        run_first_use_section(models, repeats, quick, command, out)
    return 0


def run_sequences_section(models: Path, repeats: int, command: str, out: Path | None) -> int:
    reps = min(repeats, 3)
    return only_section(
        "Sequences: keyframed poses against cold solves (medians)",
        lambda: run_sequences(models, reps),
        lambda rows, notes: sequences_section(rows, notes, command, reps),
        SEQUENCES_HEADING,
        out,
    )


def run_first_use_section(
    models: Path, repeats: int, quick: bool, command: str, out: Path | None
) -> int:
    return only_section(
        "First use: the first solve, a cold command, big models (medians)",
        lambda: run_first_use(models, repeats, quick),
        lambda rows, notes: first_use_section(rows, notes, command),
        FIRST_USE_HEADING,
        out,
    )


def run_display_section(models: Path, repeats: int, command: str, out: Path | None) -> int:
    return only_section(
        "Display rate (medians)",
        lambda: run_display(models, repeats),
        lambda rows, notes: display_section(rows, notes, command, repeats),
        DISPLAY_HEADING,
        out,
    )


def run_caps_section(models: Path, repeats: int, command: str, out: Path | None) -> int:
    return only_section(
        "Open models: what capping costs (medians)",
        lambda: run_caps(models, repeats),
        lambda rows, notes: caps_section(rows, notes, command, repeats),
        CAPS_HEADING,
        out,
    )
