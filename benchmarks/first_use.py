"""The First use section (issue 27): what a user meets first, measured from outside.

``python -m benchmarks --only first-use`` runs it alone and replaces the section in
``docs/BENCHMARKS.md``; the full ``python -m benchmarks`` runs it too. Rows:

* the inside test (signed ray crossings per grid column, :mod:`isochor.core.inside`) against
  the exact winding number on the fold guard's sample grids: agreement and time;
* each paper example's first solve, the report's ``solve_time_s`` of a cold
  ``isochor solve --example NAME`` (a fresh process), and the whole cold command;
* ``isochor solve`` with the ``fast`` extra against ``ISOCHOR_NO_JIT=1`` (the same command
  without numba), runs interleaved, on every example and shared model: the ratio of the
  medians. The policy (:func:`isochor.core.kernels.worth`): a model under
  ``WORTH_TRIANGLES`` triangles never loads numba (the compiled solve saves less than
  loading numba costs, about 0.5 s of CPU from a warm cache, and loading it beside the
  solve on two cores slows the solve), so both runs take the same path and the ratio is 1
  within noise; a bigger model starts numba once its level pyramid is made (made in a
  forked child, which numba's memory would add to) and waits for it before building the
  problem;
* the API's first solves on a busy machine when nobody chose BLAS's threads, with the
  solver's one-thread limit and without it (:mod:`benchmarks.api_threads`);
* the first solve of the 1.38M and 5.5M armadillos (one and two midpoint subdivisions of
  the 346k one, made into the cache folder) and the command's peak memory per triangle,
  with the forked child that makes its level pyramid (:class:`TreePeak`).

Each command runs through a two-line wrapper that calls the command line's ``main`` and
then prints its own peak memory and whether numba was imported (the same imports as
``python -m isochor``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks import BLAS_ENV
from benchmarks.api_threads import api_threads_rows
from benchmarks.display import Row, target_table
from benchmarks.drag_cases import big_armadillo
from benchmarks.machine import UNIT_BYTES, machine_unit
from benchmarks.scale import ARMADILLO, ROOT
from benchmarks.timing import Timing

HEADING = "## First use (issue 27)"
#: first solve_time_s targets (seconds) per example; the others 40 ms
FIRST_SOLVE = {"torus-compression": 0.025}
FIRST_SOLVE_DEFAULT = 0.040
COLD_COMMAND = 1.0
#: a cold ``isochor solve`` beyond its own solve (start-up, imports, reading, the report),
#: seconds, at most
BEYOND_SOLVE = 0.5
#: the shared models whose cold commands give the row beyond the solve (small: no numba)
BEYOND_MODELS = ("cow.obj", "kitten.obj", "fertility.obj")
BIG_FIRST_SOLVE = 3.0
BIG_GROWTH = 4.5
BYTES_PER_TRIANGLE = 500.0
AGREEMENT = 0.999
#: the shared models of the ratio rows (those that load; the others are reported)
SHARED = (
    "cow.obj",
    "spot_triangulated.obj",
    "kitten.obj",
    "fertility.obj",
    "torus.obj",
    "torus_knot_quads.obj",
    "two_objects.obj",
    "bunny_watertight.obj",
    ARMADILLO,
)
#: the inside-test rows: shared models small enough for exact winding numbers of a grid
INSIDE_MODELS = ("cow.obj", "spot_triangulated.obj", "kitten.obj", "torus_knot_quads.obj")
BIG5 = "armadillo_5533k.ply"

#: the command in a wrapper that prints its peak resident set (:func:`peak_rss_mb`: its own
#: map's high-water mark; ``ru_maxrss`` keeps the spawning benchmark process's size, which
#: once made the 1.38M command look 3.5 GB)
_WRAP = (
    "import sys, json\n"
    "from isochor.app.cli.main import main\n"
    "rc = main(sys.argv[1:])\n"
    "from benchmarks.timing import peak_rss_mb\n"
    "print('BENCH:' + json.dumps({'rss_mb': peak_rss_mb(), 'numba': 'numba' in sys.modules}),"
    " file=sys.stderr)\n"
    "sys.exit(rc)\n"
)


@dataclass
class Cold:
    """One cold command."""

    wall: float
    solve_s: float | None  #: the report's solve_time_s
    rss_mb: float
    numba: bool
    ok: bool


def cold(args: list[str], folder: Path, jit: bool = True, timeout: float = 1800) -> Cold:
    """``isochor ARGS --report r.json -q`` in a fresh process, timed from outside."""
    env = dict(os.environ)
    for v in BLAS_ENV:
        env.setdefault(v, "1")
    env.pop("ISOCHOR_NO_JIT", None)
    # as a user's command runs: Python writes its bytecode caches on the first run and
    # reads them after (a shell with this set compiled every module of every run: +40 ms)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if not jit:
        env["ISOCHOR_NO_JIT"] = "1"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    report = folder / "r.json"
    report.unlink(missing_ok=True)
    cmd = [sys.executable, "-c", _WRAP, *args, "--report", str(report), "-q"]
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    wall = time.perf_counter() - t
    probe = next(
        (json.loads(s[6:]) for s in proc.stderr.splitlines() if s.startswith("BENCH:")), {}
    )
    solve = json.loads(report.read_text())["solve_time_s"] if report.is_file() else None
    ok = proc.returncode in (0, 3) and solve is not None
    return Cold(wall, solve, probe.get("rss_mb", 0.0), bool(probe.get("numba")), ok)


def model_scenario(path: Path, folder: Path) -> Path:
    """A scenario on the model file: a 3x3x3 lattice, a top corner moved by a tenth of the
    model's size."""
    import trimesh

    mesh = trimesh.load(path, force="mesh", process=False)
    size = float(np.max(mesh.extents))
    doc = {
        "model": {"path": str(path)},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": [2, 2, 2], "by": [0.1 * size, 0.0, 0.0]}],
    }
    out = folder / f"{path.stem}.json"
    out.write_text(json.dumps(doc))
    return out


