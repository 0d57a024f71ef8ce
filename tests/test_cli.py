"""The ``isochor`` command line (isochor.app.cli.main), headless: no Qt is imported here."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import trimesh

import isochor.core.solve.multilevel
from isochor.app.cli import main as cli
from isochor.app.cli.main import main
from isochor.core.io.meshio import load_mesh, mesh_bytes
from isochor.core.scenario.examples import EXAMPLES
from isochor.core.scenario.paper_models import bend_scenario, cow_bend_scenario, squash_scenario
from tests.fresh import run_fresh
from tests.models import CLOSED, REFUSED, available, icosphere, model, trimesh_volume

ROOT = Path(__file__).resolve().parents[1]
REPORT_KEYS = {
    "volume_original",
    "volume_final",
    "relative_volume_error",
    "target_volume_ratio",
    "levels",
    "nodes",
    "free_nodes",
    "time_s",
    "warnings",
    "bodies",
    "converged",
}


def exported_volume(path: Path) -> float:
    """Volume of a written mesh, measured by trimesh (not by core)."""
    mesh = trimesh.load_mesh(str(path), process=False)
    mesh.merge_vertices()
    assert mesh.is_watertight and mesh.is_winding_consistent
    return float(mesh.volume)


def solve_cli(tmp_path, scenario, out_name="out.ply", extra=()):
    """Write ``scenario``, run ``isochor solve`` in-process; return (status, report, out)."""
    scene = tmp_path / "scene.json"
    scenario.write(scene)
    out, report = tmp_path / out_name, tmp_path / "report.json"
    status = main(["solve", str(scene), "--out", str(out), "--report", str(report), *extra])
    doc = json.loads(report.read_text()) if report.exists() else None
    return status, doc, out


# -- every closed model loads and solves ----------------------------------------------------
# (model, edit, output format): bends and squashes with 5x2x2 and 4x3x3 lattices
CASES = [
    ("cow.obj", "bend", ".ply"),
    ("cow_flipped_patch.obj", "squash", ".ply"),
    ("spot_triangulated.obj", "squash", ".stl"),
    ("bunny_watertight.obj", "bend", ".ply"),
    ("kitten.obj", "bend", ".obj"),
    ("fertility.obj", "squash", ".ply"),
    ("torus_knot_quads.obj", "bend", ".ply"),
    ("multibody_inconsistent_winding.stl", "squash", ".ply"),
]


def test_cases_cover_every_closed_model():
    assert set(CLOSED) <= {c[0] for c in CASES}


@pytest.mark.parametrize("name, edit, suffix", CASES)
def test_model_solves_and_the_export_keeps_the_volume(tmp_path, capsys, name, edit, suffix):
    path = model(name)
    scenario = bend_scenario(path) if edit == "bend" else squash_scenario(path)
    assert scenario.lattice_nodes == ((5, 2, 2) if edit == "bend" else (4, 3, 3))
    status, report, out = solve_cli(tmp_path, scenario, f"out{suffix}")
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert set(report) >= REPORT_KEYS
    assert report["converged"] is True
    # the loaded model's volume, measured independently of isochor.core.io.meshio
    if name == "cow_flipped_patch.obj":
        reference = trimesh_volume(model("cow.obj"))  # the repaired cow is the cow
    elif name.startswith("multibody"):
        reference = report["volume_original"]  # checked against convex hulls in test_meshio
    else:
        reference = trimesh_volume(path)
    assert report["volume_original"] == pytest.approx(reference, rel=1e-9)
    final = exported_volume(out)
    assert final == pytest.approx(reference, rel=1e-3)  # the issue: within 0.1%
    assert abs(report["relative_volume_error"]) <= 5e-4
    assert report["volume_final"] == pytest.approx(final, rel=1e-5)  # STL is float32
    # the export is the full-resolution mesh, deformed
    assert len(trimesh.load_mesh(str(out), process=False).faces) == load_mesh(path).mesh.n_faces
    n_nodes = int(np.prod(scenario.lattice_nodes))
    assert len(report["nodes"]) == n_nodes and report["free_nodes"] == 12
    assert report["levels"] and report["levels"][-1]["relative_volume_error"] is not None
    assert {
        "level",
        "triangles",
        "steps",
        "time_s",
        "max_node_change",
        "relative_volume_error",
    } <= set(report["levels"][0])
    # one printed row per level, as the levels finished
    rows = [line.split() for line in captured.out.splitlines()[1:] if line[:5].strip().isdigit()]
    assert [int(r[0]) for r in rows] == [lvl["level"] for lvl in report["levels"]]
    assert [int(r[1]) for r in rows] == [lvl["triangles"] for lvl in report["levels"]]
    warned = [line for line in captured.err.splitlines() if "isochor: warning:" in line]
    if name in ("cow_flipped_patch.obj", "multibody_inconsistent_winding.stl"):
        assert report["warnings"] and warned
    else:
        assert report["warnings"] == [] and warned == []
    # what the other format cannot carry is said, once, and in the report too
    notes = [line for line in captured.err.splitlines() if line.startswith("isochor: note:")]
    assert len(notes) == len(report["export_notes"])
    if name in ("spot_triangulated.obj", "torus_knot_quads.obj"):
        assert "texture coordinates" in notes[0] or "normals" in notes[0], notes
    assert report["bodies"] == (2 if name.startswith("multibody") else 1)


def test_a_repaired_model_exported_in_its_own_format_keeps_its_own_faces(tmp_path, capsys):
    """cow_flipped_patch.obj has 300 triangles wound the wrong way: the solver works on the
    repaired cow; the export in OBJ keeps the file's faces as they were (the same asset),
    says so, and the same repair of the exported file gives the preserved volume."""
    path = model("cow_flipped_patch.obj")
    status, report, out = solve_cli(tmp_path, squash_scenario(path), "out.obj")
    err = capsys.readouterr().err
    assert status == 0 and report["converged"], err
    faces = lambda p: [ln for ln in p.read_text().splitlines() if ln.startswith("f ")]  # noqa: E731
    assert faces(out) == faces(path)
    assert "keeps cow_flipped_patch.obj's own faces as they were" in err
    assert any("own faces" in note for note in report["export_notes"])
    again = load_mesh(out)
    assert again.volume == pytest.approx(trimesh_volume(model("cow.obj")), rel=1e-3)


def test_cow_bending_plate_4(tmp_path, capsys):
    """The paper's cow bending: 5804 triangles, 5x2x2 lattice, the head end bent."""
    scenario = cow_bend_scenario(model("cow.obj").parent)
    status, report, out = solve_cli(tmp_path, scenario, "cow.obj")
    assert status == 0, capsys.readouterr().err
    assert report["triangles"] == 5804 and report["lattice"] == [5, 2, 2]
    assert report["free_nodes"] == 12 and report["converged"]
    assert abs(report["relative_volume_error"]) <= 7e-4  # Table 1: 0.07%
    assert exported_volume(out) == pytest.approx(trimesh_volume(model("cow.obj")), rel=1e-3)
    # the free middle layers moved away from their rest places to give the volume back
    nodes = np.array(report["nodes"]).reshape(5, 2, 2, 3)
    rest = load_mesh(model("cow.obj")).mesh.vertices
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    pad = 0.05 * (hi - lo)
    rest_x = np.linspace(lo[0] - pad[0], hi[0] + pad[0], 5)
    assert np.allclose(nodes[0, :, :, 0], rest_x[0])  # pinned
    assert np.max(np.abs(nodes[1:4, :, :, 0] - rest_x[1:4, None, None])) > 1e-3
    deformed = trimesh.load_mesh(str(out), process=False)
    original = trimesh.load_mesh(str(model("cow.obj")), process=False)
    head = original.vertices[:, 0] > 4.0
    assert deformed.vertices[head, 1].mean() > original.vertices[head, 1].mean() + 0.5


