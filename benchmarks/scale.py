"""Evaluation at scale (torus meshes up to a million triangles) and the 346k armadillo (load,
pyramid, solves, memory, and the export's rewrite of its file)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from benchmarks import BLAS_ENV
from benchmarks.cases import run_solve
from benchmarks.timing import Timing, peak_rss_mb, time_call
from isochor.core.lattice import Lattice
from isochor.core.mesh import TriMesh
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import Model, Problem
from isochor.core.solve.multilevel import EmbeddedSurface
from isochor.core.solve.solver import SolverOptions
from isochor.core.volume import VolumeOperator

#: the repository (the folder that holds ``benchmarks/``)
ROOT = Path(__file__).resolve().parents[1]
ARMADILLO = "armadillo_loop1_346k.ply"
#: triangles -> (nu, nv) of ``isochor.core.scenario.shapes.torus``: 2 nu nv triangles
SCALE_TORI = {4096: (64, 32), 65536: (256, 128), 262144: (512, 256), 1048576: (1024, 512)}


@dataclass
class ScaleRow:
    """One volume + gradient evaluation in node space, timed."""

    triangles: int
    nodes: int
    form: str  #: "dense" or "factored" basis (the one that evaluates)
    setup_s: float  #: basis and VolumeOperator, one run
    t_eval: Timing  #: basis apply + volume and gradient + basis transpose
    t_volume: Timing  #: volume and gradient alone (vertex space)
    t_reference: Timing | None  #: the straightforward NumPy version (per-face np.cross)


class ReferenceEvaluation:
    """The straightforward NumPy evaluation Isochor started with, kept for comparison.

    A dense (or k-sliced factored) basis in point-major layout, three ``np.cross`` per face
    and a sparse corner-to-vertex gather.
    """

    def __init__(self, lattice: Lattice, mesh: TriMesh, dense_limit: int = 8_000_000):
        from isochor.core.lattice import bernstein

        uvw = lattice.to_parameters(mesh.vertices)
        nl, nm, nn = lattice.shape
        bu, bv, bw = (bernstein(d - 1, uvw[:, i]) for i, d in enumerate((nl, nm, nn)))
        p = len(uvw)
        self.shape, self.p = (nl, nm, nn), p
        self.buv = (bu[:, :, None] * bv[:, None, :]).reshape(p, nl * nm)
        self.bw = np.ascontiguousarray(bw)
        self.dense = None
        if p * nl * nm * nn <= dense_limit:
            self.dense = (self.buv[:, :, None] * bw[:, None, :]).reshape(p, -1)
        faces = mesh.faces
        f = len(faces)
        self.f0, self.f1, self.f2 = (faces[:, i] for i in range(3))
        self.gather = sp.csr_matrix(
            (np.ones(3 * f), (faces.T.ravel(), np.arange(3 * f))), shape=(p, 3 * f)
        )

    def apply(self, x: np.ndarray) -> np.ndarray:
        """(p, 3) points for (nodes, 3) node positions."""
        if self.dense is not None:
            return self.dense @ x
        nl, nm, nn = self.shape
        xr = x.reshape(nl * nm, nn, 3)
        out = np.zeros((self.p, 3))
        for k in range(nn):
            out += self.bw[:, k, None] * (self.buv @ xr[:, k, :])
        return out

    def apply_transpose(self, g: np.ndarray) -> np.ndarray:
        """(nodes, 3) for (p, 3) per-point values."""
        if self.dense is not None:
            return self.dense.T @ g
        nl, nm, nn = self.shape
        out = np.empty((nl * nm, nn, 3))
        for k in range(nn):
            out[:, k, :] = self.buv.T @ (self.bw[:, k, None] * g)
        return out.reshape(nl * nm * nn, 3)

    def __call__(self, x: np.ndarray, center: np.ndarray) -> tuple[float, np.ndarray]:
        """Volume and its (nodes, 3) gradient for node positions ``x``."""
        v = self.apply(x) - center
        a, b, c = v[self.f0], v[self.f1], v[self.f2]
        bc = np.cross(b, c)
        vol = float(np.einsum("ij,ij->", a, bc) / 6.0)
        corners = np.concatenate([bc, np.cross(c, a), np.cross(a, b)])
        return vol, self.apply_transpose((self.gather @ corners) / 6.0)


def scale_row(
    mesh: TriMesh, shape: tuple[int, int, int], repeats: int, reference: bool = True
) -> ScaleRow:
    """Time one volume + gradient evaluation in node space on ``mesh``.

    Raises AssertionError when the evaluation disagrees with :class:`ReferenceEvaluation`.
    """
    lattice = Lattice.around(mesh.vertices, shape)
    t = time.perf_counter()
    basis = lattice.point_basis(mesh.vertices)
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
        same_v = abs(v1 - v0) <= 1e-10 * abs(v0)
        if not (same_v and np.allclose(g1, g0, rtol=1e-8, atol=1e-10 * np.abs(g0).max())):
            raise AssertionError("the evaluation disagrees with the reference version")
        t_ref = time_call(lambda: ref(x, center), max(1, min(repeats, 5)))
        del ref
    form = "factored" if basis.buv is not None else "dense"
    return ScaleRow(mesh.n_faces, lattice.n_nodes, form, setup, t_eval, t_vol, t_ref)


def armadillo_bend(levels: list[TriMesh], shape=(5, 5, 5), angle_deg: float = 30.0):
    """A bend of a model.

    Lattice layers along its longest axis; the first layer pinned, the last turned by
    ``angle_deg`` about the next-longest axis through the centre of the layer before it.

    Returns
    -------
    (lattice, nodes (n, 3), fixed (n,) bool)
    """
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


#: the map the export timing gives the file back through: affine, not orthogonal
REWRITE_MAP = (
    np.array([[1.3, 0.4, -0.2], [0.1, 0.8, 0.3], [-0.3, 0.2, 1.1]]),
    np.array([0.5, -1.25, 2.0]),
)


def rewrite_seconds(path: str | Path, repeats: int) -> list[float]:
    """Seconds :func:`isochor.core.io.roundtrip.rewrite` takes to give the model file back
    deformed, less the time of its one call of the map: the file's own work (reading the
    positions, writing them back, keeping everything else). One untimed warm-up run, then
    ``repeats`` (at least one)."""
    from isochor.core.io.roundtrip import rewrite

    data = Path(path).read_bytes()
    suffix = Path(path).suffix.lower()
    a, b = REWRITE_MAP

    def once() -> float:
        spent = []

        def deform(x: np.ndarray) -> np.ndarray:
            t = time.perf_counter()
            out = x @ a.T + b
            spent.append(time.perf_counter() - t)
            return out

        def jacobian(x: np.ndarray) -> np.ndarray:
            return np.broadcast_to(a, (len(x), 3, 3)).copy()

        t = time.perf_counter()
        rewrite(data, suffix, deform, jacobian)
        return time.perf_counter() - t - sum(spent)

    once()
    return [once() for _ in range(max(1, repeats))]


def armadillo_child(path: str, repeats: int) -> dict:
    """Load, pyramid and bend-solve the armadillo, and give its file back deformed (the
    export's rewrite); returns the numbers (run in a child, ``python -m benchmarks
    --armadillo-child PLY``, for its own peak memory)."""
    from isochor.core import kernels
    from isochor.core.io.meshio import load_mesh
    from isochor.core.solve.pyramid import build_pyramid

    out: dict = {"rss_start_mb": peak_rss_mb()}
    t = time.perf_counter()
    kernels.start()  # as load_model does: the kernels load while the model does
    loaded = load_mesh(path)
    out["load_s"] = time.perf_counter() - t
    t = time.perf_counter()
    levels = build_pyramid(loaded.mesh)
    out["pyramid_s"] = time.perf_counter() - t
    out["levels"] = [m.n_faces for m in levels]
    lattice, nodes, fixed = armadillo_bend(levels)
    options = SolverOptions()
    scenario = Scenario({"mesh": str(path)}, lattice_nodes=lattice.shape)
    # the bodies as loading counted them, as the command line's problem has them
    surface = EmbeddedSurface(lattice, levels, n_bodies=loaded.bodies)
    problem = Problem(scenario, surface, nodes, fixed, Model(tuple(levels)))
    cold = run_solve(problem, nodes, fixed, options)
    out["first_record_cold_s"] = cold.first_record
    out["solve_cold_s"] = cold.wall
    runs = [run_solve(problem, nodes, fixed, options) for _ in range(max(1, repeats))]
    out["solve_s"] = [r.wall for r in runs]
    out["first_record_s"] = [r.first_record for r in runs]
    res = runs[0].result
    out["terminal_tri"] = levels[res.terminal_level].n_faces if res.terminal_level >= 0 else 0
    out["dv"] = res.rel_volume_error
    out["converged"] = res.converged
    out["steps"] = [s.steps for s in res.levels]
    out["level_ms"] = [1e3 * s.time_s for s in res.levels]
    out["rewrite_s"] = rewrite_seconds(path, repeats)
    out["peak_rss_mb"] = peak_rss_mb()
    return out


def run_armadillo(models: Path, repeats: int, timeout: float = 600) -> tuple[dict | None, str]:
    """:func:`armadillo_child` in a child process: its numbers, or None and why not."""
    path = models / ARMADILLO
    if not path.is_file():
        return None, f"armadillo skipped: {path} not found"
    env = dict(os.environ)
    for v in BLAS_ENV:
        env.setdefault(v, "1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    cmd = [sys.executable, "-m", "benchmarks", "--armadillo-child", str(path)]
    cmd += ["--repeats", str(repeats)]
    try:
        proc = subprocess.run(
            cmd,
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
            cwd=str(ROOT),
            check=False,
        )
    except subprocess.TimeoutExpired:
        return None, f"armadillo failed: no answer within {timeout:.0f} s"
    if proc.returncode != 0:
        return None, "armadillo failed: " + (proc.stderr.strip().splitlines() or ["?"])[-1]
    return json.loads(proc.stdout.strip().splitlines()[-1]), ""