def _inside_rows(models: Path, repeats: int) -> list[Row]:
    """Agreement of the grid inside test with the exact winding number on the sample grids
    of the examples' probe levels and some shared models; the time of each."""
    from isochor.core.io.meshio import load_mesh
    from isochor.core.scenario.shapes import builtin_levels

    meshes = {}
    for name in ("torus", "club"):
        levels = builtin_levels(name)
        meshes[name] = next(m for m in levels if m.n_faces >= 1000)
    for name in INSIDE_MODELS:
        if (models / name).is_file():
            meshes[name] = load_mesh(models / name).mesh
    agree = total = 0
    worst, fast_t, exact_t = 1.0, [], []
    for mesh in meshes.values():
        same, points, fast, exact = _agreement(mesh, repeats)
        agree, total = agree + same, total + points
        worst = min(worst, same / points)
        fast_t.append(fast)
        exact_t.append(exact)
    share = agree / max(total, 1)
    why = (
        f"{agree} of {total} grid points on {len(meshes)} meshes ({', '.join(meshes)}), the "
        f"worst mesh {100 * worst:.3f} %; per mesh {1e3 * np.median(fast_t):.1f} ms against "
        f"{1e3 * np.median(exact_t):.0f} ms for exact winding numbers (medians)"
    )
    what = f"inside test agrees with the exact winding number: {100 * share:.3f} %"
    t = Timing(tuple(fast_t))
    return [Row(what, t, f">= {100 * AGREEMENT:g} %", share >= AGREEMENT, why)]


def _agreement(mesh, repeats: int) -> tuple[int, int, float, float]:
    """On a grid of about 8000 cell centres over the mesh's box: the points where the
    grid test and the exact winding number agree, the points, and the seconds of each."""
    from benchmarks.timing import time_call
    from isochor.core.bodies import winding_numbers
    from isochor.core.inside import grid_winding

    lo, hi = mesh.bounds
    cells = np.maximum(1, np.rint((hi - lo) / ((np.prod(hi - lo) / 8000) ** (1 / 3))))
    cells = cells.astype(int)
    step = (hi - lo) / cells
    axes = [lo[c] + (np.arange(cells[c]) + 0.5) * step[c] for c in range(3)]
    grid = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    tri = mesh.vertices[mesh.faces]

    def fast():
        return grid_winding(mesh.vertices, mesh.faces, lo, step, cells).ravel()

    def exact():
        return winding_numbers(grid, tri)

    t_fast, t_exact = time_call(fast, repeats), time_call(exact, 1, 0)
    same = int(np.sum((np.abs(fast()) > 0.5) == (np.abs(exact()) > 0.5)))
    return same, len(grid), t_fast.median, t_exact.median


