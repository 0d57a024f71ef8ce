"""The install a studio adopts: the wheel built from the source files carries the MIT
licence, and ``pip install isochor`` (no extras) in a fresh virtual environment gives the
library and the command line without PySide6, VTK or pyvista; the editor then says in one
line what to install (``pip install 'isochor[gui]'``).

The fresh environment installs the wheel with pip as a user would (NumPy, SciPy, trimesh,
fast-simplification, threadpoolctl, Pillow from pip's cache or the index); where they cannot
be fetched the test skips, saying why (outside CI)."""

from __future__ import annotations

import json
import os
import subprocess
import venv
import zipfile
from pathlib import Path

import pytest

from isochor.core.defaults import TOL_VOLUME
from tests.test_structure import _OFFLINE, _build_wheel, _copy_sources, _version

#: the editor's libraries, none of which a lean install may hold
GUI = ("PySide6", "shiboken6", "vtk", "vtkmodules", "pyvista", "pyvistaqt")
#: seconds for one install into the fresh environment (about 45 s with a warm cache)
INSTALL_TIMEOUT = 600

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel of the files git would commit, built without network."""
    src, out = tmp_path_factory.mktemp("src"), tmp_path_factory.mktemp("wheel")
    _copy_sources(src)
    return _build_wheel(src, out)


@pytest.fixture(scope="module")
def lean(wheel, tmp_path_factory) -> Path:
    """A fresh virtual environment with ``pip install isochor`` from the wheel: its bin/."""
    where = tmp_path_factory.mktemp("lean") / "venv"
    venv.create(where, with_pip=True)
    bin_dir = where / "bin"
    pip = [str(bin_dir / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    try:
        run = subprocess.run(
            [*pip, str(wheel)], capture_output=True, text=True, timeout=INSTALL_TIMEOUT
        )
    except subprocess.TimeoutExpired:
        pytest.skip(f"pip install isochor took more than {INSTALL_TIMEOUT} s (slow network?)")
    if run.returncode != 0 and any(s in run.stderr for s in _OFFLINE) and not os.environ.get("CI"):
        pytest.skip(f"the dependencies cannot be fetched: {run.stderr.strip().splitlines()[-1]}")
    assert run.returncode == 0, run.stderr
    return bin_dir


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """A command of the lean environment, outside the repository, with no display and no
    path into the source tree (what it finds is what the wheel installed)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "DISPLAY")}
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_the_wheel_carries_the_licence(wheel):
    dist_info = f"isochor-{_version()}.dist-info/"
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        metadata = archive.read(dist_info + "METADATA").decode()
        licence = archive.read(dist_info + "licenses/LICENSE").decode()
    assert "\nLicense-Expression: MIT\n" in metadata
    assert "\nLicense-File: LICENSE\n" in metadata
    assert licence == (Path(__file__).parents[1] / "LICENSE").read_text()
    assert licence.startswith("MIT License") and "Isochor developers" in licence
    # the lean requirements: the editor's libraries only under the gui extra
    requires = [line for line in metadata.splitlines() if line.startswith("Requires-Dist:")]
    plain = [r for r in requires if "extra ==" not in r]
    assert not [r for r in plain if any(g.lower() in r.lower() for g in GUI)], plain
    assert any("PySide6-Essentials" in r and 'extra == "gui"' in r for r in requires), requires
    assert f"{dist_info}licenses/LICENSE" in names


def test_the_lean_install_has_no_gui_libraries(lean, tmp_path):
    code = (
        "import importlib.util, json\n"
        f"print(json.dumps({{n: importlib.util.find_spec(n) is not None for n in {GUI!r}}}))\n"
    )
    run = _run([str(lean / "python"), "-c", code], tmp_path)
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout)
    assert found == dict.fromkeys(GUI, False), found


def test_the_lean_command_line_solves(lean, tmp_path):
    run = _run(
        [str(lean / "isochor"), "solve", "--example", "torus-compression", "-q"]
        + ["--out", "torus.ply", "--report", "report.json"],
        tmp_path,
    )
    assert run.returncode == 0, run.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["converged"] is True
    assert abs(report["relative_volume_error"]) <= TOL_VOLUME
    assert (tmp_path / "torus.ply").stat().st_size > 0
    listed = _run([str(lean / "isochor"), "examples"], tmp_path)
    assert listed.returncode == 0 and "torus-compression" in listed.stdout, listed


def test_the_lean_api_deforms(lean, tmp_path):
    """``isochor.deform`` on a sphere whose top is pushed down, the bottom pinned: the
    volume kept to the solver's tolerance, the top moved."""
    code = (
        "import json, trimesh, isochor\n"
        "ball = trimesh.creation.icosphere(subdivisions=3)\n"
        "r = isochor.deform(ball, lattice=(3, 3, 3), moves={(1, 1, 2): (0.0, 0.0, -0.5)},\n"
        "                   pins=[(i, j, 0) for i in range(3) for j in range(3)])\n"
        "print(json.dumps({'converged': bool(r.converged),\n"
        "                  'ratio': float(r.mesh.volume / ball.volume),\n"
        "                  'top': float(r.mesh.vertices[:, 2].max()),\n"
        "                  'type': type(r.mesh).__name__}))\n"
    )
    run = _run([str(lean / "python"), "-c", code], tmp_path)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout.splitlines()[-1])
    assert out["converged"] and out["type"] == "Trimesh"
    assert abs(out["ratio"] - 1) <= TOL_VOLUME, out
    assert out["top"] < 0.95, out  # the top came down (the sphere's top is at 1)


@pytest.mark.parametrize(
    "command",
    [
        ["isochor"],
        ["isochor", "edit", "model.obj"],
        ["isochor-editor"],
        ["python", "-m", "isochor"],
    ],
    ids=["isochor", "edit", "isochor-editor", "python-m"],
)
def test_the_lean_editor_says_what_to_install(lean, tmp_path, command):
    run = _run([str(lean / command[0]), *command[1:]], tmp_path)
    assert run.returncode == 1, run
    assert run.stdout == ""
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in run.stderr, run.stderr
    assert lines[0].startswith("isochor: the editor needs PySide6")
    assert "pip install 'isochor[gui]'" in lines[0]


def test_the_full_install_finds_the_editor_libraries():
    """The check above can fail: in this (full) environment nothing is missing."""
    from isochor.app.cli.launch import missing_gui

    assert missing_gui() is None
