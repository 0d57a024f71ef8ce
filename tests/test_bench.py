"""The benchmark (``benchmarks/``) on tiny sizes, and the fast evaluation against the
straightforward per-face formula. No timing is asserted: times only have to be positive."""

import dataclasses
import itertools
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.optimize

from benchmarks import (
    cases,
    constraint_cases,
    constraints,
    constraints_report,
    machine,
    profiling,
    report,
    scale,
    tables,
    targets,
    timing,
)
from benchmarks.cases import median_run, node_error
from benchmarks.scale import ScaleRow
from benchmarks.tables import Table1Row
from benchmarks.timing import Timing
from isochor.core import lattice as lat_mod
from isochor.core import volume as vol_mod
from isochor.core.lattice import Lattice, PointBasis
from isochor.core.scenario.shapes import sphere_levels, torus
from isochor.core.solve import lbfgs as lbfgs_mod
from isochor.core.springs import SpringNetwork
from isochor.core.volume import VolumeOperator, signed_volume
from tests.models import box, model

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def small_case():
    """The torus compression cut at 1024 triangles, solved from the 64-triangle level."""
    case = cases.example_case("torus-compression")
    case.levels = case.levels[:4]  # 16 .. 1024 triangles
    case.options = dataclasses.replace(case.options, start_triangles=64)
    return case


@pytest.fixture(scope="module")
def small_rows(small_case):
    lines = []
    rows = tables.table1_rows(small_case, repeats=2, log=lines.append)
    rows.append(tables.table1_row(small_case, 1, "paper size", 2))  # cut at 256 triangles
    assert lines and all(isinstance(s, str) for s in lines)
    return rows


# -- timing ------------------------------------------------------------------------------------
def test_timing_median_spread_and_milliseconds():
    t = Timing((0.003, 0.001, 0.002, 0.010))
    assert t.median == pytest.approx(0.0025)
    assert (t.lo, t.hi) == (0.001, 0.010) and t.spread == pytest.approx(0.009)
    assert t.ms() == "2.5 (1.0-10.0)" and t.ms(2) == "2.50 (1.00-10.00)"
    assert Timing((0.5,)).spread == 0.0


def test_time_call_warms_up_then_times_every_repeat():
    calls = []
    t = timing.time_call(lambda: calls.append(1), repeats=3, warmup=2)
    assert len(calls) == 5 and len(t.values) == 3 and all(v >= 0 for v in t.values)
    assert len(timing.time_call(lambda: None, repeats=0, warmup=0).values) == 1


def test_environment_and_memory():
    assert timing.peak_rss_mb() > 10
    env = timing.environment({"OMP_NUM_THREADS": "4"})
    assert {"date", "cpu", "python", "numpy", "scipy", "blas", "platform"} <= set(env)
    assert "set by the user" in env["blas"] and "OPENBLAS_NUM_THREADS" in env["blas"]
    assert "set by the user" not in timing.environment({})["blas"]


@pytest.fixture
def unit_of_100ms():
    """The machine unit taken as 100 ms for the test (the measured one put back after)."""
    fixed = machine.MachineUnit(Timing((0.1,)), Timing((0.05,)))
    previous = machine.use(fixed)
    yield fixed
    machine.use(previous)


def test_machine_unit_reads_a_gigabyte_and_runs_the_compute_kernel():
    unit = machine.measure(repeats=2)
    assert len(unit.read.values) == 2 and len(unit.compute.values) == 2
    assert unit.seconds == unit.read.median > 0 and unit.compute.median > 0
    assert unit.bandwidth == pytest.approx(machine.UNIT_BYTES / unit.read.median)
    assert unit.flops == pytest.approx(machine.FLOPS / unit.compute.median)
    words = unit.words()
    assert words.startswith("machine unit: 1 GB") and "GB/s" in words and "GFLOP/s" in words
    assert machine.FLOPS == 2 * machine.DEGREE * machine.COMPUTE_POINTS * machine.COMPUTE_PASSES


def test_the_compute_kernel_is_horners_rule_for_its_polynomial():
    x = np.linspace(-1.0, 1.0, 1001)
    y = machine.compute_kernel(x, np.empty_like(x), passes=3)
    # the same multiply-adds in the same order as np.polyval; a few ulps either way
    bound = machine.DEGREE * np.finfo(float).eps * np.polyval(np.abs(machine.COEFFICIENTS), abs(x))
    assert np.all(np.abs(y - np.polyval(machine.COEFFICIENTS, x)) <= bound)