def _ratio_row(name: str, fast: list[Cold], slow: list[Cold]) -> Row:
    tf, ts = Timing(tuple(c.wall for c in fast)), Timing(tuple(c.wall for c in slow))
    ratio = tf.median / ts.median
    loaded = any(c.numba for c in fast)
    noise = max(tf.spread, ts.spread) / ts.median
    # both runs take the same NumPy path when numba is not loaded: the ratio is noise
    same_path = not loaded
    met = all(c.ok for c in fast + slow) and (ratio <= 1.0 or (same_path and ratio - 1 <= noise))
    path = "numba loaded and waited for" if loaded else "numba never loaded (same path)"
    why = f"ratio {ratio:.2f}; without numba {ts.ms(0)} ms; {path}"
    if same_path and ratio > 1.0:
        why += f"; above 1 by less than the runs' spread ({100 * noise:.0f} %)"
    if not all(c.ok for c in fast + slow):
        why += "; a run failed"
    return Row(f"cold isochor solve, fast / without, {name}", tf, "ratio <= 1.0", met, why)


def beyond_solve_row(what: str, runs: dict[str, list[Cold]]) -> Row:
    """A cold command's time beyond its own solve (``wall - solve_time_s``: the interpreter,
    the imports, reading the model, building the problem, writing the report), per model
    the median of its runs; the row is the slowest model's."""
    beyond = {
        name: Timing(tuple(c.wall - c.solve_s for c in cs if c.ok and c.solve_s is not None))
        for name, cs in runs.items()
        if any(c.ok and c.solve_s is not None for c in cs)
    }
    if not beyond:
        return Row(what, None, f"<= {1e3 * BEYOND_SOLVE:g} ms", None, "no run succeeded")
    worst = max(beyond, key=lambda n: beyond[n].median)
    each = "; ".join(
        f"{n} {t.ms(0)} ms beside a {1e3 * float(np.median([c.solve_s or 0 for c in runs[n]])):.0f}"
        " ms solve"
        for n, t in beyond.items()
    )
    met = beyond[worst].median <= BEYOND_SOLVE
    why = (
        f"{each}; what is left is the interpreter, NumPy and scipy.sparse (with its "
        "linalg, which the solver uses) and Isochor's own modules (python -X importtime); "
        "trimesh, scipy.optimize, scipy.spatial and numba are not imported (tests/test_startup.py)"
    )
    return Row(
        f"{what} (slowest: {worst})", beyond[worst], f"<= {1e3 * BEYOND_SOLVE:g} ms", met, why
    )


def read_bandwidth() -> float:
    """Bytes a second one thread reads: the fastest of the machine unit's 1 GB sums
    (:mod:`benchmarks.machine`; a streaming read, far larger than the caches)."""
    unit = machine_unit()
    return UNIT_BYTES / unit.read.lo


def _evaluation_setup(triangles: int, shape=(3, 3, 3)):
    """A torus of about ``triangles`` triangles, its basis, volume operator, random
    nodes and centre (as :func:`benchmarks.scale.scale_row` makes them)."""
    from isochor.core.lattice import Lattice
    from isochor.core.scenario.shapes import torus
    from isochor.core.volume import VolumeOperator

    nu = int(round(np.sqrt(triangles / 4)))
    mesh = torus(2 * nu, nu)
    lattice = Lattice.around(mesh.vertices, shape)
    basis = lattice.point_basis(mesh.vertices)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)
    rng = np.random.default_rng(0)
    x = lattice.rest_nodes + rng.normal(scale=0.02 * lattice.size, size=(lattice.n_nodes, 3))
    return mesh, basis, op, x, mesh.center


def _cpu_ms(fn, repeats: int) -> float:
    """Median CPU time of ``fn`` (all threads), ms."""
    spent = []
    for _ in range(max(3, repeats)):
        c = time.process_time()
        fn()
        spent.append(time.process_time() - c)
    return 1e3 * float(np.median(spent))


