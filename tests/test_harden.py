"""Issue 28, hardening: every file a model reads is protected from the outputs (the command
line out of process, Session.save/export in process), glTF URIs stay in the model's folder,
one error type in the API, duplicate scenario keys and pinned+moved nodes refused, exact
volumes far from the origin (closed forms), the written file's volume reported."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

import isochor
from isochor.core.errors import IsochorError
from isochor.core.io.companions import model_inputs
from isochor.core.io.gltf import read_gltf
from isochor.core.io.meshio import mesh_bytes
from isochor.core.mesh import TriMesh
from isochor.core.scenario.document import Scenario
from isochor.core.volume import signed_volume
from tests.models import box, icosphere
from tests.test_contract import check, snapshot, write_json
from tests.test_contract import isochor as run_isochor


# -- every file an input uses ------------------------------------------------------------
def _obj_with_library(folder: Path) -> Path:
    obj = mesh_bytes(icosphere(2), ".obj")
    (folder / "m.obj").write_bytes(b"mtllib m.mtl\n" + obj)
    (folder / "m.mtl").write_text("newmtl a\nmap_Kd -s 1 1 1 wood map.png\nbump bumps.png\n")
    (folder / "wood map.png").write_bytes(b"not really a png")
    (folder / "bumps.png").write_bytes(b"nor this")
    return folder / "m.obj"


def _gltf_with_files(folder: Path) -> Path:
    files = trimesh.exchange.gltf.export_gltf(
        trimesh.Scene(trimesh.creation.icosphere(2)), include_normals=True
    )
    for name, data in files.items():
        (folder / name).write_bytes(data)
    doc = json.loads(files["model.gltf"])
    doc["images"] = [{"uri": "skin.png"}]
    (folder / "skin.png").write_bytes(b"image")
    (folder / "model.gltf").write_text(json.dumps(doc))
    return folder / "model.gltf"


def test_the_files_a_model_reads_are_listed(tmp_path):
    roles = {p.name: role for p, role in model_inputs(_obj_with_library(tmp_path))}
    assert roles == {
        "m.obj": "the model",
        "m.mtl": "the model's material library m.mtl",
        "wood map.png": "the model's texture wood map.png",
        "bumps.png": "the model's texture bumps.png",
    }
    gltf = {p.name for p, _ in model_inputs(_gltf_with_files(tmp_path))}
    buffers = [b["uri"] for b in json.loads((tmp_path / "model.gltf").read_text())["buffers"]]
    assert gltf == {"model.gltf", "skin.png", *buffers}


@pytest.mark.parametrize(
    "spell", ["m.mtl", "./m.mtl", "sub/../wood map.png", "link.mtl", "hard.png", "m.obj"]
)
def test_session_save_and_export_never_replace_a_file_the_model_reads(tmp_path, spell):
    _obj_with_library(tmp_path)
    (tmp_path / "sub").mkdir()
    os.symlink(tmp_path / "m.mtl", tmp_path / "link.mtl")
    os.link(tmp_path / "bumps.png", tmp_path / "hard.png")
    before = snapshot(tmp_path)
    session = isochor.load(tmp_path / "m.obj", lattice=(3, 3, 3))
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for write in (session.save, session.export):
            with pytest.raises(IsochorError, match="would overwrite the model") as caught:
                write(spell)
            assert "\n" not in str(caught.value)
    finally:
        os.chdir(cwd)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("role", ["--report", "--out"])
def test_the_command_line_never_replaces_a_buffer_or_a_library(tmp_path, role):
    gltf = _gltf_with_files(tmp_path)
    buffer = json.loads(gltf.read_text())["buffers"][0]["uri"]
    _obj_with_library(tmp_path)
    doc = {"model": {"path": "model.gltf"}, "lattice": {"nodes": [3, 3, 3]}}
    write_json(tmp_path / "s.json", doc)
    for target in (buffer, "m.mtl"):
        if role == "--out" and target == "m.mtl":
            target = "wood map.png"
        before = snapshot(tmp_path)
        run = run_isochor("solve", "s.json", role, target, cwd=tmp_path)
        if target != buffer:  # the OBJ's files: the scenario on the OBJ
            write_json(tmp_path / "o.json", {**doc, "model": {"path": "m.obj"}})
            before = snapshot(tmp_path)
            run = run_isochor("solve", "o.json", role, target, cwd=tmp_path)
        assert run.returncode == 1 and "would overwrite the model's" in run.stderr, run
        check(run, before, snapshot(tmp_path), [])


# -- glTF URIs stay in the model's folder ----------------------------------------------------
@pytest.mark.parametrize(
    "uri",
    [
        "../../../../../etc/passwd",
        "/etc/passwd",
        "file:///etc/passwd",
        "sub/../../outside.bin",
        "%2e%2e/outside.bin",
        "http://example.com/x.bin",
        "out.bin",  # a link leading out
    ],
)
@pytest.mark.parametrize("kind", ["buffers", "images"])
def test_a_gltf_uri_outside_its_folder_is_refused_and_nothing_read(tmp_path, uri, kind):
    folder = tmp_path / "model"
    folder.mkdir()
    gltf = _gltf_with_files(folder)
    (tmp_path / "outside.bin").write_bytes(b"secret")
    os.symlink(tmp_path / "outside.bin", folder / "out.bin")
    doc = json.loads(gltf.read_text())
    doc[kind][0]["uri"] = uri
    with pytest.raises(IsochorError, match="is refused") as caught:
        read_gltf(json.dumps(doc).encode(), ".gltf", name="model.gltf", base_dir=folder)
    message = str(caught.value)
    assert message.startswith("model.gltf: ") and "\n" not in message
    assert "own folder" in message


def test_gltf_uris_inside_the_folder_and_data_uris_are_read(tmp_path):
    folder = tmp_path / "model"
    (folder / "sub").mkdir(parents=True)
    gltf = _gltf_with_files(folder)
    doc = json.loads(gltf.read_text())
    name = doc["buffers"][0]["uri"]
    (folder / name).rename(folder / "sub" / name)
    doc["buffers"][0]["uri"] = f"sub/{name}"
    points, faces = read_gltf(json.dumps(doc).encode(), ".gltf", base_dir=folder)
    assert len(faces) == 320 and np.isfinite(points).all()


# -- one error type in the API ---------------------------------------------------------------
MESH = (icosphere(1).vertices, icosphere(1).faces)


@pytest.mark.parametrize(
    "mistake",
    [
        lambda s: isochor.Session(MESH, (3, 3, 3), colour=1),
        lambda s: isochor.deform(MESH, (3, 3, 3), colour=1),
        lambda s: isochor.load(5),
        lambda s: s.move((1, 1, 1), by=(1, 0)),
        lambda s: s.move((1, 1, 1), to="abc"),
        lambda s: s.add_handle((0, 0)),
        lambda s: s.move_handle(3, (0, 0, 0)),
        lambda s: s.key("x"),
        lambda s: (setattr(s, "nodes", np.zeros((3, 3))), s.solve()),
        lambda s: isochor.deform(MESH, (3, 3, 3), moves=[{"nod": [0, 0, 0], "by": [0, 0, 0]}]),
        lambda s: isochor.deform(MESH, (3, 3, 3), pins=[{"axes": "z"}]),
        lambda s: isochor.deform(MESH, (3, 3, 3), handles=[{"at": [0, 0]}]),
        lambda s: isochor.deform(MESH, (3, 3, 3), pins=5),
        lambda s: isochor.Session((MESH[0], MESH[1] + 0.5), (3, 3, 3)),
    ],
)
def test_every_api_mistake_is_one_isochor_error(mistake):
    session = isochor.Session(MESH, (3, 3, 3))
    with pytest.raises(IsochorError) as caught:
        mistake(session)
    assert "\n" not in str(caught.value)


def test_an_unknown_keyword_names_the_known_ones():
    with pytest.raises(IsochorError, match="unknown keyword 'colour'") as caught:
        isochor.Session(MESH, (3, 3, 3), colour=1)
    assert "target" in str(caught.value) and "padding" in str(caught.value)


# -- the scenario: duplicate keys, pinned and moved ----------------------------------------
def test_a_duplicate_key_is_refused_naming_it(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(
        '{"model": {"builtin": "sphere"}, "lattice": {"nodes": [3, 3, 3], "nodes": [4, 4, 4]}}'
    )
    with pytest.raises(IsochorError, match="'nodes' is given twice"):
        Scenario.read(path)


def test_a_node_both_pinned_and_moved_is_refused_saying_why():
    doc = {
        "model": {"builtin": "sphere"},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": [2, 2, 2], "by": [0.1, 0, 0]}],
        "pins": [[2, 2, 2]],
    }
    with pytest.raises(IsochorError, match=r"node \[2, 2, 2\] is also moved"):
        Scenario.from_dict(doc)


# -- exact far from the origin ---------------------------------------------------------------
@pytest.mark.parametrize(
    ("size", "offset"), [(64.0, 0.0), (64.0, 1e12), (64.0, 1e13), (2.0**20, 9e14)]
)
def test_the_volume_far_from_the_origin_is_exact(size, offset):
    """A box (every corner exact at these offsets), its volume in closed form at rest, and
    after a solve with a move the volume kept within the tolerance, also as measured from
    the deformed world points (up to their own rounding: each moves less than
    sqrt(3) ulp / 2, the volume by less than that times the area)."""
    mesh = box((size, size / 2, size / 4))
    exact, area = size**3 / 8, 2 * (size**2 / 2 + size**2 / 4 + size**2 / 8)
    shifted = (mesh.vertices + offset, mesh.faces)
    assert np.array_equal(shifted[0] - offset, mesh.vertices)  # representable exactly
    session = isochor.Session(shifted, (3, 3, 3))
    tol = session.problem.scenario.tol_volume
    session.move((2, 2, 2), by=(size / 8, 0.0, 0.0))
    result = session.solve()
    assert abs(result.volume_original / exact - 1) <= tol
    assert result.converged and abs(result.rel_volume_error) <= tol
    world = session.lattice.deform(mesh.vertices + offset, session.nodes)
    bound = np.sqrt(3) * np.spacing(max(offset, 1.0)) * area + 1e-12 * exact
    assert abs(signed_volume(world, mesh.faces) - result.volume_final) <= bound


@pytest.mark.parametrize(("size", "offset"), [(64.0, 3e14), (1.0, 1e13)])
def test_a_model_too_far_for_its_size_is_refused(size, offset):
    """Beyond what doubles can measure within the tolerance: one line saying why."""
    mesh = box((size, size, size))
    with pytest.raises(IsochorError, match="too far from the origin for its size"):
        isochor.Session((mesh.vertices + offset, mesh.faces), (3, 3, 3))


# -- the written file's volume ---------------------------------------------------------------
def test_a_float32_output_reports_its_own_volume_and_warns(tmp_path):
    thin = box((1.0, 1.0, 1e-4))
    far = TriMesh(thin.vertices + 1000.0, thin.faces)
    (tmp_path / "thin.ply").write_bytes(mesh_bytes(far, ".ply"))
    session = isochor.load(tmp_path / "thin.ply", lattice=(3, 3, 2))
    session.move((2, 2, 1), by=(0.1, 0, 0))
    session.solve()
    single = session.export_bytes(tmp_path / "o.stl")
    double = session.export_bytes(tmp_path / "o.ply")
    written = trimesh.load(trimesh.util.wrap_as_stream(single.data), file_type="stl")
    stored = signed_volume(np.asarray(written.vertices, float), np.asarray(written.faces))
    assert single.single and single.volume == pytest.approx(stored, rel=1e-6)
    assert any(n.startswith("warning: o.stl holds volume") for n in single.notes)
    assert not double.single and not any(n.startswith("warning") for n in double.notes)
    assert double.volume == pytest.approx(session.result.volume_final, rel=1e-9)