def test_example_solves_in_a_subprocess_without_qt(tmp_path):
    code = (
        "from isochor.app.cli.main import main\n"
        f"status = main(['solve', '--example', 'torus-compression', '--out', "
        f"{str(tmp_path / 't.stl')!r}, '--report', {str(tmp_path / 'r.json')!r}])\n"
        "print('status', status)\n"
    )
    run, gui = run_fresh(
        code,
        cwd=ROOT,
        timeout=300,
        extra=frozenset({"isochor.app.cli.launch", "isochor.app.window.mainwindow"}),
    )
    assert run.returncode == 0 and "status 0" in run.stdout, run.stderr
    assert gui == []
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["converged"] and len(report["nodes"]) == 27 and report["free_nodes"] == 9
    assert report["volume_final"] == pytest.approx(exported_volume(tmp_path / "t.stl"), rel=1e-5)


def test_refused_model_in_a_subprocess_is_one_line(tmp_path):
    bad = tmp_path / "broken.ply"
    bad.write_bytes(mesh_bytes(icosphere(2), ".ply")[:700])
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps({"model": {"path": "broken.ply"}}))
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "isochor.app.cli.main",
            "solve",
            str(scene),
            "--out",
            str(tmp_path / "o.ply"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 1
    assert run.stderr.count("\n") == 1 and run.stderr.startswith("isochor: ")
    assert "broken.ply" in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "o.ply").exists()


