"""The first evaluation of a fresh process, while the compiled kernels load in the background.

A program's first volume evaluation large enough to start the kernels
(``isochor.core.kernels.START_SIZE`` faces) runs on the NumPy path while a background thread
imports numba and loads the kernels from its cache (or compiles them): it never waits for
them. :func:`first_evaluation` starts a fresh interpreter per repeat (:func:`child`), which
times that first evaluation, then how long the kernels took to arrive after it, then the
NumPy path's evaluation once warm, on the torus of ``tests/test_kernels.py`` (6144
triangles, a 3x3x3 lattice).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass

from benchmarks import BLAS_ENV
from benchmarks.scale import ROOT
from benchmarks.timing import Timing


@dataclass(frozen=True)
class FirstEvaluation:
    """What the fresh processes measured, one value per process."""

    first: Timing  #: the first evaluation, NumPy path while the kernels load
    load: Timing  #: from the end of the first evaluation until the kernels were ready
    warm: Timing  #: the NumPy path's evaluation in the same process, warm (fastest of 5)
    statuses: tuple[str, ...]  #: ``kernels.status()`` right after each first evaluation


def child() -> None:
    """In a fresh interpreter: print the numbers as one JSON line."""
    from isochor.core import kernels
    from isochor.core.lattice import Lattice
    from isochor.core.scenario.shapes import torus
    from isochor.core.volume import VolumeOperator

    mesh = torus(64, 48)
    lattice = Lattice.around(mesh.vertices, (3, 3, 3))
    basis = lattice.point_basis(mesh.vertices)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)

    def evaluate():
        v, g = op.value_and_gradient(basis.apply(lattice.rest_nodes), mesh.center)
        return v, basis.apply_transpose(g)

    t = time.perf_counter()
    evaluate()
    first = time.perf_counter() - t
    status = kernels.status()
    t = time.perf_counter()
    kernels.ready(timeout=900)
    load = time.perf_counter() - t
    warm = []
    with kernels.numpy_path():
        for _ in range(5):
            t = time.perf_counter()
            evaluate()
            warm.append(time.perf_counter() - t)
    print(json.dumps({"first": first, "status": status, "load": load, "warm": min(warm)}))


def first_evaluation(repeats: int, timeout: float = 900) -> FirstEvaluation:
    """:func:`child` in ``repeats`` fresh interpreters (at least one), one after another."""
    env = dict(os.environ)
    for v in BLAS_ENV:
        env.setdefault(v, "1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    code = "from benchmarks.first_evaluation import child; child()"
    runs = []
    for _ in range(max(1, repeats)):
        proc = subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
            cwd=str(ROOT),
            check=True,
        )
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return FirstEvaluation(
        *(Timing(tuple(r[k] for r in runs)) for k in ("first", "load", "warm")),
        tuple(r["status"] for r in runs),
    )
