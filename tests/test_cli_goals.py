"""The command-line contract of issue 11 (what a solve holds), tested out of process: the real
``isochor solve`` in a temporary folder, as a user runs it.

The options ``--target RATIO``, ``--preserve {total,per-body}``, ``--keep-centroid``,
``--anchor {far-side,none}`` and ``--fold-guard`` override the scenario's version 2 keys.
Every run in this file is held to the contract:

- exit 0, 1, 2 or 3, no hang, no traceback; every line on standard error starts ``isochor:``;
  exits 1 and 2 print exactly one line, exit 3 exactly one line besides warnings and notes;
- exit 0 or 3 writes the report, and its ``converged`` says which;
- **exit 0 is never a lie**: converged true, nothing folded, ``|target_error|`` within the
  volume tolerance, the final volume of the same sign as the original (and with
  ``per-body`` every body within the tolerance, with ``keep_centroid`` the centre of mass
  within a fifth of the tolerance of the object's size).

The solves run a few at a time (one per core) so that the file stays well under a minute.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cache
from math import comb
from pathlib import Path

import numpy as np
import pytest

from isochor.core.defaults import TOL_VOLUME
from isochor.core.goal.spec import RATIO_RANGE
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.edits import MAX_MOVE
from isochor.core.scenario.problem import build
from tests import test_contract as contract
from tests.models import available, model

# -- running the command ----------------------------------------------------------------
ENV = {k: v for k, v in os.environ.items() if k != "ISOCHOR_DEBUG"}
#: the console script next to this interpreter, else ``python -m isochor``
_SCRIPT = Path(sys.executable).with_name("isochor")
COMMAND = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "isochor"]
TIMEOUT = 120.0
WORKERS = max(1, min(4, os.cpu_count() or 1))
FACES = {f"{a} {s}" for a in "xyz" for s in ("min", "max")}
RANGE = f"{RATIO_RANGE[0]:g}..{RATIO_RANGE[1]:g}"  # "0.05..20"

SMALL_TORUS = {"builtin": "torus", "n_levels": 3}  # 256 triangles
TINY_TORUS = {"builtin": "torus", "n_levels": 1}  # 16 triangles
#: the independent fold check: (point, triangle) pairs spent on winding numbers, and at most
#: this many random points in the model's bounding box
WINDING_BUDGET = 8_000_000
MAX_SAMPLES = 50_000


@dataclass(repr=False)
class Run(contract.Run):
    """A contract run with the report it wrote and the tolerance it was solved to."""

    tol: float = TOL_VOLUME
    report: dict | None = None
    folder: Path | None = None

    @property
    def problems(self) -> list[str]:
        """The lines that are not warnings or notes."""
        return [
            line
            for line in self.lines
            if not line.startswith(("isochor: warning: ", "isochor: note: "))
        ]

    def __repr__(self) -> str:
        status = "TIMED OUT" if self.returncode is None else f"exit {self.returncode}"
        keys = (
            "converged",
            "target_error",
            "folded",
            "held",
            "body_volumes",
            "centroid_shift",
            "message",
        )
        summary = {k: self.report.get(k) for k in keys} if self.report else None
        return (
            f"`isochor {' '.join(self.argv)}` -> {status} after {self.elapsed:.1f} s; "
            f"stderr: {self.stderr[-1500:]!r}; report: {summary}"
        )


def isochor(*args, cwd: Path, timeout: float = TIMEOUT) -> Run:
    """Run the ``isochor`` command in ``cwd``; never raises on a timeout."""
    argv = [str(a) for a in args]
    t0 = time.monotonic()
    try:
        proc = subprocess.run(
            [*COMMAND, *argv],
            cwd=cwd,
            env=ENV,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            timeout=timeout,
            check=False,
        )
        code, out, err = proc.returncode, proc.stdout, proc.stderr
    except subprocess.TimeoutExpired as exc:
        code, out, err = None, exc.stdout or b"", exc.stderr or b""
    dt = time.monotonic() - t0
    return Run(argv, code, out.decode("utf-8", "replace"), err.decode("utf-8", "replace"), dt)


def contract_problems(run: Run) -> list[str]:
    """What ``run`` did against the contract (see the module notes)."""
    if run.returncode is None:
        return [f"hung: killed after {run.elapsed:.0f} s"]
    out = []
    if run.returncode not in (0, 1, 2, 3):
        out.append(f"exit status {run.returncode}")
    if "Traceback" in run.stderr:
        out.append("a traceback on stderr")
    stray = [line for line in run.lines if not line.startswith("isochor: ")]
    if stray:
        out.append(f"stderr lines not starting 'isochor: ': {stray[:3]!r}")
    if run.returncode in (1, 2) and len(run.lines) != 1:
        out.append(f"exit {run.returncode} with {len(run.lines)} stderr lines, not 1")
    if run.returncode == 3 and len(run.problems) != 1:
        out.append(f"exit 3 with {len(run.problems)} stderr lines (warnings aside), not 1")
    if run.returncode == 0 and run.problems:
        out.append(f"exit 0 but stderr says {run.problems!r}")
    if run.returncode in (0, 3):
        if run.report is None:
            out.append("no report written")
        elif run.report.get("converged") is not (run.returncode == 0):
            out.append(f"exit {run.returncode} but converged is {run.report.get('converged')}")
        elif run.returncode == 3 and not run.report.get("message"):
            out.append("exit 3 but the report's message is empty")
    if run.returncode == 0 and run.report is not None:
        out += success_problems(run.report, run.tol)
    return out


def success_problems(r: dict, tol: float) -> list[str]:
    """Why a report cannot be the report of a success (exit 0)."""
    out = []
    if r["converged"] is not True:
        out.append("converged is not true")
    if r["folded"] is None or r["folded"]["fraction"] != 0:
        out.append(f"folded {r['folded']}")
    if not abs(r["target_error"]) <= tol:
        out.append(f"|target_error| {r['target_error']:.3g} > tolerance {tol:g}")
    if not r["volume_final"] * r["volume_original"] > 0:
        out.append(f"volume {r['volume_original']:.6g} -> {r['volume_final']:.6g}: sign changed")
    if r["preserve"] == "per-body":
        bad = [b for b in r["body_volumes"] if not abs(b["error"]) <= tol]
        if not r["body_volumes"] or bad:
            out.append(f"per-body: bodies off the tolerance {bad or r['body_volumes']}")
    if r["keep_centroid"] and not (
        r["centroid_shift"] is not None and r["centroid_shift"] <= 0.2 * tol
    ):
        out.append(f"keep_centroid: centroid_shift {r['centroid_shift']}")
    return out


def check(run: Run) -> Run:
    problems = contract_problems(run)
    assert not problems, f"{run}\n  " + "\n  ".join(problems)
    return run


def solve(
    folder: Path,
    doc: dict | None = None,
    *args,
    name: str = "s",
    out: str | None = None,
    timeout: float = TIMEOUT,
) -> Run:
    """``isochor solve NAME.json ARGS --report NAME.r.json -q`` in ``folder`` (the scenario
    written there first; without one, ARGS say what to solve); checks the contract."""
    what: list = []
    tol = TOL_VOLUME
    if doc is not None:
        (folder / f"{name}.json").write_text(json.dumps(doc, indent=1))
        what = [f"{name}.json"]
        tol = doc.get("tolerance", {}).get("volume", TOL_VOLUME)
    report = folder / f"{name}.r.json"
    extra = ["--out", out] if out else []
    run = isochor(
        "solve", *what, *args, *extra, "--report", report.name, "-q", cwd=folder, timeout=timeout
    )
    run.tol, run.folder = tol, folder
    if run.returncode in (0, 3) and report.is_file():
        run.report = json.loads(report.read_text())
    check(run)
    assert run.returncode in (0, 3) or not report.exists(), f"exit {run.returncode} wrote {report}"
    return run


def solve_all(folder: Path, jobs: list[dict]) -> list[Run]:
    """:func:`solve` for each job (its keyword arguments, ``args`` the options), a few at a
    time; every job needs its own ``name``."""
    names = [j["name"] for j in jobs]
    assert len(set(names)) == len(names), names

    def one(job: dict) -> Run:
        job = dict(job)
        return solve(folder, job.pop("scenario", None), *job.pop("args", ()), **job)

    with ThreadPoolExecutor(WORKERS) as pool:
        return list(pool.map(one, jobs))


def one_line(run: Run, status: int, *names: str) -> str:
    """The run ended with ``status`` and one line naming all of ``names``."""
    assert run.returncode == status and len(run.lines) == 1, run
    line = run.lines[0]
    assert line.startswith("isochor: "), run
    missing = [n for n in names if n not in line]
    assert not missing, f"does not name {missing}: {run}"
    return line


# -- scenarios ------------------------------------------------------------------------------
def scenario(
    model_: dict,
    nodes=(3, 3, 3),
    moves=(),
    pins=(),
    version: int = 1,
    **keys,
) -> dict:
    doc = {
        "format": "isochor-scenario",
        "version": version,
        "model": dict(model_),
        "lattice": {"nodes": list(nodes), "padding": 0.05},
        "moves": [dict(m) for m in moves],
        "pins": [p if isinstance(p, dict) else list(p) for p in pins],
    }
    doc.update(keys)
    return doc


def cow() -> dict:
    return {"path": str(model("cow.obj"))}


def named_model(name: str) -> dict:
    """``torus`` (256 triangles) or ``cow`` (5804; skips when the shared models are absent)."""
    return SMALL_TORUS if name == "torus" else cow()


@dataclass(frozen=True)
class Rest:
    """The rest lattice of a scenario (as the command line fits it), its full mesh and
    points inside the model."""

    shape: tuple[int, int, int]
    origin: np.ndarray
    axes: np.ndarray
    nodes: np.ndarray
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)

    def index(self, i: int, j: int, k: int) -> int:
        _, m, n = self.shape
        return (i * m + j) * n + k

    @property
    def size(self) -> float:
        return float(np.linalg.norm(self.axes, axis=1).max())

    @property
    def interior(self) -> np.ndarray:
        """Random points inside the model (by winding numbers computed here), seeded."""
        return _interior(self.vertices.tobytes(), self.faces.tobytes())


@cache
def _rest(key: str) -> Rest:
    doc = json.loads(key)
    problem = build(Scenario.from_dict(doc))
    lat = problem.surface.lattice
    return Rest(
        tuple(lat.shape),
        np.array(lat.origin, dtype=float),
        np.array(lat.axes, dtype=float),
        np.array(lat.rest_nodes, dtype=float),
        np.array(problem.surface.full.vertices, dtype=float),
        np.array(problem.surface.full.faces, dtype=np.int64),
    )


@cache
def _interior(vertices: bytes, faces: bytes) -> np.ndarray:
    v = np.frombuffer(vertices).reshape(-1, 3)
    f = np.frombuffer(faces, dtype=np.int64).reshape(-1, 3)
    count = min(MAX_SAMPLES, WINDING_BUDGET // len(f))
    points = np.random.default_rng(11).uniform(v.min(axis=0), v.max(axis=0), (count, 3))
    return points[np.abs(winding_numbers(v, f, points)) > 0.5]


def rest_of(model_: dict, nodes=(3, 3, 3)) -> Rest:
    """The rest lattice for ``model_`` with ``nodes`` (built in process, no moves)."""
    return _rest(json.dumps(scenario(model_, nodes), sort_keys=True))


def layer(shape, axis: int, index: int) -> list[list[int]]:
    """The nodes (i, j, k) of one layer of the lattice."""
    return [
        [i, j, k]
        for i in range(shape[0])
        for j in range(shape[1])
        for k in range(shape[2])
        if (i, j, k)[axis] == index
    ]


# -- an independent det J ------------------------------------------------------------------
def _bernstein(n: int, t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, dtype=float)[:, None]
    i = np.arange(n + 1)
    return np.array([comb(n, k) for k in i], dtype=float) * t**i * (1 - t) ** (n - i)


def _bernstein_dt(n: int, t: np.ndarray) -> np.ndarray:
    out = np.zeros((len(t), n + 1))
    if n:
        low = _bernstein(n - 1, t)
        out[:, 1:] += low
        out[:, :-1] -= low
    return n * out


def det_j(rest: Rest, nodes, points: np.ndarray) -> np.ndarray:
    """det of the Jacobian of the FFD with ``nodes`` at ``points``, computed here from the
    Bernstein form (not with isochor's lattice code): 1 at rest, <= 0 where folded."""
    uvw = (points - rest.origin) @ np.linalg.inv(rest.axes)
    grid = np.asarray(nodes, dtype=float).reshape(*rest.shape, 3)
    b = [_bernstein(s - 1, uvw[:, a]) for a, s in enumerate(rest.shape)]
    d = [_bernstein_dt(s - 1, uvw[:, a]) for a, s in enumerate(rest.shape)]
    cols = []
    for a in range(3):
        f = [d[c] if c == a else b[c] for c in range(3)]
        cols.append(np.einsum("pi,pj,pk,ijkc->pc", f[0], f[1], f[2], grid))
    return np.linalg.det(np.stack(cols, axis=-1)) / np.linalg.det(rest.axes)


def winding_numbers(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The winding number of a closed triangle mesh at each point (solid angles, Van
    Oosterom and Strackee): about 1 inside, 0 outside."""
    a0, b0, c0 = (vertices[faces[:, n]] for n in range(3))
    out = np.empty(len(points))
    for s in range(0, len(points), 64):
        p = points[s : s + 64, None, :]
        a, b, c = a0 - p, b0 - p, c0 - p
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("pfi,pfi->pf", a, b) * lc
            + np.einsum("pfi,pfi->pf", b, c) * la
            + np.einsum("pfi,pfi->pf", c, a) * lb
        )
        out[s : s + 64] = np.arctan2(num, den).sum(axis=1) / (2 * np.pi)
    return out


def independent_folds(run: Run, rest: Rest) -> dict:
    """det J for the reported nodes at the model's vertices and at random points inside it,
    computed here: the share folded (det J <= 0) of each and the lowest det J."""
    nodes = run.report["nodes"]
    at_vertices = det_j(rest, nodes, rest.vertices)
    inside = det_j(rest, nodes, rest.interior)
    return {
        "vertex_fraction": float(np.mean(at_vertices <= 0)),
        "interior_fraction": float(np.mean(inside <= 0)) if len(inside) else 0.0,
        "interior_points": len(inside),
        "min_det_j": float(min(at_vertices.min(), inside.min(initial=np.inf))),
    }


#: a fold too small for the report's samples (about 2000 points in the bounding box) to be
#: expected to see: this share of the inside points, det J no lower than this
SLIVER_SHARE, SLIVER_DET = 1e-3, -0.05


def check_folds_independently(run: Run, rest: Rest) -> dict:
    """Always: the folded share of the vertices is what the report says. On exit 0: det J
    is positive at every vertex and, but for a sliver between the report's samples, at every
    sampled inside point."""
    if run.report is None:
        return {}
    mine = independent_folds(run, rest)
    reported = run.report["folded"]
    assert abs(mine["vertex_fraction"] - reported["vertex_fraction"]) <= 2 / len(rest.vertices), (
        f"vertex fraction folded: {mine} measured here, {reported} reported: {run}"
    )
    if run.returncode == 0:
        sliver = mine["interior_fraction"] <= SLIVER_SHARE and mine["min_det_j"] >= SLIVER_DET
        assert mine["vertex_fraction"] == 0 and sliver, (
            f"exit 0 but folded: {mine} measured here: {run}"
        )
    return mine


# == 1. folds never pass ====================================================================
@pytest.mark.parametrize("name", ["torus", "cow"])
def test_top_layer_squashed_below_the_pinned_bottom_is_exit_3_folded(tmp_path, name):
    """Every k=2 node moved down by 1.5 lattice heights, below the pinned k=0 layer: the
    model is turned inside out whatever the solver does; with the fold guard and without."""
    m = named_model(name)
    rest = rest_of(m)
    h = rest.axes[2, 2]
    doc = scenario(
        m,
        moves=[{"node": n, "by": [0, 0, -1.5 * h]} for n in layer(rest.shape, 2, 2)],
        pins=layer(rest.shape, 2, 0),
    )
    runs = solve_all(
        tmp_path,
        [
            {"scenario": doc, "name": "guarded"},
            {"scenario": doc, "args": ["--no-fold-guard"], "name": "unguarded"},
        ],
    )
    for run in runs:
        assert run.returncode == 3, run
        assert "folded" in run.problems[0], run
        assert run.report["converged"] is False, run
        assert run.report["folded"]["fraction"] > 0, run
        assert run.report["folded"]["min_det_j"] < 0, run
        check_folds_independently(run, rest)
    assert runs[1].report["fold_guard"] is False and runs[0].report["fold_guard"] is True


@pytest.mark.parametrize("name, node, depth", [("torus", [1, 1, 2], 2.0), ("cow", [0, 0, 2], 3.0)])
def test_one_node_pushed_through_the_pinned_opposite_face(tmp_path, name, node, depth):
    """A top node pushed two or three lattice heights below the pinned bottom face. The
    lattice may bend around it without folding the model: exit 0 only when det J (computed
    here) is positive at every vertex and inside point, otherwise exit 3."""
    m = named_model(name)
    rest = rest_of(m)
    moves = [{"node": node, "by": [0, 0, -depth * rest.axes[2, 2]]}]
    run = solve(tmp_path, scenario(m, moves=moves, pins=layer(rest.shape, 2, 0)))
    assert run.returncode in (0, 3), run
    check_folds_independently(run, rest)


#: which variants of the fold-back test run on which model
FOLD_BACK = {
    "torus": ["forced", "forced-unguarded", "first-pinned", "free"],
    "cow": ["forced", "first-pinned"],
}


@pytest.mark.parametrize("name", ["torus", "cow"])
def test_last_layer_folded_back_over_the_body(tmp_path, name):
    """A 5x2x2 lattice, its last layer moved in -x a quarter of the lattice past the first.

    - forced: first layer pinned, the middle layers held to x-motion only (axis pins "yz"):
      x(u) must run backwards somewhere, the model is folded: exit 3, with the guard or not;
    - first-pinned: the rest free, the lattice may loop out of the way; free: nothing
      pinned, it may slide. Either: exit 0 only with det J positive everywhere.
    """
    m = named_model(name)
    rest = rest_of(m, (5, 2, 2))
    moves = [{"node": n, "by": [-1.25 * rest.axes[0, 0], 0, 0]} for n in layer(rest.shape, 0, 4)]
    first = layer(rest.shape, 0, 0)
    held = [{"node": n, "axes": "yz"} for i in (1, 2, 3) for n in layer(rest.shape, 0, i)]
    forced = scenario(m, (5, 2, 2), moves, first + held, version=2)
    variants = {
        "forced": {"scenario": forced},
        "forced-unguarded": {"scenario": forced, "args": ["--no-fold-guard"]},
        "first-pinned": {"scenario": scenario(m, (5, 2, 2), moves, first)},
        "free": {"scenario": scenario(m, (5, 2, 2), moves)},
    }
    names = FOLD_BACK[name]
    runs = dict(zip(names, solve_all(tmp_path, [dict(variants[n], name=n) for n in names])))
    for variant, run in runs.items():
        if variant.startswith("forced"):
            assert run.returncode == 3, run
            assert "folded" in run.problems[0], run
            assert run.report["folded"]["fraction"] > 0, run
        assert run.returncode in (0, 3), run
        check_folds_independently(run, rest)


def test_a_move_of_a_thousand_model_sizes_never_passes(tmp_path):
    """A corner moved 1000 model sizes away (under the 1000-lattice-size limit): exit 3
    (folded or not converged) or exit 1 with one line, never exit 0; just over the limit:
    exit 1, one line naming the move."""
    rest = rest_of(TINY_TORUS, (2, 2, 2))
    far = 1000 * float(np.ptp(rest.vertices, axis=0).max())
    assert far < MAX_MOVE * rest.size
    over = 1.001 * MAX_MOVE * rest.size
    far_run, over_run = solve_all(
        tmp_path,
        [
            {
                "scenario": scenario(TINY_TORUS, (2, 2, 2), [{"node": [1, 1, 1], "by": by}]),
                "name": n,
            }
            for n, by in (("far", [far, 0, 0]), ("over", [over, 0, 0]))
        ],
    )
    measured = independent_folds(far_run, rest) if far_run.report else None
    assert far_run.returncode in (1, 3), f"{far_run}; det J measured here: {measured}"
    if far_run.returncode == 1:
        one_line(far_run, 1)
    one_line(over_run, 1, "moves[0]")


@pytest.mark.parametrize("pinned", [False, True], ids=["free", "bottom-pinned"])
@pytest.mark.parametrize("name", ["torus", "cow"])
def test_shrink_to_a_tenth_and_grow_tenfold(tmp_path, name, pinned):
    """Targets 0.1 and 10: exit 0 only with nothing folded (det J checked here too) and the
    target met, otherwise exit 3. Each model gets each ratio by --target once and by the
    scenario's key once (alternating with the pins)."""
    m = named_model(name)
    rest = rest_of(m)
    pins = layer(rest.shape, 2, 0) if pinned else []
    jobs = []
    for ratio in (0.1, 10.0):
        if (ratio == 0.1) != pinned:
            jobs.append({"scenario": scenario(m, pins=pins), "args": ["--target", ratio]})
        else:
            jobs.append({"scenario": scenario(m, pins=pins, target_volume_ratio=ratio)})
        jobs[-1]["name"] = f"r{ratio:g}"
    for run, ratio in zip(solve_all(tmp_path, jobs), (0.1, 10.0)):
        assert run.returncode in (0, 3), run
        r = run.report
        assert r["target_volume_ratio"] == ratio, run
        assert r["volume_target"] == pytest.approx(ratio * r["volume_original"], rel=1e-12), run
        check_folds_independently(run, rest)


def test_the_target_option_and_the_scenario_key_solve_alike(tmp_path):
    by_option, by_key = solve_all(
        tmp_path,
        [
            {"scenario": scenario(SMALL_TORUS), "args": ["--target", "10"], "name": "option"},
            {"scenario": scenario(SMALL_TORUS, target_volume_ratio=10), "name": "key"},
        ],
    )
    assert by_option.returncode == by_key.returncode, (by_option, by_key)
    assert by_option.report["target_volume_ratio"] == by_key.report["target_volume_ratio"] == 10
    assert by_option.report["nodes"] == by_key.report["nodes"], (by_option, by_key)


# == 2. ratios ==============================================================================
def test_the_ratio_bounds_either_succeed_or_exit_3(tmp_path):
    runs = solve_all(
        tmp_path,
        [
            {"scenario": scenario(SMALL_TORUS), "args": ["--target", t], "name": f"t{t}"}
            for t in RATIO_RANGE
        ],
    )
    for run, ratio in zip(runs, RATIO_RANGE):
        assert run.returncode in (0, 3), run
        assert run.report["target_volume_ratio"] == ratio, run
        if run.returncode == 0:
            final = run.report["volume_final"] / run.report["volume_original"]
            assert final == pytest.approx(ratio, rel=run.tol), run


BAD_RATIOS = ["0.01", "25", "1e-6", "0", "-1", "nan"]


def test_a_target_option_out_of_range_is_one_line_naming_the_range(tmp_path):
    doc = scenario(SMALL_TORUS)
    jobs = [
        {"scenario": doc, "args": ["--target", t], "name": f"t{n}"}
        for n, t in enumerate(BAD_RATIOS)
    ]
    jobs.append({"scenario": doc, "args": ["--target", "abc"], "name": "word"})
    runs = solve_all(tmp_path, jobs)
    for run in runs[:-1]:
        one_line(run, 1, "--target", RANGE)
    one_line(runs[-1], 2, "--target", "abc")  # not a number at all: argparse's usage error
    assert not list(tmp_path.glob("*.r.json"))


#: (ratio as JSON text, what the one line must name besides the file)
SCENARIO_RATIOS = [
    ("0.01", ["target_volume_ratio", RANGE]),
    ("25", ["target_volume_ratio", RANGE]),
    ("1e-6", ["target_volume_ratio", RANGE]),
    ("0", ["target_volume_ratio"]),
    ("-1", ["target_volume_ratio"]),
    ("NaN", ["NaN"]),  # not JSON: the file is refused as JSON
]


@pytest.fixture(scope="module")
def scenario_ratio_runs(tmp_path_factory) -> dict[str, Run]:
    """``isochor solve`` on a scenario file with each of :data:`SCENARIO_RATIOS` (run once
    for the tests that read them)."""
    folder = tmp_path_factory.mktemp("ratios")
    doc = json.dumps(scenario(SMALL_TORUS, target_volume_ratio="@ratio@"))
    for n, (text, _) in enumerate(SCENARIO_RATIOS):
        (folder / f"r{n}.json").write_text(doc.replace('"@ratio@"', text))

    def one(n: int) -> Run:
        return isochor("solve", f"r{n}.json", "-q", cwd=folder)

    with ThreadPoolExecutor(WORKERS) as pool:
        runs = list(pool.map(one, range(len(SCENARIO_RATIOS))))
    return {text: run for (text, _), run in zip(SCENARIO_RATIOS, runs)}


def test_a_scenario_ratio_out_of_range_is_one_line_naming_the_key(scenario_ratio_runs):
    for text, names in SCENARIO_RATIOS:
        one_line(check(scenario_ratio_runs[text]), 1, *names)


@pytest.mark.parametrize("ratio", ["0.01", "25", "1e-6", "0", "-1"])
def test_a_scenario_ratio_message_states_the_range_that_is_accepted(scenario_ratio_runs, ratio):
    """The one line states the range a ratio must be in, 0.05..20, and no other."""
    line = one_line(check(scenario_ratio_runs[ratio]), 1, "target_volume_ratio")
    assert RANGE in line and "1e+06" not in line, line


# == 3. anchor ==============================================================================
def test_a_one_node_drag_holds_the_far_face_unless_anchor_none(tmp_path):
    m = {"path": str(available("cow.obj"))} if available("cow.obj") else SMALL_TORUS
    rest = rest_of(m)
    move = np.array([0.3 * rest.axes[0, 0], 0.0, 0.2 * rest.axes[2, 2]])
    doc = scenario(m, moves=[{"node": [2, 1, 1], "by": move.tolist()}])
    v2 = scenario(m, moves=doc["moves"], version=2, anchor="none")
    anchored, drifting, overridden = solve_all(
        tmp_path,
        [
            {"scenario": doc, "name": "default"},
            {"scenario": doc, "args": ["--anchor", "none"], "name": "none"},
            {"scenario": v2, "args": ["--anchor", "far-side"], "name": "overridden"},
        ],
    )
    far = [rest.index(*n) for n in layer(rest.shape, 0, 0)]
    size = float(np.linalg.norm(move))

    def far_motion(run: Run) -> float:
        nodes = np.asarray(run.report["nodes"])
        return float(np.linalg.norm(nodes[far] - rest.nodes[far], axis=1).max()) / size

    for run in (anchored, overridden):
        assert run.returncode == 0, run
        r = run.report
        assert r["anchor"] == "far-side" and r["held"]["face"] == "x min", run
        nodes = np.asarray(r["nodes"])
        held = [rest.index(*n) for n in r["held"]["nodes"]]
        assert sorted(held) == sorted(far), run
        assert np.array_equal(nodes[held], rest.nodes[held]), run
        assert far_motion(run) < 0.1, run
        moved = rest.index(2, 1, 1)
        assert np.allclose(nodes[moved], rest.nodes[moved] + move, rtol=0, atol=1e-9 * size)
    assert drifting.returncode in (0, 3), drifting
    r = drifting.report
    assert r["anchor"] == "none" and r["held"] == {"face": None, "nodes": []}, drifting
    assert far_motion(drifting) > far_motion(anchored), (drifting, anchored)
    assert anchored.report["held"]["face"] in FACES


# == 4. per body ============================================================================
def _two_spheres(folder: Path) -> tuple[Path, list[float]]:
    trimesh = pytest.importorskip("trimesh")
    big = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    small = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    small.apply_translation([2.5, 0.0, 0.0])
    path = folder / "two.obj"
    trimesh.util.concatenate([big, small]).export(str(path))
    return path, [float(big.volume), float(small.volume)]


def _body_volumes(path: Path) -> list[float]:
    """The volumes of the bodies of a mesh file, by trimesh, largest first."""
    import trimesh

    mesh = trimesh.load_mesh(str(path), process=True)
    return sorted((float(b.volume) for b in mesh.split(only_watertight=False)), reverse=True)


def test_two_spheres_squashed_keep_each_volume_per_body(tmp_path, record_property):
    path, volumes = _two_spheres(tmp_path)
    m = {"path": path.name}
    rest = rest_of({"path": str(path)})
    h = rest.axes[2, 2]
    moves = [{"node": n, "by": [0, 0, -0.3 * h]} for n in layer(rest.shape, 2, 2)]
    pins = layer(rest.shape, 2, 0)
    total = scenario(m, moves=moves, pins=pins)
    keyed = scenario(m, moves=moves, pins=pins, version=2, preserve="per-body")
    runs = solve_all(
        tmp_path,
        [
            {
                "scenario": total,
                "args": ["--preserve", "per-body"],
                "name": "option",
                "out": "o1.obj",
            },
            {"scenario": keyed, "name": "key", "out": "o2.obj"},
            {"scenario": total, "name": "total"},
            {"scenario": keyed, "args": ["--preserve", "total"], "name": "overridden"},
        ],
    )
    for run, out in zip(runs[:2], ("o1.obj", "o2.obj")):
        assert run.returncode == 0, run
        r = run.report
        assert r["preserve"] == "per-body" and r["bodies"] == 2, run
        assert len(r["body_volumes"]) == 2, run
        for body, original in zip(sorted(r["body_volumes"], key=lambda b: -b["original"]), volumes):
            assert body["original"] == pytest.approx(original, rel=1e-6), run
            assert abs(body["error"]) <= run.tol, run
        # the file written, measured by trimesh: each sphere kept its own volume
        for final, original in zip(_body_volumes(tmp_path / out), volumes):
            assert abs(final / original - 1) <= run.tol, (final, original, run)
    assert runs[0].report["nodes"] == runs[1].report["nodes"]
    for run in runs[2:]:
        assert run.returncode == 0, run
        r = run.report
        assert r["preserve"] == "total" and len(r["body_volumes"]) == 2, run
        errors = [b["error"] for b in r["body_volumes"]]
        assert all(math.isfinite(e) for e in errors), run
        record_property(f"{run.argv[1]} body errors (total kept)", errors)
    assert runs[2].report["nodes"] == runs[3].report["nodes"]


def test_a_repaired_multibody_model_keeps_each_body(tmp_path):
    path = model("multibody_inconsistent_winding.stl")
    rest = rest_of({"path": str(path)})
    h = rest.axes[2, 2]
    doc = scenario(
        {"path": str(path)},
        moves=[{"node": n, "by": [0, 0, -0.3 * h]} for n in layer(rest.shape, 2, 2)],
        pins=layer(rest.shape, 2, 0),
    )
    run = solve(tmp_path, doc, "--preserve", "per-body")
    assert run.returncode == 0, run
    r = run.report
    assert r["preserve"] == "per-body" and len(r["body_volumes"]) == r["bodies"] >= 2, run
    assert all(abs(b["error"]) <= run.tol for b in r["body_volumes"]), run


# == 5. centroid ============================================================================
def test_club_bend_keeps_its_centroid_with_keep_centroid(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    kept, free = solve_all(
        tmp_path,
        [
            {"args": ["--example", "club-bend", "--keep-centroid"], "name": "kept", "out": "k.ply"},
            {"args": ["--example", "club-bend"], "name": "free", "out": "f.ply"},
        ],
    )
    assert kept.returncode == 0, kept
    assert kept.report["keep_centroid"] is True, kept
    assert kept.report["centroid_shift"] is not None, kept
    assert kept.report["centroid_shift"] <= 1e-4, kept
    assert free.returncode == 0, free
    assert free.report["keep_centroid"] is False and free.report["centroid_shift"] is None, free
    # measured by trimesh on the written meshes, against the rest club
    from isochor.core.scenario.shapes import builtin_levels

    club = builtin_levels("club")[-1]
    rest = trimesh.Trimesh(club.vertices, club.faces, process=False)
    size = float(np.ptp(club.vertices, axis=0).max())

    def shift(name: str) -> float:
        mesh = trimesh.load_mesh(str(tmp_path / name), process=False)
        return float(np.linalg.norm(mesh.center_mass - rest.center_mass)) / size

    assert shift("k.ply") <= 1e-4, shift("k.ply")
    assert shift("f.ply") > 10 * shift("k.ply"), (shift("f.ply"), shift("k.ply"))


# == 6. per-axis pins ======================================================================
def test_axis_pins_hold_their_axes_only(tmp_path):
    rest = rest_of(SMALL_TORUS)
    w, h = rest.axes[0, 0], rest.axes[2, 2]
    doc = scenario(
        SMALL_TORUS,
        moves=[{"node": [2, 2, 2], "by": [0.3 * w, 0.1 * w, -0.2 * h]}],
        pins=[
            *layer(rest.shape, 0, 0),
            {"node": [2, 2, 1], "axes": "z"},
            {"node": [1, 1, 1], "axes": "yx"},
        ],
        version=2,
    )
    run = solve(tmp_path, doc)
    assert run.returncode == 0, run
    nodes = np.asarray(run.report["nodes"])
    z_only, xy = rest.index(2, 2, 1), rest.index(1, 1, 1)
    assert nodes[z_only, 2] == rest.nodes[z_only, 2], run  # exactly
    assert np.abs(nodes[z_only, :2] - rest.nodes[z_only, :2]).max() > 1e-3 * w, run
    assert np.array_equal(nodes[xy, :2], rest.nodes[xy, :2]), run
    assert abs(nodes[xy, 2] - rest.nodes[xy, 2]) > 1e-6 * h, run


def test_bad_axis_pins_and_version_mixups_are_one_line(tmp_path):
    base = scenario(SMALL_TORUS, moves=[{"node": [2, 2, 2], "by": [0.1, 0, 0]}])
    v2_key_in_v1 = dict(base, pins=[[0, 0, 0]], preserve="per-body")
    jobs = [
        {"scenario": dict(base, version=2, pins=[{"node": [1, 1, 1], "axes": "q"}]), "name": "q"},
        {"scenario": dict(base, version=2, pins=[{"node": [1, 1, 1], "axes": ""}]), "name": "e"},
        {"scenario": dict(base, pins=[{"node": [1, 1, 1], "axes": "z"}]), "name": "v1pin"},
        {"scenario": v2_key_in_v1, "name": "v1key"},
        {"scenario": dict(base, pins=[[0, 0, 0], [0, 2, 0]]), "name": "v1"},
    ]
    q, empty, v1pin, v1key, v1 = solve_all(tmp_path, jobs)
    one_line(q, 1, "q.json", "pins[0].axes")
    one_line(empty, 1, "pins[0].axes")
    one_line(v1pin, 1, "pins[0]", '"version": 2')
    one_line(v1key, 1, "preserve", '"version": 2')
    assert v1.returncode == 0, v1  # a version 1 scenario without the new keys still solves
    assert v1.report["preserve"] == "total" and v1.report["anchor"] == "far-side", v1


def test_the_options_override_every_scenario_key(tmp_path):
    doc = scenario(
        SMALL_TORUS,
        moves=[{"node": [2, 1, 1], "by": [0.2, 0.0, 0.0]}],
        version=2,
        target_volume_ratio=2.0,
        preserve="per-body",
        keep_centroid=True,
        anchor="none",
        fold_guard=False,
    )
    options = [
        "--target",
        "0.5",
        "--preserve",
        "total",
        "--no-keep-centroid",
        "--anchor",
        "far-side",
        "--fold-guard",
    ]
    as_written, overridden = solve_all(
        tmp_path,
        [{"scenario": doc, "name": "file"}, {"scenario": doc, "args": options, "name": "cli"}],
    )
    assert as_written.returncode in (0, 3) and overridden.returncode in (0, 3)
    got = {k: as_written.report[k] for k in ("preserve", "keep_centroid", "anchor", "fold_guard")}
    assert got == {
        "preserve": "per-body",
        "keep_centroid": True,
        "anchor": "none",
        "fold_guard": False,
    }
    assert as_written.report["target_volume_ratio"] == 2.0
    r = overridden.report
    got = {k: r[k] for k in ("preserve", "keep_centroid", "anchor", "fold_guard")}
    assert got == {
        "preserve": "total",
        "keep_centroid": False,
        "anchor": "far-side",
        "fold_guard": True,
    }
    assert r["target_volume_ratio"] == 0.5 and r["centroid_shift"] is None, overridden
    assert r["held"]["face"] in FACES, overridden