# -- refused files ------------------------------------------------------------------------
def _refused(tmp_path) -> dict[str, Path]:
    files = {}
    for name in REFUSED:
        if (path := available(name)) is not None:
            files[name] = path
    good = mesh_bytes(icosphere(2), ".ply")
    for name, data in {
        "empty.obj": b"",
        "garbage.stl": np.random.default_rng(3).bytes(2000),
        "garbage.obj": b"this is not a mesh\n",
        "truncated.ply": good[: len(good) // 2],
        "truncated.obj": mesh_bytes(icosphere(2), ".obj")[:4000],
        "unknown.xyz": b"1 2 3\n",
    }.items():
        (tmp_path / name).write_bytes(data)
        files[name] = tmp_path / name
    files["missing.obj"] = tmp_path / "missing.obj"
    return files


def test_every_refused_file_gives_one_line_and_status_1(tmp_path, capsys):
    files = _refused(tmp_path)
    assert len(files) >= 7
    for name, path in files.items():
        scene = tmp_path / f"{name}.json"
        scene.write_text(
            json.dumps({"model": {"path": str(path)}, "lattice": {"nodes": [4, 3, 3]}})
        )
        out = tmp_path / "never.ply"
        status = main(
            ["solve", str(scene), "--out", str(out), "--report", str(tmp_path / "never.json")]
        )
        captured = capsys.readouterr()
        assert status == 1, name
        lines = captured.err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("isochor: ") and name in lines[0], lines
        if name in REFUSED:
            assert REFUSED[name] in lines[0]
        assert not out.exists() and not (tmp_path / "never.json").exists()
        assert captured.out == ""


def test_bad_scenario_files(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"model": {"builtin": "torus"}, "lattice": {"nodes": [3, 3]}}')
    assert main(["solve", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("isochor: ") and "lattice.nodes" in err and err.count("\n") == 1
    assert main(["solve", str(tmp_path / "none.json")]) == 1
    assert "no such scenario file" in capsys.readouterr().err


# -- options and outputs ------------------------------------------------------------------
def test_examples_lists_every_example(capsys):
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    assert [line.split()[0] for line in out.splitlines()] == list(EXAMPLES)


def test_solve_example_without_outputs(capsys):
    assert main(["solve", "--example", "torus-compression"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].split()[:2] == ["level", "triangles"]
    assert "volume" in out.splitlines()[-1]


def test_unknown_example(capsys):
    assert main(["solve", "--example", "teapot-melt"]) == 1
    assert "torus-compression" in capsys.readouterr().err


def test_outputs_are_checked_before_solving(tmp_path, capsys, monkeypatch):
    def no_solve(*args, **kwargs):
        raise AssertionError("solved anyway")

    monkeypatch.setattr(isochor.core.solve.multilevel, "solve", no_solve)
    for argv, text in (
        (["--out", str(tmp_path / "x.3ds")], "x.3ds"),
        (["--out", str(tmp_path / "no" / "x.ply")], "does not exist"),
        (["--report", str(tmp_path / "no" / "r.json")], "does not exist"),
        (["--out", str(tmp_path)], "folder"),
    ):
        assert main(["solve", "--example", "club-bend", *argv]) == 1
        err = capsys.readouterr().err
        assert text in err and err.count("\n") == 1


def test_unwritable_output_is_one_line(tmp_path, capsys, monkeypatch):
    import isochor.core.scenario.document

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path / "o.ply"))

    monkeypatch.setattr(isochor.core.io.atomic.tempfile, "mkstemp", denied)
    assert main(["solve", "--example", "torus-compression", "--out", str(tmp_path / "o.ply")]) == 1
    err = capsys.readouterr().err
    assert err == (
        f"isochor: {tmp_path / 'o.ply'}: cannot write in the folder {tmp_path} "
        "(Permission denied)\n"
    )


def test_not_converged_writes_outputs_and_exits_3(tmp_path, capsys, monkeypatch):
    real = isochor.core.solve.multilevel.solve

    def unlucky(*args, **kwargs):
        result = yield from real(*args, **kwargs)
        return dataclasses.replace(result, converged=False, message="ran out of steps")

    monkeypatch.setattr(isochor.core.solve.multilevel, "solve", unlucky)
    out, rep = tmp_path / "o.obj", tmp_path / "r.json"
    status = main(
        ["solve", "--example", "torus-compression", "--out", str(out), "--report", str(rep)]
    )
    assert status == 3
    assert "ran out of steps" in capsys.readouterr().err
    assert out.exists() and json.loads(rep.read_text())["converged"] is False


# -- Ctrl-C -------------------------------------------------------------------------------
def test_ctrl_c_stops_the_solve_and_writes_nothing(tmp_path, capsys, monkeypatch):
    real = isochor.core.solve.multilevel.solve
    closed = []

    def interrupted(*args, **kwargs):
        gen = real(*args, **kwargs)
        try:
            for record in gen:
                yield record
                if record.level_done:
                    raise KeyboardInterrupt  # as if Ctrl-C arrived inside the solver
        finally:
            closed.append(True)

    monkeypatch.setattr(isochor.core.solve.multilevel, "solve", interrupted)
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    status = main(
        ["solve", "--example", "torus-compression", "--out", str(out), "--report", str(rep)]
    )
    assert status == 130
    assert capsys.readouterr().err == "isochor: interrupted (SIGINT); nothing was written\n"
    assert closed and list(tmp_path.iterdir()) == []


def test_ctrl_c_between_steps_closes_the_generator(monkeypatch):
    from isochor.core.api import Session
    from isochor.core.scenario.examples import example_scenario

    real = isochor.core.solve.multilevel.solve
    state = {"closed": False, "records": 0}

    def watched(*args, **kwargs):
        gen = real(*args, **kwargs)
        try:
            for record in gen:
                state["records"] += 1
                yield record
        except GeneratorExit:
            state["closed"] = True
            raise

    class Keyboard:
        def write(self, text):
            if text.strip() and not text.lstrip().startswith("level"):
                raise KeyboardInterrupt  # Ctrl-C while printing the first level's row
            return len(text)

        def flush(self):
            pass

    monkeypatch.setattr(isochor.core.solve.multilevel, "solve", watched)
    try:
        cli.run_solve(Session(example_scenario("torus-compression")), Keyboard())
    except KeyboardInterrupt:
        # checked while the traceback still holds run_solve's frame (and its generator):
        # closed explicitly, not by the garbage collector later
        assert state["closed"] and state["records"] > 1
    else:
        raise AssertionError("the interrupt was swallowed")


# -- dispatch to the editor -------------------------------------------------------------
def test_edit_and_no_command_open_the_editor_lazily(monkeypatch):
    calls = []
    fake = types.ModuleType("isochor.app.cli.launch")
    fake.run_editor = lambda path, shot, timeout=None: calls.append((path, shot, timeout)) or 7
    monkeypatch.setitem(sys.modules, "isochor.app.cli.launch", fake)
    assert main(["edit", "scene.json", "--screenshot", "s.png", "--timeout", "9"]) == 7
    assert main([]) == 7
    assert main(["edit", "cow.obj"]) == 7
    assert calls == [("scene.json", "s.png", 9.0), (None, None, None), ("cow.obj", None, None)]


def test_editor_that_cannot_start_is_one_line(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "isochor.app.cli.launch", None)  # import fails
    assert main(["edit", "x.json"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("isochor: the editor cannot start") and err.count("\n") == 1


def test_version_and_no_bench_command(capsys):
    from isochor import __version__

    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"isochor {__version__}\n"
    assert main(["bench"]) == 2  # the benchmark is `make bench`, not shipped


def test_a_signal_whose_exception_comes_out_as_another_is_still_an_interruption(capsys):
    # a SIGINT that lands while a C extension is imported comes out as "ImportError:
    # initialization failed"; it must end as interrupted (130), not as an internal error
    from isochor.app.cli import interrupts
    from isochor.app.cli import main as cli

    before = interrupts.state.raised
    interrupts.state.raised = 2
    try:
        status = cli._status(ImportError("initialization failed"), debug=False)
    finally:
        interrupts.state.raised = before
    assert status == 130
    assert capsys.readouterr().err == "isochor: interrupted (SIGINT); nothing was written\n"


def test_a_one_shot_command_sets_its_heap_thresholds(monkeypatch, tmp_path):
    """``isochor solve`` sets glibc's malloc thresholds before the model is made (the
    first-solve rows of the benchmark measure what it saves); elsewhere it is a no-op."""
    import platform

    from isochor.app.cli import opening
    from tests.fresh import run_fresh

    calls = []
    monkeypatch.setattr(opening, "steady_heap", lambda: calls.append(True) or True)
    assert main(["solve", "--example", "cup-squeeze", "-q"]) == 0
    assert calls, "the command set its heap thresholds"
    proc, _ = run_fresh(
        "from isochor.app.cli.opening import steady_heap\nprint('SET', steady_heap())\n"
    )
    glibc = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"
    assert f"SET {glibc}" in proc.stdout, proc.stderr