def _evaluation_row(repeats: int) -> Row:
    """One volume + gradient evaluation on a million triangles with 27 nodes (compiled,
    :meth:`isochor.core.volume.VolumeOperator.node_gradient`: the basis, the volume's
    gradient and its transpose in one pass), against its read-bandwidth floor: the bytes
    it must read at least once (the points' lattice coordinates and the vertex fans the
    gradient walks) at the bandwidth of one thread's streaming read.

    The reason gives, from the same run: the three passes one after the other (basis
    apply, ``value_and_gradient``, ``apply_transpose``) and each against its own floor
    (the bytes it reads and writes), the CPU time of both (all threads: a loaded
    machine's wall clock is not the only figure), and the one pass on a torus small
    enough for the core's cache, scaled up: what the arithmetic alone costs."""
    from benchmarks.timing import time_call
    from isochor.core import kernels
    from isochor.core.kernels import threads as kernel_threads

    if not kernels.ready(timeout=900):
        return Row("evaluation at the bandwidth floor", None, "<= 3x", None, "no kernels")
    mesh, basis, op, x, center = _evaluation_setup(1048576)

    def one():
        return op.node_gradient(basis, x, center)

    def three():  # what benchmarks.scale.scale_row times
        v, g = op.value_and_gradient(basis.apply(x), center)
        return v, basis.apply_transpose(g)

    points = basis.apply(x)
    grad = op.value_and_gradient(points, center)[1]
    passes = {
        "apply": lambda: basis.apply(x),
        "volume and gradient": lambda: op.value_and_gradient(points, center),
        "transpose": lambda: basis.apply_transpose(grad),
    }
    t_one, t_three = time_call(one, repeats), time_call(three, repeats)
    cpu_one, cpu_three = _cpu_ms(one, repeats), _cpu_ms(three, repeats)
    t_pass = {name: time_call(fn, repeats) for name, fn in passes.items()}
    small, s_basis, s_op, s_x, s_center = _evaluation_setup(32768)  # 16k vertices: 1 MB
    previous = kernel_threads.set_threads(1)
    try:
        cached = _cpu_ms(lambda: s_op.node_gradient(s_basis, s_x, s_center), 5 * repeats)
    finally:
        kernel_threads.set_threads(previous)
    cached *= mesh.n_vertices / small.n_vertices
    ptr, seq = kernels.fans(mesh.faces, mesh.n_vertices)
    uvw, rows = basis.uvw, points.nbytes  # the points and the gradient: (3, m) float64
    need = uvw.nbytes + ptr.nbytes + seq.nbytes
    moved = {  # bytes each of the three passes reads and writes
        "apply": uvw.nbytes + rows,
        "volume and gradient": rows + ptr.nbytes + seq.nbytes + rows,
        "transpose": uvw.nbytes + rows,
    }
    bandwidth = read_bandwidth()
    floor = need / bandwidth
    ratio = t_one.median / floor
    each = ", ".join(
        f"{name} {1e3 * t.median:.2f} ms ({t.median * bandwidth / moved[name]:.1f}x "
        f"its {moved[name] / 1e6:.0f} MB)"
        for name, t in t_pass.items()
    )
    threads = kernel_threads.threads()
    why = (
        f"{ratio:.2f}x the floor {1e3 * floor:.1f} ms ({need / 1e6:.0f} MB at "
        f"{bandwidth / 1e9:.1f} GB/s, one thread), in one pass (node_gradient) on "
        f"{threads} threads, CPU {cpu_one:.1f} ms a run. The three passes one after the "
        f"other: {t_three.ms()} ms, {t_three.median / floor:.2f}x the floor, CPU "
        f"{cpu_three:.1f} ms; {each}: together they move "
        f"{sum(moved.values()) / need:.1f}x the floor's bytes, the one pass about the "
        f"floor's. What is left is arithmetic: the one pass on a torus that fits the "
        f"core's cache takes {cached:.1f} ms of CPU scaled to this size "
        f"({cached / (1e3 * floor):.1f}x the floor on one thread, "
        f"{cached / (1e3 * floor) / threads:.1f}x on {threads} idle cores): the basis "
        "about 3 ns a point each way (some 120 multiply-adds), the fans' three cross "
        "products about 4.5 ns a regular vertex; load average "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs at the end"
    )
    what = f"volume + gradient, {mesh.n_faces} triangles, 27 nodes, against the read floor"
    return Row(what, t_one, "<= 3x the floor", ratio <= 3.0, why)