def test_unit_is_measured_once_per_process_and_every_time_is_stated_in_it(unit_of_100ms):
    assert machine.unit_seconds() == 0.1 and machine.machine_unit() is unit_of_100ms
    assert machine.in_units(0.05) == "0.5 u" and machine.in_units(30.0) == "300 u"
    t = targets.torus_40ms_target([_row(t2=0.030)])
    assert t.units == "0.3 u < 0.4 u" and t.units in t.line()
    assert targets.eval_1m_target([_scale_row(0.035)]).units == "0.35 u >= 0.3 u"
    assert targets.accuracy_target([_row()]).units == ""  # not a time
    from benchmarks.display import Row, target_table

    row = Row("a drag frame", Timing((0.02, 0.05, 0.03)), "<= 16 ms", False)
    assert row.units() == "0.3 u (<= 0.16 u)"
    assert row.line() == "a drag frame: 30.0 (20.0-50.0) ms = 0.3 u (<= 0.16 u); <= 16 ms; " + (
        "**MISSED**: slower than the target"
    )
    assert Row("ratio", Timing((0.2,)), "ratio <= 1.0", True).units() == "2 u"
    assert Row("none", None, "-", None, "why").units() == "-"
    table = target_table([row], [])
    assert "machine units" in table[0] and "| 0.3 u (<= 0.16 u) |" in table[2]


