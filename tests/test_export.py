"""The one export path end to end (issue 10): a real solve, then the model's own file
rewritten, checked line by line and measured by trimesh (not by core); the command line,
the window's document and the Python API give the same bytes."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest
import trimesh

import isochor
from isochor.app.cli.main import main
from isochor.app.editor.document import Document
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.paper_models import bend_scenario, squash_scenario
from tests.models import icosphere, model


def kinds(path) -> Counter:
    """How many lines of each OBJ keyword."""
    return Counter(line.split()[0] for line in path.read_text().splitlines() if line.split())


def solve(tmp_path, scenario: Scenario, out: str, *extra: str) -> dict:
    scene = tmp_path / "scene.json"
    scenario.write(scene)
    report = tmp_path / "report.json"
    argv = ["solve", str(scene), "--out", str(tmp_path / out), "--report", str(report), "-q"]
    assert main([*argv, *extra]) == 0
    return json.loads(report.read_text())


def trimesh_volume(path) -> float:
    mesh = trimesh.load(str(path), force="mesh", process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)  # UV and normal seams
    assert mesh.is_watertight
    return float(mesh.volume)


@pytest.mark.parametrize(
    ("name", "edit"),
    [("spot_triangulated.obj", squash_scenario), ("torus_knot_quads.obj", bend_scenario)],
)
def test_obj_export_keeps_everything_but_the_positions(tmp_path, name, edit):
    source = model(name)
    report = solve(tmp_path, edit(source), "out.obj")
    out = tmp_path / "out.obj"
    assert kinds(out) == kinds(source)  # v, vt, vn, f, g, usemtl, mtllib ... line counts
    src_lines, out_lines = source.read_text().splitlines(), out.read_text().splitlines()
    assert len(src_lines) == len(out_lines)
    for a, b in zip(src_lines, out_lines):
        if not a.startswith(("v ", "vn ")):
            assert a == b  # faces with their polygons and triplets, UVs, materials, comments
    moved = [b for a, b in zip(src_lines, out_lines) if a.startswith("v ") and a != b]
    assert moved  # the deformation is there
    for line in out_lines:
        if line.startswith("vn "):
            assert np.linalg.norm([float(x) for x in line.split()[1:4]]) == pytest.approx(
                1, abs=1e-9
            )
    assert trimesh_volume(out) == pytest.approx(report["volume_target"], rel=1e-3)
    for note in report["export_notes"]:  # only the torus knot's missing .mtl, said
        assert "quadknot.obj.mtl was not found; mtllib kept as is" in note


def test_ply_export_keeps_extra_properties(tmp_path):
    ball = icosphere(3)
    rows = "\n".join(
        f"{x:.17g} {y:.17g} {z:.17g} {0.5 + 0.5 * x:.9g} {i % 7}"
        for i, (x, y, z) in enumerate(ball.vertices)
    )
    faces = "\n".join(f"3 {a} {b} {c}" for a, b, c in ball.faces)
    header = (
        "ply\nformat ascii 1.0\ncomment scanned\n"
        f"element vertex {ball.n_vertices}\nproperty double x\nproperty double y\n"
        "property double z\nproperty float s\nproperty uchar confidence\n"
        f"element face {ball.n_faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    (tmp_path / "ball.ply").write_text(header + rows + "\n" + faces + "\n")
    report = solve(tmp_path, squash_scenario(tmp_path / "ball.ply"), "out.ply")
    text = (tmp_path / "out.ply").read_text()
    assert text.startswith(header)
    body = text[len(header) :].splitlines()
    assert [r.split()[3:] for r in body[: ball.n_vertices]] == [
        r.split()[3:] for r in rows.splitlines()
    ]
    assert body[ball.n_vertices :] == faces.splitlines()
    assert trimesh_volume(tmp_path / "out.ply") == pytest.approx(report["volume_target"], rel=1e-3)

    # another format: the note names the properties the PLY held (read by the one parser)
    report = solve(tmp_path, squash_scenario(tmp_path / "ball.ply"), "out.obj")
    assert [n for n in report["export_notes"] if "properties (s, confidence)" in n], report


def test_glb_round_trip_keeps_vertex_count_and_uvs_and_can_be_a_morph_target(tmp_path):
    spot = trimesh.load(str(model("spot_triangulated.obj")), process=False)
    (tmp_path / "spot.glb").write_bytes(spot.export(file_type="glb"))
    before = trimesh.load(str(tmp_path / "spot.glb"), force="mesh", process=False)
    report = solve(tmp_path, squash_scenario(tmp_path / "spot.glb"), "out.glb")
    after = trimesh.load(str(tmp_path / "out.glb"), force="mesh", process=False)
    assert len(after.vertices) == len(before.vertices)
    assert np.array_equal(after.visual.uv, before.visual.uv)
    assert not np.allclose(after.vertices, before.vertices)
    assert trimesh_volume(tmp_path / "out.glb") == pytest.approx(report["volume_target"], rel=1e-3)

    solve(tmp_path, squash_scenario(tmp_path / "spot.glb"), "morph.glb", "--morph-target")
    data = (tmp_path / "morph.glb").read_bytes()
    doc = json.loads(data[20 : 20 + int.from_bytes(data[12:16], "little")])
    mesh = doc["meshes"][0]
    assert mesh["weights"][-1] == 1.0 and mesh["extras"]["targetNames"][-1] == "isochor"
    assert "POSITION" in mesh["primitives"][0]["targets"][-1]
    base = trimesh.load(str(tmp_path / "morph.glb"), force="mesh", process=False)
    np.testing.assert_allclose(base.vertices, before.vertices)  # the original mesh stays


def test_another_format_says_what_it_cannot_carry(tmp_path, capsys):
    report = solve(tmp_path, squash_scenario(model("spot_triangulated.obj")), "out.stl")
    err = capsys.readouterr().err
    assert len(report["export_notes"]) == 1
    note = report["export_notes"][0]
    assert "texture coordinates" in note and "Export as .obj to keep them" in note
    assert err.count("isochor: note:") == 1
    with pytest.raises(AssertionError):  # a morph target needs glTF in and out
        solve(tmp_path, squash_scenario(model("spot_triangulated.obj")), "m.obj", "--morph-target")


def test_the_command_line_the_window_and_the_api_write_the_same_file(tmp_path):
    source = model("spot_triangulated.obj")
    report = solve(tmp_path, squash_scenario(source), "cli.obj")
    nodes = np.array(report["nodes"])
    doc = Document.open(tmp_path / "scene.json")
    doc.export(tmp_path / "window.obj", nodes)
    session = isochor.load(tmp_path / "scene.json")
    session.nodes = nodes
    session.export(tmp_path / "api.obj")
    cli = (tmp_path / "cli.obj").read_bytes()
    assert (tmp_path / "window.obj").read_bytes() == cli
    assert (tmp_path / "api.obj").read_bytes() == cli


def test_an_export_refuses_a_model_changed_on_disk(tmp_path):
    (tmp_path / "ball.obj").write_bytes((model("cow.obj")).read_bytes())
    session = isochor.load(tmp_path / "ball.obj")
    with open(tmp_path / "ball.obj", "a") as fh:
        fh.write("# edited elsewhere\n")
    with pytest.raises(isochor.IsochorError, match="changed on disk since it was opened"):
        session.export(tmp_path / "out.obj")
    assert not (tmp_path / "out.obj").exists()