def run_first_use(models: Path, repeats: int, quick: bool = False) -> tuple[list[Row], list[str]]:
    rows: list[Row] = []
    notes: list[str] = []
    from isochor.core.kernels import WORTH_TRIANGLES
    from isochor.core.scenario.examples import EXAMPLES

    rows += _inside_rows(models, repeats)
    rows.append(_evaluation_row(repeats))
    rows += api_threads_rows(repeats if not quick else 2)
    reps = max(3, repeats if not quick else 2)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in EXAMPLES:
            args = ["solve", "--example", name]
            fast, slow = [], []
            for _ in range(reps):  # interleaved: the machine's load hits both alike
                fast.append(cold(args, folder))
                slow.append(cold(args, folder, jit=False))
            first = Timing(tuple(c.solve_s or np.inf for c in fast))
            limit = FIRST_SOLVE.get(name, FIRST_SOLVE_DEFAULT)
            slow_first = Timing(tuple(c.solve_s or np.inf for c in slow))
            rows.append(
                Row(
                    f"first solve (report's solve_time_s), cold, {name}",
                    first,
                    f"<= {1e3 * limit:g} ms",
                    first.median <= limit,
                    f"without numba {slow_first.ms(1)} ms",
                )
            )
            if name == "torus-compression":
                wall = Timing(tuple(c.wall for c in fast))
                rows.append(
                    Row(
                        "cold isochor solve --example torus-compression, in all",
                        wall,
                        f"<= {1e3 * COLD_COMMAND:g} ms",
                        wall.median <= COLD_COMMAND,
                        "start-up, imports, the built-in torus, the solve and the report",
                    )
                )
            rows.append(_ratio_row(name, fast, slow))
            if name == "torus-compression":
                rows.append(
                    beyond_solve_row("cold isochor solve --example, beyond its solve", {name: fast})
                )
        beyond: dict[str, list[Cold]] = {}
        for name in SHARED if not quick else SHARED[:2]:
            path = models / name
            if not path.is_file():
                notes.append(f"{name}: not in {models}; left out")
                continue
            scenario = model_scenario(path, folder)
            fast, slow = [], []
            for _ in range(reps):
                fast.append(cold(["solve", str(scenario)], folder))
                slow.append(cold(["solve", str(scenario)], folder, jit=False))
            if not any(c.ok for c in fast + slow):  # a model isochor refuses (not closed)
                notes.append(f"{name}: isochor solve refuses it either way; left out")
                continue
            rows.append(_ratio_row(name, fast, slow))
            if name in BEYOND_MODELS:
                beyond[name] = fast
        rows.append(
            beyond_solve_row("cold isochor solve on a model file, beyond its solve", beyond)
        )
        if not quick:
            rows += _big_rows(models, folder, notes)
    notes.append(f"the kernels are loaded for models of {WORTH_TRIANGLES} triangles and more")
    for r in rows:
        print("  " + r.line())
    return rows, notes


def big_armadillo_5m(models: Path) -> Path | None:
    """The 5.5M-triangle armadillo (one midpoint subdivision of the 1.38M one), made once
    into the cache folder beside it; None without the 346k one."""
    big = big_armadillo(models)
    if big is None:
        return None
    out = big.with_name(BIG5)
    if not out.is_file():
        import trimesh

        mesh = trimesh.load(big, process=False)
        v, f = trimesh.remesh.subdivide(mesh.vertices, mesh.faces)
        del mesh
        tmp = out.with_suffix(".tmp.ply")
        trimesh.Trimesh(v, f, process=False).export(tmp)
        tmp.replace(out)
    return out


def _big_rows(models: Path, folder: Path, notes: list[str]) -> list[Row]:
    """The first solve of the 1.38M and 5.5M armadillos (one cold command each) and their
    peak memory per triangle."""
    big = big_armadillo(models)
    if big is None:
        notes.append(f"the big armadillo rows need {models / ARMADILLO}; left out")
        return []
    runs, trees = {}, {}
    for label, path in (("1.38M", big), ("5.5M", big_armadillo_5m(models))):
        scenario = model_scenario(path, folder)
        with TreePeak() as trees[label]:
            runs[label] = (cold(["solve", str(scenario)], folder), _triangles(path))
    rows = []
    c1, c5 = runs["1.38M"][0], runs["5.5M"][0]
    t1 = Timing((c1.solve_s or np.inf,))
    rows.append(
        Row(
            "first solve (solve_time_s), cold, armadillo 1.38M (1 run)",
            t1,
            f"<= {1e3 * BIG_FIRST_SOLVE:g} ms",
            c1.ok and t1.median <= BIG_FIRST_SOLVE,
            f"the whole command {c1.wall:.1f} s",
        )
    )
    t5 = Timing((c5.solve_s or np.inf,))
    growth = t5.median / t1.median
    rows.append(
        Row(
            f"first solve (solve_time_s), cold, armadillo 5.5M (1 run; {growth:.2f}x the 1.38M)",
            t5,
            f"<= {BIG_GROWTH:g}x the 1.38M",
            c5.ok and growth <= BIG_GROWTH,
            f"the whole command {c5.wall:.1f} s",
        )
    )
    for label, (c, n) in runs.items():
        tree = trees[label]
        peak = max(c.rss_mb, tree.peak_mb)
        per = peak * 2**20 / n
        rows.append(
            Row(
                f"peak memory of the command, armadillo {label}: {peak:.0f} MB, "
                f"{per:.0f} bytes a triangle",
                None,
                f"<= {BYTES_PER_TRIANGLE:g} bytes a triangle",
                c.ok and per <= BYTES_PER_TRIANGLE,
                _memory_words(c, tree, n),
            )
        )
    return rows


