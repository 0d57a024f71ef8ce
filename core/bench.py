"""The paper's benchmark on this machine: ``isochor bench [--quick]``.

Reproduces Hirota, Maheshwari and Lin (1999) Tables 1 and 2 and Figures 5-8 with Isochor's
solver, measures how evaluation time scales with the mesh, times the 346k-triangle armadillo,
checks the targets of the performance issue, and writes ``docs/BENCHMARKS.md`` (and the
figures next to it). Numbers are printed as they come.

Every timing is the median of ``--repeats`` runs (5 by default) with the smallest and largest
beside it. BLAS runs on one thread: this module sets ``OMP_NUM_THREADS``,
``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS`` to 1 before NumPy is imported (unless they
are set already, and then the report says so), or limits the threads with threadpoolctl when
NumPy was imported first and threadpoolctl is installed.

Definitions (as in the paper):

* T2: the multi-level solve (``core.multilevel.solve``), from the first ``next()`` to the
  returned result, on a surface whose levels are already set up (the editor keeps them per
  document). "cold" is the first solve on a fresh surface, which also sets the levels up.
* T1: the same solve (same lattice, moves, pins and tolerances) on the terminal mesh only,
  ``EmbeddedSurface(lattice, [terminal mesh])``, levels set up likewise.
* Terminal: where the solve stopped by its own test (Eq 29 estimate, node change, volume on
  the full mesh); "paper size" rows cut the pyramid at the paper's terminal size and disable
  the early stop, so every level up to that size is solved.
* Node error (Figures 5-8): the largest distance of a node from its final position, over
  the object size.

``python -m core.bench --help`` lists the options.
"""

from __future__ import annotations

import os
import sys

_BLAS_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_NUMPY_FIRST = "numpy" in sys.modules
_USER_BLAS = {v: os.environ[v] for v in _BLAS_ENV if v in os.environ}
if not _NUMPY_FIRST:
    for _v in _BLAS_ENV:
        os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.sparse as sp  # noqa: E402

from core.lattice import Lattice  # noqa: E402
from core.mesh import TriMesh  # noqa: E402
from core.multilevel import EmbeddedSurface, SolveResult, solve  # noqa: E402
from core.scenario import atomic_write_text  # noqa: E402
from core.solver import SolverOptions  # noqa: E402
from core.volume import VolumeOperator  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "docs" / "BENCHMARKS.md"
DEFAULT_MODELS = ROOT.parent / "shared" / "models"
ARMADILLO = "armadillo_loop1_346k.ply"
#: a hand-written part of BENCHMARKS.md after this line is kept when the file is rewritten
KEEP_MARKER = "<!-- hand-written below: kept by `isochor bench` -->"

_THREADPOOL = None  # threadpoolctl limiter, kept alive while the benchmark runs


def _limit_blas_threads() -> None:
    global _THREADPOOL
    if _THREADPOOL is not None or not _NUMPY_FIRST or _USER_BLAS:
        return
    try:
        from threadpoolctl import threadpool_limits  # noqa: PLC0415
    except ImportError:
        return
    _THREADPOOL = threadpool_limits(1, user_api="blas")


# -- the paper's numbers -----------------------------------------------------------------------
@dataclass(frozen=True)
class PaperRow:
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
#: Table 2 of the paper as far as our copy of the text has it: k, N_tri, dX, N_step, T, T_c
PAPER_TABLE2 = [(0, 16, 0.25, 90, 120, 120), (1, 64, 0.079, 15, 60, 180),
                (2, 256, 0.033, 19, 290, 470), (3, 1024, 0.004, 13, 700, 1170)]
TITLES = {
    "torus-compression": "Torus compression",
    "torus-stretch": "Torus stretch",
    "club-compression": "Club partial compression",
    "cow-bend": "Cow bending",
}
FIGURES = {"torus-compression": 5, "torus-stretch": 6, "club-compression": 7, "cow-bend": 8}


# -- timing ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Timing:
    """Repeated measurements in seconds."""

    values: tuple[float, ...]

    @property
    def median(self) -> float:
        return float(np.median(self.values))

    @property
    def lo(self) -> float:
        return float(min(self.values))

    @property
    def hi(self) -> float:
        return float(max(self.values))

    def ms(self, digits: int = 1) -> str:
        """``median (min-max)`` in milliseconds."""
        f = f"{{:.{digits}f}}"
        return f"{f.format(1e3 * self.median)} ({f.format(1e3 * self.lo)}-{f.format(1e3 * self.hi)})"


def time_call(fn: Callable[[], object], repeats: int, warmup: int = 1) -> Timing:
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return Timing(tuple(out))


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB.

    Linux's ``VmHWM`` (the high-water mark of this process's own memory map) when there is
    one: ``ru_maxrss`` of a child started by a large parent reports the parent's size,
    because Linux carries the old map's peak over ``fork`` and ``exec``."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# -- running a solve ---------------------------------------------------------------------------
@dataclass
class Run:
    """One drained solve."""

    result: SolveResult
    wall: float  #: seconds from the first next() to the result
    first_record: float  #: seconds from the first next() to the first Progress record
    times: np.ndarray  #: (r,) Progress.elapsed of every record
    nodes: np.ndarray  #: (r, n, 3) node positions of every record
    levels: np.ndarray  #: (r,) level of every record


def run_solve(surface: EmbeddedSurface, nodes: np.ndarray, fixed: np.ndarray,
              options: SolverOptions, **kwargs) -> Run:
    """Drain ``solve`` and keep every record (for the convergence curves)."""
    gen = solve(surface, nodes, fixed, options=options, **kwargs)
    t0 = time.perf_counter()
    first = None
    records = []
    while True:
        try:
            rec = next(gen)
        except StopIteration as stop:
            result = stop.value
            break
        if first is None:
            first = time.perf_counter() - t0
        records.append(rec)
    wall = time.perf_counter() - t0
    n = len(nodes)
    return Run(
        result, wall, wall if first is None else first,
        np.array([r.elapsed for r in records]),
        np.array([r.nodes for r in records]).reshape(-1, n, 3),
        np.array([r.level for r in records], dtype=int),
    )


def node_error(run: Run, size: float) -> np.ndarray:
    """(r,) largest node distance from the run's final nodes, / object size."""
    if not len(run.nodes):
        return np.zeros(0)
    d = np.linalg.norm(run.nodes - run.result.nodes[None], axis=2)
    return d.max(axis=1) / size