def test_main_sets_one_blas_thread_before_numpy_is_imported():
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
    }
    env["MKL_NUM_THREADS"] = "3"  # the user's setting is kept
    code = (
        "import os, sys; import benchmarks.__main__ as m; "
        "print(os.environ['OMP_NUM_THREADS'], os.environ['OPENBLAS_NUM_THREADS'], "
        "os.environ['MKL_NUM_THREADS'], 'numpy' in sys.modules, m.NUMPY_FIRST, m.USER_BLAS)"
    )
    out = (
        subprocess.run(
            [sys.executable, "-c", code],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        .stdout.strip()
        .split(maxsplit=5)
    )
    assert out == ["1", "1", "3", "False", "False", "{'MKL_NUM_THREADS': '3'}"]
    usage = subprocess.run(
        [sys.executable, "-m", "benchmarks", "--help"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "python -m benchmarks" in usage and "--quick" in usage and "--repeats" in usage
    assert "--only" in usage and "constraints" in usage


# -- cases and Tables 1-2 ----------------------------------------------------------------------
def test_run_solve_keeps_every_record(small_case):
    problem = small_case.on()
    run = cases.run_solve(problem, small_case.nodes, small_case.fixed, small_case.options)
    r = len(run.times)
    assert r > 2 and run.nodes.shape == (r, len(small_case.nodes), 3) and run.levels.shape == (r,)
    assert np.all(np.diff(run.times) >= 0) and 0 < run.first_record <= run.wall
    assert run.result.converged and run.levels[0] == 1 and run.levels[-1] == 3
    err = node_error(run, small_case.size)
    assert len(err) == r and err[-1] < 1e-12 and err.max() > 1e-3


def test_table1_rows_are_sane(small_case, small_rows):
    rows = small_rows
    assert rows[0].variant.startswith("estimate") and rows[-1].variant == "paper size"
    for r in rows:
        assert r.t1.median > 0 and r.t2.median > 0 and r.t2_cold > 0
        assert math.isfinite(r.speedup) and r.speedup > 0
        assert r.converged1 and r.converged2
        assert abs(r.dv_full) <= 5e-4 and abs(r.dv_terminal) <= 5e-4 and abs(r.dv_t1) <= 5e-4
        assert r.terminal_tri in [m.n_faces for m in small_case.levels]
        assert r.steps1 > 0 and r.steps2 > 0 and r.paper == tables.PAPER_TABLE1[r.case]
    # a paper-size row solves every level of the cut pyramid
    assert rows[-1].terminal_tri == rows[-1].finest_tri == 256
    assert len(rows[0].t2_runs) == len(rows[0].t1_runs) == 2


def test_table2_rows_are_the_median_runs_level_stats(small_rows):
    row = small_rows[0]
    t2 = tables.table2(row)
    stats = median_run(row.t2_runs).result.levels
    assert len(t2) == len(stats) >= 2
    for lr, s in zip(t2, stats, strict=True):
        assert (lr.k, lr.n_tri, lr.dx, lr.steps, lr.t) == (
            s.level,
            s.triangles,
            s.max_node_change,
            s.steps,
            s.time_s,
        )
    assert [lr.k for lr in t2] == list(range(t2[0].k, t2[0].k + len(t2)))
    assert [lr.t_cum for lr in t2] == pytest.approx(list(itertools.accumulate(lr.t for lr in t2)))
    assert all(b > a > 0 for a, b in itertools.pairwise(lr.t_cum for lr in t2))
    assert "N_step" in tables.fmt_level_row(t2[0])


def test_start_level_sweep_and_first_record(small_case, small_rows):
    sweep = tables.start_level_sweep(small_case, 1, max_start=2, log=lambda s: None)
    assert [s.start for s in sweep] == [0, 1] and [s.n_tri for s in sweep] == [16, 64]
    assert all(s.t2.median > 0 and s.steps > 0 and abs(s.dv) <= 5e-4 for s in sweep)
    cold, warm = tables.first_record_latency(small_case, small_rows)
    assert cold > 0 and warm > 0


# -- where the time goes -----------------------------------------------------------------------
def _core_state():
    classes = (VolumeOperator, PointBasis, SpringNetwork)
    return ({c: dict(vars(c)) for c in classes}, lbfgs_mod.line_search, scipy.optimize.line_search)


def test_profile_comes_from_cprofile_and_leaves_the_core_alone(small_case):
    before = _core_state()
    vg = VolumeOperator.value_and_gradient
    prof = profiling.profile_solve(small_case)
    assert VolumeOperator.value_and_gradient is vg
    assert _core_state() == before and sys.getprofile() is None
    assert all(profiling.code_key(f) is not None for f in profiling.WATCHED.values())

    assert [lv.level for lv in prof.levels] == [s.level for s in prof.result.levels] == [1, 2, 3]
    for lv, s in zip(prof.levels, prof.result.levels, strict=True):
        assert (lv.triangles, lv.steps, lv.level_s) == (s.triangles, s.steps, s.time_s)
        assert lv.evals >= lv.steps > 0 and lv.eval_s > 0 and lv.segment_s >= lv.level_s * 0.9
        # one per volume gradient on the NumPy path; none in the compiled one pass
        assert lv.calls["basis transpose"].calls in (0, lv.evals)
        assert lv.calls["springs"].calls > 0
    tot = prof.totals
    assert tot["volume+gradient"].calls >= sum(lv.evals for lv in prof.levels) + 1  # the start
    assert tot["volume+gradient"].cum_s > 0 and tot["line search"].calls >= 0
    assert prof.total_s > 0 and prof.plain_s > 0 and prof.start_s > 0 and prof.finish_s > 0
    assert prof.top and all(calls > 0 and own >= 0 for _, calls, own, _ in prof.top)


# -- targets -----------------------------------------------------------------------------------
def _row(
    case="torus-compression",
    tri=4096,
    t1=0.06,
    t2=0.03,
    dv=1e-4,
    dx=5e-4,
    converged=True,
    variant="estimate",
):
    return Table1Row(
        case,
        variant,
        tri,
        tri,
        Timing((t1,)),
        Timing((t2,)),
        t2,
        10,
        12,
        dv,
        dv,
        dv,
        dx,
        True,
        converged,
        None,
    )


def test_a_target_under_its_limit_is_met_and_one_over_is_missed():
    met = targets.torus_40ms_target([_row(t2=0.030)])
    missed = targets.torus_40ms_target([_row(t2=0.050)])
    assert met.met is True and "30.0 ms < 40 ms" in met.reason
    assert missed.met is False and "50.0 ms >= 40 ms" in missed.reason and missed.why
    assert met.line().startswith("[MET] ") and missed.line().startswith("[MISSED] ")
    other = targets.torus_40ms_target([_row(tri=1024)])
    assert other.met is None and "4096" in other.reason
    assert other.line().startswith("[not measured] ")


def test_table1_targets():
    ok, slow = _row(t1=0.06, t2=0.03), _row(case="club-compression", t1=0.02, t2=0.03)
    assert targets.never_slower_target([ok]).met is True
    t = targets.never_slower_target([ok, slow])
    assert t.met is False and "club-compression" in t.reason and "0.67x" in t.reason

    assert targets.speedup_65k_target([_row(tri=65536, t1=0.6, t2=0.1)]).met is True
    t = targets.speedup_65k_target([_row(tri=65536, t1=0.4, t2=0.1)])
    assert t.met is False and "4.0x < 5x" in t.reason
    assert targets.speedup_65k_target([ok]).met is None

    assert targets.accuracy_target([ok]).met is True
    t = targets.accuracy_target([_row(dv=6e-4)])
    assert t.met is False and "0.060% > 0.05%" in t.reason
    t = targets.accuracy_target([_row(dx=2e-3)])
    assert t.met is False and "node change" in t.reason
    t = targets.accuracy_target([_row(converged=False)])
    assert t.met is False and "not converged" in t.reason
    assert targets.accuracy_target([_row(variant="paper size")]).met is None


def _scale_row(t_eval, tri=1048576, nodes=27):
    return ScaleRow(tri, nodes, "factored", 0.5, Timing((t_eval,)), Timing((t_eval / 2,)), None)


def _arma(load=0.5, pyramid=0.8, cold=0.3, peak=400.0, rewrite=0.06):
    return {
        "rewrite_s": [rewrite - 0.01, rewrite, rewrite + 0.01],
        "load_s": load,
        "pyramid_s": pyramid,
        "solve_cold_s": cold,
        "solve_s": [0.08, 0.09],
        "first_record_s": [3e-4],
        "first_record_cold_s": 0.015,
        "peak_rss_mb": peak,
        "rss_start_mb": 80.0,
        "levels": [82, 336],
        "terminal_tri": 336,
        "dv": 2e-4,
        "converged": True,
        "steps": [100, 12],
        "level_ms": [40.0, 9.0],
    }


def test_scale_armadillo_and_first_record_targets():
    assert targets.eval_1m_target([_scale_row(0.025)]).met is True
    t = targets.eval_1m_target([_scale_row(0.035)])
    assert t.met is False and "35.0 ms >= 30 ms" in t.reason
    t = targets.eval_1m_target([_scale_row(0.01, tri=65536)], quick=True)
    assert t.met is None and "--quick" in t.reason and "--quick" in t.measured

    assert [t.met for t in targets.armadillo_targets(_arma())] == [True, True, True, True]
    missed = targets.armadillo_targets(_arma(load=2.5, cold=1.2, peak=3000.0, rewrite=0.6))
    assert [t.met for t in missed] == [False, False, False, False]
    assert "3.30 s >= 3 s" in missed[0].reason and "3000 MB >= 2048 MB" in missed[3].reason
    assert "0.60 s >= 0.5 s" in missed[2].reason  # the median
    (t,) = targets.armadillo_targets(None, "armadillo skipped: x.ply not found")
    assert t.met is None and "x.ply" in t.reason

    assert targets.first_record_target({"torus": (0.015, 0.001)}).met is True
    assert targets.first_record_target({"torus": (0.025, 0.001)}).met is False
    t = targets.first_record_target({"a": (0.001, 0.001), "b": (0.002, 0.030)})
    assert t.met is False and "30.0 ms >= 20 ms" in t.reason
    assert targets.first_record_target({}).met is None


def test_targets_of_a_measured_run_are_definite(small_rows):
    latency = {"torus-compression": (0.004, 0.0003)}
    ts = targets.evaluate_targets(
        small_rows, [], None, latency, quick=True, arma_why="--quick skips the armadillo"
    )
    names = [t.name for t in ts]
    assert names[0] == targets.ACCURACY and names[-1] == targets.FIRST_RECORD
    by_name = {t.name: t for t in ts}
    # converged within the volume tolerance, but the cut pyramid ends before the nodes settle
    acc = by_name[targets.ACCURACY]
    assert all(r.converged2 and abs(r.dv_full) <= 5e-4 for r in small_rows)
    assert acc.met is False and "node change" in acc.reason and ">= 0.1%" in acc.reason
    assert by_name[targets.FIRST_RECORD].met is True
    slower = by_name[targets.NEVER_SLOWER]
    assert slower.met is all(r.speedup >= 1 for r in small_rows)
    assert ("below 1" in slower.reason) is not slower.met
    assert by_name[targets.SPEEDUP_65K].met is None and by_name[targets.EVAL_1M].met is None
    assert by_name["armadillo 346k targets"].met is None
    for t in ts:
        assert t.measured and t.reason and t.status in t.line()


# -- the Constraints section ---------------------------------------------------------------------
def _check_rows(rows):
    for r in rows:
        assert r.constraint in constraints.CONSTRAINTS and r.key and r.case and r.triangles > 0
        assert len(r.labels) == 2 and r.labels[0] != r.labels[1]
        for t in (r.t_with, r.t_without):
            assert len(t.values) == 1 and t.median > 0  # one repeat
        assert r.first_with > 0 and r.ratio > 0 and 0 < r.tol_volume < 1
        for o in (r.with_, r.without):
            assert isinstance(o.converged, bool) and o.steps >= 0
            assert 0 <= o.folded <= 1 and np.isfinite(o.min_det)
            assert np.isfinite(o.target_error) and np.isfinite(o.centroid_shift)
            assert np.isfinite(o.far_layer) and o.rigid_shift >= 0 and o.slide >= 0
            assert isinstance(constraints.measured(r, o), str)
        assert r.key in constraints.console_line(r)


@pytest.fixture(scope="module")
def built_in_constraints(tmp_path_factory):
    """The section on tiny inputs from an empty models folder: the built-in cases only."""
    lines = []
    empty = tmp_path_factory.mktemp("no_models")
    rows, notes = constraint_cases.run_constraints(empty, repeats=1, tiny=True, log=lines.append)
    return rows, notes, lines


def test_constraints_section_on_built_in_shapes_skips_the_shared_models(built_in_constraints):
    rows, notes, lines = built_in_constraints
    assert [r.key for r in rows] == ["torus-drag", "two-spheres"]
    assert len(notes) == 7 and all("skipped" in n and "not found" in n for n in notes)
    assert len(lines) == len(rows) + len(notes)
    _check_rows(rows)
    anchor, spheres = rows
    # far-side holds the far layer; without it the drag moves the torus as a whole
    assert anchor.with_.far_layer < 1e-9 and anchor.without.far_layer > 0.5
    assert len(spheres.with_.body_errors) == len(spheres.without.body_errors) == 2

    ts = targets.constraint_targets(rows)
    by_name = {t.name: t for t in ts}
    for name in (targets.ANCHOR_FAR, targets.PER_BODY, targets.CONVERGED):
        assert by_name[name].met in (True, False), name
    for name in (targets.FOLD_FREE, targets.FOLD_COST, targets.CENTROID):
        assert by_name[name].met is None and "no" in by_name[name].reason
    for t in ts:
        assert t.measured and t.reason and t.status in t.line()


def test_constraints_section_on_the_shared_models():
    models = model("cow.obj").parent
    for name in ("kitten.obj", "multibody_inconsistent_winding.stl"):
        model(name)
    rows, notes = constraint_cases.run_constraints(
        models, repeats=1, quick=True, tiny=True, log=lambda s: None
    )
    assert not notes and {r.constraint for r in rows} == set(constraints.CONSTRAINTS)
    _check_rows(rows)
    ts = targets.constraint_targets(rows)
    assert [t.met in (True, False) for t in ts] == [True] * len(ts)  # every outcome definite
    every = targets.evaluate_targets([], [], None, {}, constraints=rows)
    assert [t.name for t in every[-len(ts) :]] == [t.name for t in ts]
    assert targets.evaluate_targets([], [], None, {})[-1].name == targets.FIRST_RECORD


def test_constraints_section_is_rendered_and_spliced_into_a_report(built_in_constraints, tmp_path):
    rows, notes, _ = built_in_constraints
    env = timing.environment()
    res = report.Results(env, True, 1, [], constraints=rows, constraint_notes=notes)
    text = report.render(res, "\nmine\n")
    assert constraints.HEADING in text and "`python -m benchmarks --quick`" in text
    assert "| anchor | torus" in text and "| per body | two spheres" in text
    assert text.index(constraints.HEADING) < text.index(report.KEEP_MARKER)
    assert constraints.HEADING not in report.render(report.Results(env, True, 1, []))

    block = "\n".join(constraints_report.section(rows, notes, "python -m x", env, 1))
    other = "# Benchmarks\n\n## Table 1\n\nt1\n\n## Scale\n\ns\n\n"
    peak = "Peak RSS of the benchmark process: 1 MB.\n\n"
    old = other + peak + report.KEEP_MARKER + "\n\nhand-written\n"
    markers = (report.KEEP_MARKER, *report.OLD_MARKERS)
    once = constraints_report.splice(old, block, markers)
    assert once.index("## Scale") < once.index(constraints.HEADING) < once.index("Peak RSS")
    assert once.endswith(report.KEEP_MARKER + "\n\nhand-written\n") and "t1" in once
    changed = block.replace("python -m x", "python -m y")
    twice = constraints_report.splice(once, changed, markers)
    assert twice == once.replace("python -m x", "python -m y")
    assert twice.count(constraints.HEADING) == 1
    # the section in the middle of a report: what follows it stays
    mid = other.replace("## Scale", block + "\n## Scale")
    assert constraints_report.splice(mid, changed, markers).count("## Scale\n\ns") == 1

    out = tmp_path / "BENCH.md"
    constraints_report.write_section(out, block.splitlines(), markers)
    constraints_report.write_section(out, block.splitlines(), markers)
    written = out.read_text(encoding="utf-8")
    assert written.count(constraints.HEADING) == 1 and report.KEEP_MARKER in written


# -- the report --------------------------------------------------------------------------------
def test_render_writes_every_table_and_keeps_the_hand_written_part(
    small_case, small_rows, tmp_path
):
    prof = profiling.profile_solve(small_case)
    sweep = tables.start_level_sweep(small_case, 1, max_start=1, log=lambda s: None)
    scale_rows = [scale.scale_row(torus(16, 8), (3, 3, 3), repeats=1)]
    latency = {"torus-compression": (0.004, 0.0003)}
    ts = targets.evaluate_targets(small_rows, [_scale_row(0.035)], _arma(), latency)
    res = report.Results(
        timing.environment(),
        True,
        2,
        small_rows,
        tables.table2(small_rows[0]),
        tables.table2_paper_schedule(small_case, 1),
        prof,
        sweep,
        scale_rows,
        _arma(),
        latency,
        ts,
        ["fig5_torus_compression.png"],
        ["a note"],
    )
    text = report.render(res, "\n## My notes\nkeep me\n")
    for heading in (
        "# Benchmarks",
        "## Targets",
        "## Table 1",
        "## Table 2",
        "## Where the time goes",
        "## Start level",
        "## Figures 5-8",
        "## Scale: one volume",
        "## Scale: the 346k",
        "## First progress record",
    ):
        assert heading in text, heading
    assert "`python -m benchmarks --quick`" in text and "> a note" in text
    assert "| Torus compression | estimate" in text and "**MISSED**" in text
    assert "Why missed, and what was tried" in text and "cProfile" in text
    assert "![fig5_torus_compression.png](fig5_torus_compression.png)" in text
    head, tail = text.split(report.KEEP_MARKER)
    assert "## My notes\nkeep me" in tail and "keep me" not in head

    # rewriting a file keeps what follows its marker (the old `isochor bench` one too)
    out = tmp_path / "docs" / "BENCHMARKS.md"
    out.parent.mkdir()
    out.write_text(f"# old\n{report.OLD_MARKERS[0]}\n\nhand-written\n", encoding="utf-8")
    report.write_report(res, out)
    written = out.read_text(encoding="utf-8")
    assert written.count(report.KEEP_MARKER) == 1 and "# old" not in written
    assert written.split(report.KEEP_MARKER)[1] == "\n\nhand-written\n"
    report.write_report(res, out)
    assert out.read_text(encoding="utf-8").split(report.KEEP_MARKER)[1] == "\n\nhand-written\n"
    assert report.kept_part(tmp_path / "missing.md") == ""


def test_figure_is_drawn(small_rows, small_case, tmp_path):
    pytest.importorskip("matplotlib")
    path = tmp_path / "fig5.png"
    assert report.draw_figure(small_rows[0], small_case.size, path) is None
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# -- evaluation at scale -----------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(3, 3, 3), (5, 2, 2)])
def test_scale_row_agrees_with_the_reference(shape, monkeypatch):
    mesh = torus(16, 8)
    row = scale.scale_row(mesh, shape, repeats=1)  # raises if the numbers disagree
    assert row.triangles == 256 and row.t_eval.median > 0 and row.t_reference.median > 0
    # the factored basis and the blocked volume loop, with blocks much smaller than the mesh
    monkeypatch.setattr(lat_mod, "DENSE_LIMIT", 0)
    monkeypatch.setattr(lat_mod, "BASIS_BLOCK", 37)
    monkeypatch.setattr(vol_mod, "BLOCK", 29)
    monkeypatch.setattr(vol_mod, "SMALL", 0)
    row = scale.scale_row(mesh, shape, repeats=1)
    assert row.form == "factored"


def test_armadillo_bend_pins_one_end_and_turns_the_other():
    levels = [box((1.0, 3.0, 2.0))]
    lattice, nodes, fixed = scale.armadillo_bend(levels, shape=(3, 5, 3), angle_deg=30)
    grid = lattice.grid_parameters()
    assert fixed.sum() == 18 and np.all(fixed == np.isin(grid[:, 1], (0.0, 1.0)))
    moved = ~np.all(np.isclose(nodes, lattice.rest_nodes), axis=1)
    assert np.all(moved == np.isclose(grid[:, 1], 1.0))


def test_armadillo_is_skipped_with_the_reason_when_the_model_is_missing(tmp_path):
    arma, why = scale.run_armadillo(tmp_path, repeats=1)
    assert arma is None and scale.ARMADILLO in why and "not found" in why


def test_rewrite_seconds_times_every_repeat_after_a_warm_up(tmp_path, monkeypatch):
    """The export row's timing: the model file given back once untimed, then once per
    repeat; each value the rewrite less its call of the map."""
    import trimesh

    from isochor.core.io import roundtrip

    path = tmp_path / "ball.ply"
    trimesh.creation.icosphere(2).export(path)
    calls = []

    def rewrite(data, suffix, deform, jacobian):
        calls.append(suffix)
        return real(data, suffix, deform, jacobian)

    real = roundtrip.rewrite
    monkeypatch.setattr(roundtrip, "rewrite", rewrite)
    took = scale.rewrite_seconds(path, 3)
    assert calls == [".ply"] * 4 and len(took) == 3 and min(took) >= 0, (calls, took)


def test_first_evaluation_runs_in_a_fresh_process_without_waiting_for_the_kernels():
    from benchmarks.first_evaluation import first_evaluation

    fe = first_evaluation(1)
    (status,) = fe.statuses
    assert status == "loading" or status.startswith("off"), status  # not "ready": no wait
    assert len(fe.first.values) == len(fe.load.values) == len(fe.warm.values) == 1
    assert fe.first.median > 0 and fe.warm.median > 0


# -- the fast evaluation against the straightforward formulas ----------------------------------
def _per_face(vertices, faces, center):
    v = vertices - center
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    grad = np.zeros_like(v)
    np.add.at(grad, faces[:, 0], np.cross(b, c) / 6)
    np.add.at(grad, faces[:, 1], np.cross(c, a) / 6)
    np.add.at(grad, faces[:, 2], np.cross(a, b) / 6)
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6), grad


def _awkward_meshes():
    rng = np.random.default_rng(7)
    sphere = sphere_levels(3)[-1]
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    yield "closed", sphere.vertices, sphere.faces
    yield "open (a hole)", sphere.vertices, sphere.faces[5:]
    flipped = sphere.faces.copy()
    flipped[::7] = flipped[::7, ::-1]
    yield "inconsistent winding", sphere.vertices, flipped
    # two tetrahedra sharing an edge: four faces on that edge; plus an unused vertex
    v = np.vstack([rng.normal(size=(4, 3)), rng.normal(size=(3, 3)) + 2.0, [[9, 9, 9]]])
    t2 = np.array([[0, 4, 1], [0, 1, 5], [1, 4, 5], [0, 5, 4]])  # shares vertices 0, 1
    yield "non-manifold edge", v, np.vstack([tet, t2])
    yield (
        "degenerate and duplicate faces",
        sphere.vertices,
        np.vstack([sphere.faces, sphere.faces[:3], [[0, 0, 1], [2, 3, 3]]]),
    )


@pytest.mark.parametrize("small", [True, False], ids=["whole-array", "blocked"])
def test_volume_operator_equals_the_per_face_formula_on_any_triangles(small, monkeypatch):
    if not small:
        monkeypatch.setattr(vol_mod, "SMALL", 0)
        monkeypatch.setattr(vol_mod, "BLOCK", 17)
    rng = np.random.default_rng(3)
    for name, verts, faces in _awkward_meshes():
        verts = verts + rng.normal(scale=0.01, size=verts.shape)
        center = rng.normal(size=3)
        op = VolumeOperator(faces, len(verts))
        v_ref, g_ref = _per_face(verts, faces, center)
        for layout in (np.ascontiguousarray(verts), np.asfortranarray(verts)):
            v, g = op.value_and_gradient(layout, center)
            assert v == pytest.approx(v_ref, rel=1e-12, abs=1e-14), name
            assert np.allclose(g, g_ref, rtol=1e-12, atol=1e-14), name
            assert op(layout, center) == pytest.approx(v_ref, rel=1e-12, abs=1e-14), name
        v_mean, _ = _per_face(verts, faces, verts.mean(axis=0))
        assert signed_volume(verts, faces) == pytest.approx(v_mean, rel=1e-12, abs=1e-14)


def test_volume_operator_with_more_than_a_million_vertices():
    """Above 2**20 vertices the edge key does not pack into 64 bits: the argsort path."""
    sphere = sphere_levels(2)[-1]
    n = (1 << 21) + 3
    verts = np.zeros((n, 3))
    verts[-len(sphere.vertices) :] = sphere.vertices + 0.1
    faces = sphere.faces + (n - len(sphere.vertices))
    op = VolumeOperator(faces, n)
    v, g = op.value_and_gradient(verts)
    v_ref, g_ref = _per_face(verts, faces, np.zeros(3))
    assert v == pytest.approx(v_ref, rel=1e-12)
    assert np.allclose(g, g_ref, rtol=1e-12, atol=1e-14)


def test_volume_operator_refuses_indices_out_of_range():
    with pytest.raises(ValueError, match="face indices"):
        VolumeOperator(np.array([[0, 1, 5]]), 3)
    op = VolumeOperator(np.zeros((0, 3), dtype=int), 4)
    v, g = op.value_and_gradient(np.ones((4, 3)))
    assert v == 0.0 and g.shape == (4, 3) and not g.any()


def test_basis_output_layout_and_values(monkeypatch):
    rng = np.random.default_rng(4)
    pts = rng.uniform(size=(300, 3))
    lat = Lattice.around(pts, (4, 3, 5))
    nodes = lat.rest_nodes + rng.normal(scale=0.05, size=(lat.n_nodes, 3))
    g = rng.normal(size=(300, 3))
    dense = lat.point_basis(pts)
    monkeypatch.setattr(lat_mod, "DENSE_LIMIT", 0)
    monkeypatch.setattr(lat_mod, "BASIS_BLOCK", 64)
    factored = lat.point_basis(pts)
    for b in (dense, factored):
        out = b.apply(nodes)
        assert out.shape == (300, 3) and out.T.flags.c_contiguous  # coordinate-major rows
        assert np.allclose(out, dense.dense @ nodes, atol=1e-12)
        for gl in (g, np.asfortranarray(g)):
            tr = b.apply_transpose(gl)
            assert tr.shape == (lat.n_nodes, 3) and tr.flags.c_contiguous
            assert np.allclose(tr, dense.dense.T @ g, atol=1e-12)


def test_beyond_the_solve_row_takes_the_slowest_models_median(unit_of_100ms):
    from benchmarks.first_use import BEYOND_SOLVE, Cold, beyond_solve_row

    def run(wall, solve, ok=True):
        return Cold(wall, solve, 100.0, False, ok)

    runs = {
        "a.obj": [run(0.40, 0.02), run(0.42, 0.02), run(0.9, 0.02, ok=False)],
        "b.obj": [run(0.70, 0.10), run(0.66, 0.10), run(0.68, 0.10)],
    }
    row = beyond_solve_row("beyond", runs)
    assert "b.obj" in row.what and row.timing.median == pytest.approx(0.58)
    assert row.met is (BEYOND_SOLVE >= 0.58) and "a.obj 390 (380-400) ms" in row.why
    slow = beyond_solve_row("beyond", {"c.obj": [run(0.9, 0.1)]})
    assert slow.met is False and slow.timing.median == pytest.approx(0.8)
    none = beyond_solve_row("beyond", {"d.obj": [run(1.0, None, ok=False)]})
    assert none.met is None and none.timing is None