def _memory_words(c: Cold, tree: TreePeak, n: int) -> str:
    """What the peak memory went to: the pyramid's forked child or the command itself."""
    own = (
        f"the command alone {c.rss_mb:.0f} MB ({c.rss_mb * 2**20 / n:.0f} B a triangle: "
        "reading, numba, the solve, the report)"
    )
    if tree.peak_mb <= 0:
        return f"no forked child seen (the pyramid made in place): {own}"
    child = tree.peak_mb - tree.command_mb
    where = "at the peak" if tree.peak_mb >= c.rss_mb else "below the command's own peak"
    return (
        f"the pyramid's forked child {where}: {child:.0f} MB of its own "
        f"({child * 2**20 / n:.0f} B a triangle: fast-simplification's working copy of the "
        f"finest level and the arrays it is given) beside the command's {tree.command_mb:.0f} "
        f"MB; {own}{'' if c.ok else '; the command failed'}"
    )


class TreePeak:
    """The peak memory of the cold command's forked child with the command, sampled from
    outside every ``every`` seconds while the child lives: the command's resident set plus
    the pages only the child holds (what it allocated and what it copied on writing). The
    pages they share count once, those shared with other programs (libraries) in full: an
    upper bound of what the two hold. The peak of the command alone (in the wrapper)
    is exact for the rest of the run, but a fork's child has its own. Linux only (/proc);
    elsewhere it sees nothing (0)."""

    def __init__(self, every: float = 0.01) -> None:
        self.every = every
        self.peak_mb = 0.0
        self.command_mb = 0.0  #: the command's own share of the peak
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> TreePeak:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        me = os.getpid()
        while not self._stop.wait(self.every):
            for command in _children(me):
                kids = _children(command)
                if not kids:
                    continue
                own = _rollup_mb(command, ("Rss",))
                child = sum(_rollup_mb(k, ("Private_Clean", "Private_Dirty")) for k in kids)
                if own + child > self.peak_mb:
                    self.peak_mb, self.command_mb = own + child, own


def _children(pid: int) -> list[int]:
    out: list[int] = []
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/children") as fh:
                out += [int(k) for k in fh.read().split()]
    except OSError:
        pass
    return out


def _rollup_mb(pid: int, fields: tuple[str, ...]) -> float:
    """The sum of ``fields`` (kB lines) of a process's ``smaps_rollup``, in MB."""
    total = 0
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key in fields:
                    total += int(value.split()[0])
    except OSError:
        pass
    return total / 1024


def _triangles(path: Path) -> int:
    """Triangles of a binary PLY, from its header."""
    with open(path, "rb") as fh:
        for line in fh:
            if line.startswith(b"element face"):
                return int(line.split()[-1])
            if line.startswith(b"end_header"):
                break
    raise ValueError(f"{path}: no face count in the header")


def section(rows: list[Row], notes: list[str], command: str) -> list[str]:
    lines = [
        HEADING,
        "",
        f"`{command}`; medians of the runs (min-max), one run where it says 1. Every",
        "command is a fresh process (`isochor solve ... --report r.json -q`), timed from",
        "outside; 'first solve' is the report's `solve_time_s`. The fast / without rows run",
        "the same command with numba and with `ISOCHOR_NO_JIT=1`, interleaved. Below",
        "`WORTH_TRIANGLES` a command never loads numba: the compiled solve saves less than",
        "loading numba costs (about 0.5 s of CPU from a warm cache; the 346k armadillo's",
        "command took 8.7 s waiting for it against 7.5 s on NumPy), and loading it beside",
        "the solve on two cores slows the solve down; from there on numba starts once the",
        "model's level pyramid is made (in a forked child, whose peak numba's 110 MB would",
        "add to) and the problem is built when it is ready.",
        f"The {machine_unit().words()}; 'u' below is that unit (:mod:`benchmarks.machine`).",
        "",
    ]
    return lines + target_table(rows, notes)