def median_run(runs: Sequence[Run]) -> Run:
    order = np.argsort([r.wall for r in runs])
    return runs[int(order[len(order) // 2])]


# -- the cases ---------------------------------------------------------------------------------
@dataclass
class Case:
    """A paper example made ready to solve: the lattice, the pyramid, the edit."""

    key: str
    lattice: Lattice
    levels: list[TriMesh]
    nodes: np.ndarray
    fixed: np.ndarray
    options: SolverOptions
    note: str = ""

    @property
    def title(self) -> str:
        return TITLES.get(self.key, self.key)

    def surface(self, upto: int | None = None, only: int | None = None) -> EmbeddedSurface:
        """A fresh surface: levels ``0..upto``, or the single level ``only``."""
        if only is not None:
            return EmbeddedSurface(self.lattice, [self.levels[only]])
        levels = self.levels if upto is None else self.levels[: upto + 1]
        return EmbeddedSurface(self.lattice, levels)

    @property
    def size(self) -> float:
        return float(self.levels[-1].size)


def example_case(name: str) -> Case:
    """One of the built-in examples (core.examples)."""
    from core.examples import example_scenario  # noqa: PLC0415
    from core.scenario import build  # noqa: PLC0415

    p = build(example_scenario(name))
    return Case(name, p.surface.lattice, list(p.surface.levels), p.nodes, p.fixed, p.options)


def cow_case(models: Path) -> tuple[Case | None, str]:
    """The paper's cow bending from ``models/cow.obj``, or None and why not."""
    if not (models / "cow.obj").is_file():
        return None, f"cow row skipped: {models / 'cow.obj'} not found"
    try:
        from core.paper_models import cow_bend_scenario  # noqa: PLC0415
        from core.scenario import build  # noqa: PLC0415
    except ImportError as exc:
        return None, f"cow row skipped: {exc} (core.meshio / core.pyramid / core.paper_models)"
    p = build(cow_bend_scenario(models))
    note = "levels " + ", ".join(str(m.n_faces) for m in p.surface.levels)
    return Case("cow-bend", p.surface.lattice, list(p.surface.levels), p.nodes, p.fixed,
                p.options, note), ""


def nearest_level(levels: Sequence[TriMesh], n_tri: int) -> int:
    return int(np.argmin([abs(np.log(m.n_faces / n_tri)) for m in levels]))


# -- Table 1 -----------------------------------------------------------------------------------
@dataclass
class Table1Row:
    case: str
    variant: str  #: "estimate" (the solver's own terminal) or "paper size"
    terminal_tri: int
    finest_tri: int  #: finest level of the pyramid the multi-level solve had
    t1: Timing
    t2: Timing
    t2_cold: float
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
        return self.t1.median / self.t2.median if self.t2.median > 0 else float("nan")


def table1_row(case: Case, repeats: int, variant: str = "estimate",
               level: int | None = None) -> Table1Row:
    """T1 and T2 of one case. ``variant="paper size"`` cuts the pyramid at ``level`` and
    solves every level up to it (no early stop)."""
    if variant == "estimate":
        surface, options = case.surface(), case.options
    else:
        surface = case.surface(upto=level)
        options = dataclasses.replace(case.options, tol_nodes=0.0)
    cold2 = run_solve(surface, case.nodes, case.fixed, options)
    res = cold2.result
    terminal = res.terminal_level if res.terminal_level >= 0 else len(surface.levels) - 1
    stats = {s.level: s for s in res.levels}
    term_stats = stats.get(terminal)
    single = case.surface(only=terminal)
    run_solve(single, case.nodes, case.fixed, case.options)  # set the level up
    runs1, runs2 = [], []
    for _ in range(max(1, repeats)):  # interleaved, so a busy spell hits both alike
        runs2.append(run_solve(surface, case.nodes, case.fixed, options))
        runs1.append(run_solve(single, case.nodes, case.fixed, case.options))
    r1 = runs1[0].result
    return Table1Row(
        case.key, variant, case.levels[terminal].n_faces, surface.levels[-1].n_faces,
        Timing(tuple(r.wall for r in runs1)), Timing(tuple(r.wall for r in runs2)), cold2.wall,
        sum(s.steps for s in r1.levels), sum(s.steps for s in res.levels),
        res.rel_volume_error,
        term_stats.rel_volume_error if term_stats else float("nan"),
        r1.rel_volume_error,
        term_stats.max_node_change if term_stats else float("nan"),
        r1.converged, res.converged, PAPER_TABLE1.get(case.key), runs2, runs1,
    )


def table1_rows(case: Case, repeats: int, paper_size: bool = True,
                max_paper_tri: int | None = None, log=print) -> list[Table1Row]:
    rows = [table1_row(case, repeats)]
    log(_fmt_row(rows[-1]))
    paper = PAPER_TABLE1.get(case.key)
    if paper_size and paper is not None:
        k = nearest_level(case.levels, paper.n_tri)
        if case.levels[k].n_faces == rows[0].terminal_tri and k == len(case.levels) - 1:
            rows[0].variant = "estimate = paper size"
            log(f"  {case.key}: the solver's terminal is the paper's size")
        elif max_paper_tri is None or case.levels[k].n_faces <= max_paper_tri:
            rows.append(table1_row(case, repeats, "paper size", k))
            log(_fmt_row(rows[-1]))
        else:
            log(f"  {case.key}: paper-size row ({case.levels[k].n_faces} triangles) skipped")
    return rows


def _fmt_row(r: Table1Row) -> str:
    return (f"  {r.case:18s} {r.variant:10s} N_tri {r.terminal_tri:7d}  T1 {r.t1.ms()} ms  "
            f"T2 {r.t2.ms()} ms  T1/T2 {r.speedup:5.1f}  |dV|/V0 {abs(r.dv_full):.2e}")


# -- where the time goes -----------------------------------------------------------------------
@dataclass
class LevelProfile:
    level: int
    triangles: int
    steps: int
    time_s: float
    evals: int  #: volume + gradient evaluations (objective and line-search trials)
    eval_s: float
    volume_only: int
    volume_only_s: float
    spring_s: float
    line_searches: int
    line_search_s: float  #: inside scipy's line_search, evaluations included


def profile_solve(case: Case, upto: int | None = None, options: SolverOptions | None = None
                  ) -> tuple[list[LevelProfile], float, float]:
    """One instrumented solve: per level, how many evaluations and where the time went.

    Returns (rows, total seconds, seconds outside the levels). The wrappers add a few
    microseconds per call, so the totals are a little above the plain T2.
    """
    import core.multilevel as ml  # noqa: PLC0415
    import core.solver as sv  # noqa: PLC0415
    import core.springs as spr  # noqa: PLC0415

    surface = case.surface(upto=upto)
    options = options or case.options
    run_solve(surface, case.nodes, case.fixed, options)  # set the levels up
    acc: dict[tuple[str, int], list[float]] = {}
    current = {"level": -1}

    def add(kind, level, dt):
        a = acc.setdefault((kind, level), [0, 0.0])
        a[0] += 1
        a[1] += dt

    orig_vg, orig_v = ml._Level.volume_and_gradient, ml._Level.volume
    orig_ls, orig_sp = sv.line_search, spr.SpringNetwork.energy_and_gradient
    tri_to_level = {lvl.n_faces: k for k, lvl in enumerate(surface.levels)}

    def vg(self, nodes):
        t = time.perf_counter()
        out = orig_vg(self, nodes)
        add("eval", tri_to_level.get(self.triangles, -1), time.perf_counter() - t)
        return out

    def v(self, nodes):
        t = time.perf_counter()
        out = orig_v(self, nodes)
        add("vol", tri_to_level.get(self.triangles, -1), time.perf_counter() - t)
        return out

    def ls(*a, **k):
        t = time.perf_counter()
        out = orig_ls(*a, **k)
        add("ls", current["level"], time.perf_counter() - t)
        return out

    def springs(self, nodes):
        t = time.perf_counter()
        out = orig_sp(self, nodes)
        add("spring", current["level"], time.perf_counter() - t)
        return out

    ml._Level.volume_and_gradient, ml._Level.volume = vg, v
    sv.line_search, spr.SpringNetwork.energy_and_gradient = ls, springs
    try:
        gen = solve(surface, case.nodes, case.fixed, options=options)
        t0 = time.perf_counter()
        while True:
            try:
                rec = next(gen)
            except StopIteration as stop:
                result = stop.value
                break
            current["level"] = rec.level if not rec.level_done else -1
        total = time.perf_counter() - t0
    finally:
        ml._Level.volume_and_gradient, ml._Level.volume = orig_vg, orig_v
        sv.line_search, spr.SpringNetwork.energy_and_gradient = orig_ls, orig_sp
    rows = []
    for s in result.levels:
        k = s.level

        def get(kind, k=k):
            return acc.get((kind, k), [0, 0.0])

        rows.append(LevelProfile(k, s.triangles, s.steps, s.time_s, int(get("eval")[0]),
                                 get("eval")[1], int(get("vol")[0]), get("vol")[1],
                                 get("spring")[1], int(get("ls")[0]), get("ls")[1]))
    inside = sum(s.time_s for s in result.levels)
    return rows, total, total - inside


# -- Table 2 -----------------------------------------------------------------------------------
def table2(row: Table1Row | Sequence[Run]) -> list[tuple[int, int, float, int, float, float]]:
    """(k, N_tri, max node change, N_step, T, cumulative T) of the median T2 run."""
    run = median_run(row.t2_runs if isinstance(row, Table1Row) else row)
    out, cum = [], 0.0
    for s in run.result.levels:
        cum += s.time_s
        out.append((s.level, s.triangles, s.max_node_change, s.steps, s.time_s, cum))
    return out


# -- evaluation scale --------------------------------------------------------------------------
@dataclass
class ScaleRow:
    triangles: int
    nodes: int
    form: str  #: "dense" or "factored" basis
    setup_s: float
    t_eval: Timing  #: basis apply + volume and gradient + basis transpose
    t_volume: Timing  #: volume and gradient alone (vertex space)
    t_reference: Timing | None  #: the straightforward NumPy version (per-face np.cross)


class ReferenceEvaluation:
    """The straightforward NumPy evaluation Isochor started with, kept for comparison:
    a dense (or k-sliced factored) basis in point-major layout, three ``np.cross`` per face
    and a sparse corner-to-vertex gather."""

    def __init__(self, lattice: Lattice, mesh: TriMesh, dense_limit: int = 8_000_000):
        from core.lattice import bernstein  # noqa: PLC0415

        uvw = lattice.to_parameters(mesh.vertices)
        l, m, n = lattice.shape
        bu, bv, bw = (bernstein(d - 1, uvw[:, i]) for i, d in enumerate((l, m, n)))
        p = len(uvw)
        self.shape, self.p = (l, m, n), p
        self.buv = (bu[:, :, None] * bv[:, None, :]).reshape(p, l * m)
        self.bw = np.ascontiguousarray(bw)
        self.dense = ((self.buv[:, :, None] * bw[:, None, :]).reshape(p, -1)
                      if p * l * m * n <= dense_limit else None)
        faces = mesh.faces
        f = len(faces)
        self.f0, self.f1, self.f2 = (faces[:, i] for i in range(3))
        self.gather = sp.csr_matrix((np.ones(3 * f), (faces.T.ravel(), np.arange(3 * f))),
                                    shape=(p, 3 * f))

    def apply(self, x):
        if self.dense is not None:
            return self.dense @ x
        l, m, n = self.shape
        xr = x.reshape(l * m, n, 3)
        out = np.zeros((self.p, 3))
        for k in range(n):
            out += self.bw[:, k, None] * (self.buv @ xr[:, k, :])
        return out

    def apply_transpose(self, g):
        if self.dense is not None:
            return self.dense.T @ g
        l, m, n = self.shape
        out = np.empty((l * m, n, 3))
        for k in range(n):
            out[:, k, :] = self.buv.T @ (self.bw[:, k, None] * g)
        return out.reshape(l * m * n, 3)

    def __call__(self, x, center):
        v = self.apply(x) - center
        a, b, c = v[self.f0], v[self.f1], v[self.f2]
        bc = np.cross(b, c)
        vol = float(np.einsum("ij,ij->", a, bc) / 6.0)
        corners = np.concatenate([bc, np.cross(c, a), np.cross(a, b)])
        return vol, self.apply_transpose((self.gather @ corners) / 6.0)


#: (nu, nv) of core.shapes.torus: 2 nu nv triangles
SCALE_TORI = {4096: (64, 32), 65536: (256, 128), 262144: (512, 256), 1048576: (1024, 512)}


def scale_row(mesh: TriMesh, shape: tuple[int, int, int], repeats: int,
              reference: bool = True) -> ScaleRow:
    """Time one volume + gradient evaluation in node space on ``mesh``."""
    lattice = Lattice.around(mesh.vertices, shape)
    t = time.perf_counter()
    basis = lattice.basis(mesh.vertices)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)
    setup = time.perf_counter() - t
    rng = np.random.default_rng(0)
    x = lattice.rest_nodes + rng.normal(scale=0.02 * lattice.size, size=(lattice.n_nodes, 3))
    center = mesh.center

    def evaluate():
        v, g = op.value_and_gradient(basis.apply(x), center)
        return v, basis.apply_transpose(g)

    pts = basis.apply(x)
    t_eval = time_call(evaluate, repeats)
    t_vol = time_call(lambda: op.value_and_gradient(pts, center), repeats)
    t_ref = None
    if reference:
        ref = ReferenceEvaluation(lattice, mesh)
        v0, g0 = ref(x, center)
        v1, g1 = evaluate()
        if not (abs(v1 - v0) <= 1e-10 * abs(v0) and np.allclose(g1, g0, rtol=1e-8,
                                                                atol=1e-10 * np.abs(g0).max())):
            raise AssertionError("the evaluation disagrees with the reference version")
        t_ref = time_call(lambda: ref(x, center), max(1, min(repeats, 5)))
        del ref
    form = "factored" if basis.buv is not None else "dense"  # the form that evaluates
    return ScaleRow(mesh.n_faces, lattice.n_nodes, form, setup, t_eval, t_vol, t_ref)


# -- the armadillo (in a child process, for its own peak memory) -------------------------------
def armadillo_bend(levels: list[TriMesh], shape=(5, 5, 5), angle_deg: float = 30.0):
    """A bend of a model: lattice layers along its longest axis, the first layer pinned, the
    last turned by ``angle_deg`` about the next-longest axis through the centre of the layer
    before it. Returns (lattice, nodes, fixed)."""
    full = levels[-1]
    lattice = Lattice.around(full.vertices, shape, 0.05)
    ext = full.extents
    a = int(np.argmax(ext))  # layers along a
    b = int(np.argsort(ext)[1])  # rotate about b
    grid = lattice.grid_parameters()
    nodes = lattice.rest_nodes.copy()
    fixed = np.zeros(lattice.n_nodes, dtype=bool)
    first, last = np.isclose(grid[:, a], 0.0), np.isclose(grid[:, a], 1.0)
    before = np.isclose(grid[:, a], 1.0 - 1.0 / (shape[a] - 1))
    pivot = nodes[before].mean(axis=0)
    t = np.radians(angle_deg)
    c = 3 - a - b
    rot = np.eye(3)
    rot[a, a], rot[a, c], rot[c, a], rot[c, c] = np.cos(t), -np.sin(t), np.sin(t), np.cos(t)
    nodes[last] = (nodes[last] - pivot) @ rot.T + pivot
    fixed[first | last] = True
    return lattice, nodes, fixed


def armadillo_child(path: str, repeats: int) -> dict:
    """Load, pyramid and bend-solve the armadillo; returns the numbers (run in a child)."""
    from core.meshio import load_mesh  # noqa: PLC0415
    from core.pyramid import build_pyramid  # noqa: PLC0415

    out: dict = {"rss_start_mb": peak_rss_mb()}
    t = time.perf_counter()
    loaded = load_mesh(path)
    out["load_s"] = time.perf_counter() - t
    t = time.perf_counter()
    levels = build_pyramid(loaded.mesh)
    out["pyramid_s"] = time.perf_counter() - t
    out["levels"] = [m.n_faces for m in levels]
    lattice, nodes, fixed = armadillo_bend(levels)
    options = SolverOptions()
    surface = EmbeddedSurface(lattice, levels)
    cold = run_solve(surface, nodes, fixed, options)
    out["first_record_cold_s"] = cold.first_record
    out["solve_cold_s"] = cold.wall
    runs = [run_solve(surface, nodes, fixed, options) for _ in range(max(1, repeats))]
    out["solve_s"] = [r.wall for r in runs]
    out["first_record_s"] = [r.first_record for r in runs]
    res = runs[0].result
    out["terminal_tri"] = levels[res.terminal_level].n_faces if res.terminal_level >= 0 else 0
    out["dv"] = res.rel_volume_error
    out["converged"] = res.converged
    out["steps"] = [s.steps for s in res.levels]
    out["level_ms"] = [1e3 * s.time_s for s in res.levels]
    out["peak_rss_mb"] = peak_rss_mb()
    return out


def run_armadillo(models: Path, repeats: int, timeout: float = 600) -> tuple[dict | None, str]:
    path = models / ARMADILLO
    if not path.is_file():
        return None, f"armadillo skipped: {path} not found"
    try:
        import core.meshio  # noqa: F401, PLC0415
        import core.pyramid  # noqa: F401, PLC0415
    except ImportError as exc:
        return None, f"armadillo skipped: {exc}"
    env = dict(os.environ)
    for v in _BLAS_ENV:
        env.setdefault(v, "1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    cmd = [sys.executable, "-m", "core.bench", "--armadillo-child", str(path),
           "--repeats", str(repeats)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=str(ROOT), check=False)
    if proc.returncode != 0:
        return None, "armadillo failed: " + (proc.stderr.strip().splitlines() or ["?"])[-1]
    return json.loads(proc.stdout.strip().splitlines()[-1]), ""


# -- environment -------------------------------------------------------------------------------
def environment() -> dict[str, str]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    blas = ", ".join(f"{k}={os.environ.get(k, 'unset')}" for k in _BLAS_ENV)
    try:
        from threadpoolctl import threadpool_info  # noqa: PLC0415

        pools = [f"{p.get('internal_api')} {p.get('num_threads')} thread(s)"
                 for p in threadpool_info() if p.get("user_api") == "blas"]
        if pools:
            blas += "; threadpoolctl: " + ", ".join(pools)
    except ImportError:
        pass
    if _USER_BLAS:
        blas += " (set by the user before the benchmark started)"
    return {
        "date": datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        "cpu": f"{cpu}, {os.cpu_count()} logical CPUs",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "blas": blas,
        "platform": platform.platform(),
    }


# -- targets -----------------------------------------------------------------------------------
@dataclass
class Target:
    name: str
    measured: str
    met: bool | None  #: None: not measured in this run
    why: str = ""  #: shown when missed: why, and what was tried


WHY = {
    "accuracy": (
        "The solver stops a level at half the volume tolerance on that level's own mesh and "
        "checks the full mesh before it stops; a row that misses means the inner "
        "minimisation stalled (see the steps and the convergence flag)."),
    "never_slower": (
        "The rows below 1 stop at about 1000-5000 triangles, where a single-level solve "
        "takes only 10-30 ms. The multi-level solve also pays for its coarser level(s) "
        "(about 100 us of solver overhead per step whatever the level: line search, L-BFGS "
        "two-loop recursion, spring gradient, progress records) and for its stopping test, "
        "which measures the volume on the full mesh (65536-81920 triangles, about 1 ms "
        "each). What was tried: every evaluation is 2-4 times cheaper than before (which "
        "also made T1 cheaper); the start-level sweep below, after which the solver "
        "starts at about 1000 triangles (start_triangles) with gtol 1e-5 and a sparse spring "
        "gradient. The club's own-terminal row stays below 1: its stopping test costs three "
        "volume evaluations on the 81920-triangle full mesh that the single-level solve on "
        "5120 triangles never does."),
    "speedup_65k": (
        "The single-level solve at 65536 triangles needs about as many steps as the "
        "multi-level one spends in total, so the gain is only the cost of an evaluation at "
        "65536 against the coarse ones."),
    "torus_40ms": (
        "Most of the solve is solver overhead per step on the coarse levels (see 'Where the "
        "time goes'); the evaluations were made 2-4 times cheaper."),
    "eval_1m": (
        "NumPy runs each operation as a separate pass; the floor with cache-sized blocks is "
        "6 gathers and 9 multiply/subtract passes per edge (1.5M edges), one sparse scatter "
        "per coordinate (3M entries) and two small matrix products for the basis (about "
        "25 + 15 ms here). What was tried: one cross product per edge instead of three per "
        "face, structure-of-arrays rows, hand-written cross products, L2-sized blocks with "
        "reused scratch, the CSC scatter called per block in place, blocked tensor-product "
        "basis products; rejected after measuring: float32 (12% faster, but the per-vertex "
        "gradient, a sum of cross products about 1000 times larger than itself, loses three "
        "digits), np.add.at and bincount scatters, complex-number and rolled-row cross "
        "products, scipy's multi-vector csc_matvecs (20x slower)."),
    "armadillo_load": "Loading and the QEM pyramid are core.meshio / core.pyramid.",
    "armadillo_solve": (
        "The solve's cost is set by how many levels and steps the bend needs; see the "
        "per-level steps in the Scale section."),
    "memory": "",
    "first_record": (
        "On a fresh surface the first record waits for the full mesh's rest volume "
        "(10 ms at 346k triangles, signed_volume, was 30 ms) and its bounding box, which "
        "EmbeddedSurface.size and .center compute with axis-0 reductions over (n, 3) rows "
        "(2 x 6 ms; 4 times faster on transposed rows: a lead-owned change). Later solves "
        "on the same surface answer in well under a millisecond."),
}


def evaluate_targets(rows: list[Table1Row], scale: list[ScaleRow], arma: dict | None,
                     latency: dict[str, tuple[float, float]]) -> list[Target]:
    out = []
    est = [r for r in rows if r.variant.startswith("estimate")]
    if est:
        worst_dv = max(max(abs(r.dv_full), abs(r.dv_terminal)) for r in est)
        worst_dx = max(r.node_change for r in est)
        ok = all(r.converged2 for r in est) and worst_dv <= 5e-4 and worst_dx < 1e-3
        out.append(Target("every example: |dV|/V0 <= 0.05% on the terminal and full mesh, "
                          "max node change < 0.1% of the size",
                          f"worst |dV|/V0 {100 * worst_dv:.3f}%, worst node change "
                          f"{100 * worst_dx:.3f}%", ok, WHY["accuracy"]))
    if rows:
        slow = [r for r in rows if r.speedup < 1.0]
        desc = ", ".join(f"{r.case} {r.variant} {r.terminal_tri}: {r.speedup:.2f}x"
                         for r in rows)
        out.append(Target("multi-level never slower than single-level (T1/T2 >= 1 in "
                          "every row)", desc, not slow, WHY["never_slower"]))
        big = [r for r in rows if r.terminal_tri >= 65536]
        if big:
            out.append(Target(">= 5x faster at 65536 triangles and above",
                              ", ".join(f"{r.case} {r.terminal_tri}: {r.speedup:.1f}x"
                                        for r in big),
                              all(r.speedup >= 5 for r in big), WHY["speedup_65k"]))
        else:
            out.append(Target(">= 5x faster at 65536 triangles and above",
                              "no row at 65536 triangles in this run", None))
    tc = [r for r in rows if r.case == "torus-compression" and r.terminal_tri == 4096]
    if tc:
        r = tc[0]
        out.append(Target("torus compression at 4096 triangles, whole multi-level solve "
                          "< 40 ms", f"{1e3 * r.t2.median:.1f} ms ({r.variant} row)",
                          r.t2.median < 0.040, WHY["torus_40ms"]))
    big = [s for s in scale if s.triangles == 1048576 and s.nodes == 27]
    if big:
        s = big[0]
        out.append(Target("volume + gradient on 1,048,576 triangles, 27 nodes < 30 ms",
                          f"{1e3 * s.t_eval.median:.1f} ms", s.t_eval.median < 0.030,
                          WHY["eval_1m"]))
    else:
        out.append(Target("volume + gradient on 1,048,576 triangles, 27 nodes < 30 ms",
                          "not measured (--quick)", None))
    if arma:
        lp = arma["load_s"] + arma["pyramid_s"]
        out.append(Target("armadillo 346k: load + pyramid < 3 s",
                          f"{lp:.2f} s (load {arma['load_s']:.2f} + pyramid "
                          f"{arma['pyramid_s']:.2f})", lp < 3.0, WHY["armadillo_load"]))
        warm = float(np.median(arma["solve_s"]))
        out.append(Target("armadillo 346k, 5x5x5 bend: full solve < 1 s",
                          f"first solve (sets the levels up) {arma['solve_cold_s']:.2f} s, "
                          f"later solves {warm:.2f} s", arma["solve_cold_s"] < 1.0,
                          WHY["armadillo_solve"]))
        out.append(Target("armadillo: peak memory < 2 GB",
                          f"{arma['peak_rss_mb']:.0f} MB peak RSS",
                          arma["peak_rss_mb"] < 2048, WHY["memory"]))
    else:
        out.append(Target("armadillo 346k targets", "not measured", None))
    if latency:
        worst = max(latency.items(), key=lambda kv: kv[1][0])
        worst_warm = max(v[1] for v in latency.values())
        out.append(Target("first progress record within 20 ms on any model",
                          f"worst first solve (fresh surface) {1e3 * worst[1][0]:.1f} ms "
                          f"({worst[0]}), worst later solve {1e3 * worst_warm:.1f} ms",
                          worst[1][0] < 0.020 and worst_warm < 0.020, WHY["first_record"]))
    return out


# -- figures -----------------------------------------------------------------------------------
def draw_figure(row: Table1Row, size: float, path: Path, single: Table1Row | None = None
                ) -> str | None:
    """Figure 5-8 style: node error against cumulative time, log scale. Returns None on
    success or why it was skipped."""
    try:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415
    except ImportError:
        return "matplotlib is not installed (pip install 'isochor[bench]'): figures skipped"
    run = median_run(row.t2_runs)
    err = np.maximum(node_error(run, size), 1e-7)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    ax.semilogy(1e3 * run.times, err, "-", color="C0", lw=1.4,
                label=f"multi-level (T2 = {1e3 * run.wall:.0f} ms)")
    ends = [i for i in range(len(run.levels)) if i + 1 == len(run.levels)
            or run.levels[i + 1] != run.levels[i]]
    for n, i in enumerate(ends):
        k = run.levels[i]
        ax.plot(1e3 * run.times[i], err[i], "o", color="C0", ms=4)
        ax.annotate(f"{row_levels_tri(run, k, row)}", (1e3 * run.times[i], err[i]),
                    textcoords="offset points", xytext=(4, 5) if n % 2 == 0 else (4, -11),
                    fontsize=7, color="C0")
    if row.t1_runs:
        r1 = median_run(row.t1_runs)
        ax.semilogy(1e3 * r1.times, np.maximum(node_error(r1, size), 1e-7), "--", color="C3",
                    lw=1.2, label=f"single level, {row.terminal_tri} triangles "
                    f"(T1 = {1e3 * r1.wall:.0f} ms)")
    ax.axhline(1e-3, color="0.6", lw=0.8, ls=":")
    ax.text(ax.get_xlim()[1], 1e-3, " 0.1%", va="center", fontsize=7, color="0.4")
    ax.set_xlabel("cumulative time (ms)")
    ax.set_ylabel("max node error / object size")
    fig_no = FIGURES.get(row.case, "")
    ax.set_title(f"Figure {fig_no}: {TITLES.get(row.case, row.case)} "
                 f"(terminal {row.terminal_tri} triangles)", fontsize=10)
    ax.set_ylim(1e-7 * 0.8, 2.0)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return None


def row_levels_tri(run: Run, k: int, row: Table1Row) -> str:
    for s in run.result.levels:
        if s.level == k:
            return str(s.triangles)
    return f"k={k}"


# -- report ------------------------------------------------------------------------------------
def _pct(x: float) -> str:
    """abs(x) in percent, 2 significant digits (at least 3 decimals)."""
    v = 100 * abs(x)
    return f"{v:.3f}%" if v >= 0.01 or v == 0 else f"{v:.2g}%"


def render(env: dict, quick: bool, repeats: int, rows: list[Table1Row],
           t2rows: list, profile: tuple | None, sweep: list, scale: list[ScaleRow],
           arma: dict | None, latency: dict, targets: list[Target], figures: list[str],
           notes: list[str], kept: str, t2paper: list | None = None) -> str:
    L = []
    L.append("# Benchmarks\n")
    L.append("Written by `isochor bench`" + (" --quick" if quick else "") +
             " (core/bench.py). Do not edit above the hand-written marker: the next run "
             "rewrites it.\n")
    L.append(f"- date: {env['date']}")
    L.append(f"- CPU: {env['cpu']} ({env['platform']})")
    L.append(f"- Python {env['python']}, NumPy {env['numpy']}, SciPy {env['scipy']}")
    L.append(f"- BLAS threads: {env['blas']}")
    L.append(f"- every time is the median of {repeats} runs, (min-max) beside it; the machine "
             "is shared, so single runs can be slower\n")
    for n in notes:
        L.append(f"> {n}\n")

    L.append("## Targets\n")
    L.append("| target | measured | |")
    L.append("|---|---|---|")
    for t in targets:
        mark = "not measured" if t.met is None else ("MET" if t.met else "**MISSED**")
        L.append(f"| {t.name} | {t.measured} | {mark} |")
    missed = [t for t in targets if t.met is False and t.why]
    if missed:
        L.append("\nWhy missed, and what was tried:\n")
        for t in missed:
            L.append(f"- *{t.name}*: {t.why}")
    L.append("")

    L.append("## Table 1: multi-level against single-level\n")
    L.append("T1: the solve on the terminal mesh only; T2: multi-level; both with the levels "
             "set up (T2 cold: the first solve on a fresh surface, setup included). "
             "|dV|/V0 is measured on the finest mesh the solve had; node change: the largest "
             "node change at the terminal level against the level before, over the object "
             "size (the solver stops below 0.1%; paper-size rows stop by force). Paper: SGI "
             "Onyx2, 195 MHz R10000.\n")
    L.append("| example | terminal | N_tri | T1 ms | T2 ms | T1/T2 | T2 cold ms | steps T1 / T2 "
             "| abs(dV)/V0 | node change | paper T1 / T2 ms | paper T1/T2 | paper N_tri "
             "| paper dV/V0 |")
    L.append("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        p = r.paper
        conv = "" if (r.converged1 and r.converged2) else " (not converged)"
        L.append(
            f"| {TITLES.get(r.case, r.case)} | {r.variant} (of {r.finest_tri}) | "
            f"{r.terminal_tri} | {r.t1.ms()} | {r.t2.ms()} | {r.speedup:.1f} | "
            f"{1e3 * r.t2_cold:.1f} | {r.steps1} / {r.steps2}{conv} | {_pct(r.dv_full)} | "
            f"{_pct(r.node_change)} | "
            + (f"{p.t1_ms:.0f} / {p.t2_ms:.0f} | {p.speedup:.0f} | {p.n_tri} | {_pct(p.dv)} |"
               if p else "| | | |"))
    L.append("")

    def level_table(rows_):
        L.append("| k | N_tri | dX | N_step | T ms | T_c ms |")
        L.append("|---:|---:|---:|---:|---:|---:|")
        for k, n, dx, st, t, tc in rows_:
            L.append(f"| {k} | {n} | {100 * dx:.2f}% | {st} | {1e3 * t:.2f} | {1e3 * tc:.2f} |")

    if t2rows:
        L.append("## Table 2: torus compression level by level\n")
        L.append("The median T2 run of the torus compression (estimate row), with the solver's "
                 "default schedule (it starts at the first level with at least "
                 "`SolverOptions.start_triangles` triangles). dX: largest node coordinate "
                 "change against the previous level (the first level: against the start), "
                 "over the object size.\n")
        level_table(t2rows)
        if t2paper:
            L.append("\nThe paper's schedule, from the 16-triangle level (`start_level=0`):\n")
            level_table(t2paper)
        L.append("\nThe paper's Table 2 (195 MHz R10000; our copy of the text ends at k = 3, "
                 "the total is 1760 ms at 4096 triangles):\n")
        L.append("| k | N_tri | dX | N_step | T ms | T_c ms |")
        L.append("|---:|---:|---:|---:|---:|---:|")
        for k, n, dx, st, t, tc in PAPER_TABLE2:
            L.append(f"| {k} | {n} | {100 * dx:.1f}% | {st} | {t} | {tc} |")
        L.append("")

    if profile:
        prows, total, outside = profile
        L.append("## Where the time goes (torus compression)\n")
        L.append("One instrumented multi-level solve (the wrappers add a few microseconds per "
                 "call). eval: volume + gradient in node space (basis, volume, transpose); "
                 "line search: time inside scipy's `line_search` (its evaluations included); "
                 "springs: spring energy and gradient; other: the rest of the level (L-BFGS "
                 "two-loop, progress records, Python).\n")
        L.append("| k | N_tri | steps | evals | evals/step | us/eval | level ms | eval ms "
                 "| line search ms | springs ms | other ms | volume-only calls (ms) |")
        L.append("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for p in prows:
            other = p.time_s - p.eval_s - p.spring_s - p.volume_only_s
            L.append(f"| {p.level} | {p.triangles} | {p.steps} | {p.evals} | "
                     f"{p.evals / max(p.steps, 1):.2f} | {1e6 * p.eval_s / max(p.evals, 1):.0f} | "
                     f"{1e3 * p.time_s:.2f} | {1e3 * p.eval_s:.2f} | {1e3 * p.line_search_s:.2f} "
                     f"| {1e3 * p.spring_s:.2f} | {1e3 * other:.2f} | {p.volume_only} "
                     f"({1e3 * p.volume_only_s:.2f}) |")
        L.append(f"\nTotal {1e3 * total:.1f} ms, of which {1e3 * outside:.1f} ms outside the "
                 "levels (start checks, warm-start test and the final volume on the full "
                 "mesh, result).\n")

    if sweep:
        L.append("## Start level (torus compression)\n")
        L.append("`solve(..., start_level=k)` skips the levels below k: where should the "
                 "bootstrapping start?\n")
        L.append("| start level | N_tri | T2 ms | terminal N_tri | steps | abs(dV)/V0 |")
        L.append("|---:|---:|---:|---:|---:|---:|")
        for k, n, t, term, steps, dv in sweep:
            L.append(f"| {k} | {n} | {t.ms()} | {term} | {steps} | {_pct(dv)} |")
        L.append("")

    if figures:
        L.append("## Figures 5-8: convergence\n")
        L.append("Largest node distance from the final position over the object size, "
                 "against cumulative time, for the median T2 run (dots: level ends, labelled "
                 "with their triangles) and the single-level solve at the terminal size "
                 "(dashed).\n")
        for f in figures:
            L.append(f"![{f}]({f})\n")

    if scale:
        L.append("## Scale: one volume + gradient evaluation\n")
        L.append("Torus meshes (`core.shapes.torus`), random node positions. eval: basis "
                 "apply, volume and gradient, basis transpose (what one solver step costs on "
                 "that level); volume: the vertex-space part alone; reference: the "
                 "straightforward NumPy version Isochor had before (per-face `np.cross`, "
                 "sparse gather), same numbers to 1e-10.\n")
        L.append("| N_tri | nodes | basis | setup ms (one run) | eval ms | volume ms "
                 "| reference ms | speed-up |")
        L.append("|---:|---:|---|---:|---:|---:|---:|---:|")
        for s in scale:
            ref = s.t_reference.ms() if s.t_reference else ""
            gain = (f"{s.t_reference.median / s.t_eval.median:.1f}x" if s.t_reference else "")
            L.append(f"| {s.triangles} | {s.nodes} | {s.form} | {1e3 * s.setup_s:.0f} | "
                     f"{s.t_eval.ms(2)} | {s.t_volume.ms(2)} | {ref} | {gain} |")
        L.append("")
    if arma:
        L.append("## Scale: the 346k-triangle armadillo, 5x5x5 lattice, a bend\n")
        L.append("Child process: `core.meshio.load_mesh`, `core.pyramid.build_pyramid`, then "
                 "the bend (first node layer along the longest axis pinned, the last turned "
                 "30 degrees). Peak memory is the child's peak RSS.\n")
        solves = Timing(tuple(arma["solve_s"]))
        firsts = Timing(tuple(arma["first_record_s"]))
        L.append(f"- levels: {', '.join(map(str, arma['levels']))} triangles")
        L.append(f"- load {arma['load_s']:.2f} s, pyramid {arma['pyramid_s']:.2f} s")
        L.append(f"- first solve (level setup included) {arma['solve_cold_s']:.3f} s, later "
                 f"solves {solves.ms()} ms")
        L.append(f"- terminal {arma['terminal_tri']} triangles, |dV|/V0 {_pct(arma['dv'])}, "
                 f"converged {arma['converged']}, steps per level {arma['steps']}, ms per "
                 f"level {[round(t, 1) for t in arma['level_ms']]}")
        L.append(f"- first progress record: first solve {1e3 * arma['first_record_cold_s']:.1f}"
                 f" ms, later {firsts.ms()} ms")
        L.append(f"- peak RSS {arma['peak_rss_mb']:.0f} MB (interpreter and imports "
                 f"{arma['rss_start_mb']:.0f} MB)\n")
    if latency:
        L.append("## First progress record\n")
        L.append("From the first `next()` on the solve generator to the first record: on a "
                 "fresh surface (nothing set up: the first solve after loading) and on a "
                 "set-up surface (every later edit).\n")
        L.append("| model | fresh surface ms | set up ms |")
        L.append("|---|---:|---:|")
        for k, (cold, warm) in latency.items():
            L.append(f"| {TITLES.get(k, k)} | {1e3 * cold:.2f} | {1e3 * warm:.2f} |")
        L.append("")
    L.append(f"Peak RSS of the benchmark process: {peak_rss_mb():.0f} MB.\n")
    L.append(KEEP_MARKER)
    return "\n".join(L) + "\n\n" + kept.lstrip("\n")


def _kept_part(path: Path) -> str:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        return ""
    i = text.find(KEEP_MARKER)
    return text[i + len(KEEP_MARKER):] if i >= 0 else ""


# -- main --------------------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="isochor bench",
        description="Reproduce the paper's Tables 1-2 and Figures 5-8 on this machine, time "
        "the evaluation at scale and the armadillo, check the performance targets.")
    p.add_argument("--quick", action="store_true",
                   help="2 repeats, small cases only (well under a minute); writes no file "
                   "unless --out is given")
    p.add_argument("--repeats", type=int, default=None,
                   help="runs per timing (default 7; 2 with --quick)")
    p.add_argument("--out", type=Path, default=None,
                   help=f"the Markdown report (default {DEFAULT_OUT.relative_to(ROOT)}; "
                   "figures go next to it)")
    p.add_argument("--models", type=Path, default=None,
                   help="folder with cow.obj and the armadillo (default ../shared/models, or "
                   "$ISOCHOR_MODELS)")
    p.add_argument("--no-figures", action="store_true", help="do not draw Figures 5-8")
    p.add_argument("--armadillo-child", metavar="PLY", help=argparse.SUPPRESS)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    _limit_blas_threads()
    if args.armadillo_child:
        print(json.dumps(armadillo_child(args.armadillo_child, args.repeats or 5)))
        return 0
    quick = args.quick
    repeats = args.repeats or (2 if quick else 7)
    out = args.out if args.out is not None else (None if quick else DEFAULT_OUT)
    models = args.models or Path(os.environ.get("ISOCHOR_MODELS", DEFAULT_MODELS))
    env = environment()
    print(f"isochor bench{' --quick' if quick else ''}: {env['cpu']}; Python {env['python']}, "
          f"NumPy {env['numpy']}, SciPy {env['scipy']}; {env['blas']}")
    print(f"{repeats} repeats per timing; medians (min-max)\n")
    notes: list[str] = []

    print("Table 1")
    cases = [example_case(n) for n in ("torus-compression", "torus-stretch", "club-compression")]
    cow, why = cow_case(models)
    if cow is None:
        notes.append(why)
        print("  " + why)
    else:
        cases.append(cow)
        notes.append(f"cow: {models / 'cow.obj'}, {cow.note} triangles")
    rows: list[Table1Row] = []
    for case in cases:
        rows += table1_rows(case, repeats, max_paper_tri=16384 if quick else None)

    tc_case = cases[0]
    tc_est = next(r for r in rows if r.case == "torus-compression" and r.variant.startswith("estimate"))
    t2rows = table2(tc_est)
    print("\nTable 2 (torus compression)")
    for k, n, dx, st, t, tc in t2rows:
        print(f"  k {k}  N_tri {n:6d}  dX {100 * dx:7.3f}%  N_step {st:4d}  T {1e3 * t:7.2f} ms"
              f"  T_c {1e3 * tc:7.2f} ms")

    surface = tc_case.surface()
    run_solve(surface, tc_case.nodes, tc_case.fixed, tc_case.options, start_level=0)
    t2paper = table2([run_solve(surface, tc_case.nodes, tc_case.fixed, tc_case.options,
                                start_level=0) for _ in range(repeats)])
    print("  paper schedule (start_level=0):")
    for k, n, dx, st, t, tc in t2paper:
        print(f"  k {k}  N_tri {n:6d}  dX {100 * dx:7.3f}%  N_step {st:4d}  T {1e3 * t:7.2f} ms"
              f"  T_c {1e3 * tc:7.2f} ms")

    print("\nWhere the time goes (torus compression, instrumented)")
    profile = profile_solve(tc_case)
    for p in profile[0]:
        print(f"  k {p.level} N_tri {p.triangles:6d} steps {p.steps:4d} evals {p.evals:4d} "
              f"{1e6 * p.eval_s / max(p.evals, 1):6.0f} us/eval  level {1e3 * p.time_s:7.2f} ms"
              f"  eval {1e3 * p.eval_s:6.2f}  line search {1e3 * p.line_search_s:6.2f}  "
              f"springs {1e3 * p.spring_s:5.2f}")
    print(f"  total {1e3 * profile[1]:.1f} ms, outside levels {1e3 * profile[2]:.1f} ms")

    print("\nStart level (torus compression)")
    sweep = []
    for k in range(min(5, len(tc_case.levels))):
        surface = tc_case.surface()
        run_solve(surface, tc_case.nodes, tc_case.fixed, tc_case.options, start_level=k)
        runs = [run_solve(surface, tc_case.nodes, tc_case.fixed, tc_case.options, start_level=k)
                for _ in range(repeats)]
        res = runs[0].result
        term = tc_case.levels[res.terminal_level].n_faces if res.terminal_level >= 0 else 0
        t = Timing(tuple(r.wall for r in runs))
        sweep.append((k, tc_case.levels[k].n_faces, t, term,
                      sum(s.steps for s in res.levels), res.rel_volume_error))
        print(f"  start {k} ({tc_case.levels[k].n_faces} tri): T2 {t.ms()} ms, terminal {term}")

    print("\nFirst progress record (fresh surface / set up)")
    latency = {}
    for case in cases:
        cold = run_solve(case.surface(), case.nodes, case.fixed, case.options).first_record
        row = next(r for r in rows if r.case == case.key and r.variant.startswith("estimate"))
        warm = float(np.median([r.first_record for r in row.t2_runs]))
        latency[case.key] = (cold, warm)
        print(f"  {case.key:18s} {1e3 * cold:6.2f} ms / {1e3 * warm:6.2f} ms")

    figures: list[str] = []
    if out is not None and not args.no_figures:
        for case in cases:
            est = [r for r in rows if r.case == case.key]
            row = est[-1]  # the paper-size row when there is one
            name = f"fig{FIGURES[case.key]}_{case.key.replace('-', '_')}.png"
            why = draw_figure(row, case.size, out.parent / name)
            if why:
                notes.append(why)
                print("  " + why)
                break
            figures.append(name)
        if figures:
            print(f"\nFigures: {', '.join(figures)}")

    print("\nScale: volume + gradient evaluation")
    scale = []
    sizes = [4096, 65536] if quick else list(SCALE_TORI)
    from core.shapes import torus  # noqa: PLC0415

    for n in sizes:
        mesh = torus(*SCALE_TORI[n])
        for shape in ((3, 3, 3), (5, 5, 5)):
            s = scale_row(mesh, shape, max(repeats, 5) if not quick else repeats)
            scale.append(s)
            ref = f"reference {s.t_reference.ms(2)} ms" if s.t_reference else ""
            print(f"  {s.triangles:8d} tri {s.nodes:4d} nodes {s.form:8s} eval {s.t_eval.ms(2)}"
                  f" ms  volume {s.t_volume.ms(2)} ms  {ref}")
        del mesh

    arma = None
    if not quick:
        print("\nArmadillo (child process)")
        arma, why = run_armadillo(models, repeats)
        if arma is None:
            notes.append(why)
            print("  " + why)
        else:
            print(f"  load {arma['load_s']:.2f} s, pyramid {arma['pyramid_s']:.2f} s, first "
                  f"solve {arma['solve_cold_s']:.3f} s, later {np.median(arma['solve_s']):.3f} s,"
                  f" peak RSS {arma['peak_rss_mb']:.0f} MB, levels {arma['levels']}")
            latency["armadillo"] = (arma["first_record_cold_s"],
                                    float(np.median(arma["first_record_s"])))

    targets = evaluate_targets(rows, scale, arma, latency)
    print("\nTargets")
    for t in targets:
        mark = "not measured" if t.met is None else ("MET" if t.met else "MISSED")
        print(f"  [{mark}] {t.name}: {t.measured}")

    if out is not None:
        text = render(env, quick, repeats, rows, t2rows, profile, sweep, scale, arma, latency,
                      targets, figures, notes, _kept_part(out), t2paper)
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out, text)
        print(f"\nWrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
