"""A cold ``isochor solve`` imports only what it uses (a contract on ``sys.modules``, checked
in a fresh process), and the plain OBJ reader that spares it trimesh reads what trimesh
reads. How long a cold command takes is the benchmark's (benchmarks/first_use.py)."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from isochor.core.io.meshio import load_mesh, mesh_bytes, plain_obj
from isochor.core.scenario.shapes import torus
from tests.models import CLOSED, OPEN, available, icosphere

ROOT = Path(__file__).resolve().parents[1]

#: what a headless solve never needs: the GUI, the general mesh library, the parts of SciPy
#: the solver does not call, the compiler (a small model solves on the NumPy path), the
#: plotting and console libraries some dependencies bring along
UNUSED = (
    "trimesh",
    "scipy.optimize",
    "scipy.spatial",
    "scipy.interpolate",
    "scipy.stats",
    "numba",
    "llvmlite",
    "PySide6",
    "vtk",
    "vtkmodules",
    "pyvista",
    "pyvistaqt",
    "matplotlib",
    "PIL",
    "rich",
    "cyclopts",
)

_PROBE = (
    "import sys, json\n"
    "from isochor.app.cli.main import main\n"
    "rc = main(sys.argv[1:])\n"
    "print('MODULES:' + json.dumps(sorted(sys.modules)))\n"
    "sys.exit(rc)\n"
)


def modules_of_a_cold_command(args: list[str], cwd: Path) -> set[str]:
    """The modules a fresh ``isochor ARGS`` process holds when it is done (it must succeed)."""
    env = {k: v for k, v in os.environ.items() if k != "ISOCHOR_NO_JIT"}
    proc = subprocess.run(
        [sys.executable, "-c", _PROBE, *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    line = next(s for s in proc.stdout.splitlines() if s.startswith("MODULES:"))
    return set(json.loads(line[len("MODULES:") :]))


def imported(modules: set[str], package: str) -> list[str]:
    return sorted(m for m in modules if m == package or m.startswith(package + "."))


def _scenario(tmp_path: Path, model: Path) -> Path:
    doc = {
        "model": {"path": str(model)},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": [2, 2, 2], "by": [0.2, 0.0, 0.0]}],
    }
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_a_cold_solve_of_a_model_file_imports_only_what_it_uses(tmp_path, suffix):
    model = tmp_path / f"ring{suffix}"
    model.write_bytes(mesh_bytes(torus(24, 12), suffix))
    scenario = _scenario(tmp_path, model)
    out = tmp_path / f"out{suffix}"
    args = ["solve", str(scenario), "--out", str(out), "--report", str(tmp_path / "r.json")]
    modules = modules_of_a_cold_command([*args, "-q"], tmp_path)
    assert {"numpy", "scipy.sparse", "isochor.core.solve.multilevel"} <= modules
    assert out.is_file() and json.loads((tmp_path / "r.json").read_text())["converged"]
    for package in UNUSED:
        assert not imported(modules, package), f"{package} imported: {imported(modules, package)}"


def test_a_cold_solve_of_an_example_imports_only_what_it_uses(tmp_path):
    modules = modules_of_a_cold_command(["solve", "--example", "torus-compression", "-q"], tmp_path)
    assert "isochor.core.solve.multilevel" in modules
    for package in UNUSED:
        assert not imported(modules, package), f"{package} imported: {imported(modules, package)}"


def _trimesh_arrays(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """What trimesh's OBJ reader gives for ``data``, as the model reader calls it."""
    import trimesh

    loaded = trimesh.load_mesh(io.BytesIO(data), file_type="obj", process=False)
    if isinstance(loaded, trimesh.Scene):
        loaded = loaded.to_mesh()
    return np.asarray(loaded.vertices, np.float64), np.asarray(loaded.faces, np.int64)


def _plain_files() -> list[tuple[str, bytes]]:
    """OBJ files of the plain kind: written by Isochor, by hand (CRLF, comments, a smoothing
    group, an object name, a vertex no triangle uses), and the shared models of that kind."""
    files = [
        ("sphere written by isochor", mesh_bytes(icosphere(3), ".obj")),
        ("ring written by isochor", mesh_bytes(torus(16, 8), ".obj")),
        (
            "by hand",
            b"# a tetrahedron\r\no tet\r\nv 0 0 0\r\nv 1 0 0\r\nv 9 9 9\r\nv 0 1 0\r\n"
            b"v 0 0 1.5e0\r\ns off\r\nf 1 4 2\r\nf 1 2 5\r\n\r\nf 1 5 4\r\nf 2 4 5\r\n",
        ),
    ]
    for name in (*CLOSED, *OPEN):
        path = available(name)
        if path is not None and name.endswith(".obj"):
            files.append((name, path.read_bytes()))
    return files


@pytest.mark.parametrize(
    "name, data", _plain_files(), ids=lambda x: x if isinstance(x, str) else ""
)
def test_the_plain_obj_reader_reads_what_trimesh_reads(name, data):
    direct = plain_obj(data)
    if direct is None:  # a shared model of another kind: trimesh reads it (the next test)
        assert name in CLOSED or name in OPEN, name
        return
    v, f = _trimesh_arrays(data)
    assert np.array_equal(direct[0], v) and np.array_equal(direct[1], f)
    assert direct[0].dtype == np.float64 and direct[1].dtype == np.int64


@pytest.mark.parametrize(
    "data",
    [
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",  # texture indices
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n",  # a quad
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",  # relative indices
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",  # no vertex 0 in OBJ
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",  # no vertex 4
        b"v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n",  # not a number
        b"v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nf 1 2 3\n",  # vertex colours
        b"o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nv 0 0 1\nf 1 2 4\n",  # two objects
        b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",  # materials
        b"v 0 0 0\nv 1 0 0\n",  # no faces
    ],
)
def test_the_plain_obj_reader_leaves_every_other_obj_to_trimesh(data):
    assert plain_obj(data) is None


def test_a_model_of_another_kind_still_loads_through_trimesh(tmp_path):
    path = tmp_path / "quads.obj"  # a cube of quads, with texture coordinates
    corners = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    quads = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    text = "".join(f"v {x} {y} {z}\n" for x, y, z in corners) + "vt 0 0\n"
    text += "".join("f " + " ".join(f"{i}/1" for i in q) + "\n" for q in quads)
    path.write_text(text)
    assert plain_obj(path.read_bytes()) is None
    loaded = load_mesh(path)
    assert loaded.mesh.n_faces == 12 and loaded.volume == pytest.approx(1.0, rel=1e-12)
