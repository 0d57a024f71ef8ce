"""Issue 39 items 2 and 3: the OBJ reader follows the format and names the line; material
libraries stay in the model's folder; a required glTF extension Isochor lacks is refused;
a model of many closed pieces in one object opens with one body for each."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from isochor.core.errors import IsochorError
from isochor.core.io.gltf import read_gltf
from isochor.core.io.meshio import load_mesh, mesh_bytes, plain_obj
from isochor.core.io.objfile import read_obj
from isochor.core.mesh import TriMesh
from tests.models import box, icosphere, joined

TET = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
TET_FACES = b"f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


@pytest.mark.parametrize(
    "faces, words",
    [
        (b"f 0 3 2\n", "line 5: vertex index 0 does not exist"),
        (b"f 1 3\n", "line 5: a face needs at least three vertices, this one has 2"),
        (b"f\n", "line 5: a face needs at least three vertices, this one has 0"),
        (b"f 1 3 44\n", "line 5: vertex index 44 does not exist: the file has 4 vertices"),
        (b"f -5 3 2\n", "line 5: vertex index -5 does not exist"),
        (b"f 1 x 2\n", "line 5: 'x' is not a vertex index"),
    ],
)
def test_bad_faces_are_refused_naming_the_line(tmp_path, faces, words):
    path = tmp_path / "m.obj"
    path.write_bytes(TET + faces + TET_FACES)
    with pytest.raises(IsochorError) as err:
        load_mesh(path)
    assert str(err.value).startswith("m.obj: ") and words in str(err.value)
    assert "axis" not in str(err.value) and "size" not in str(err.value)


def test_negative_indices_count_back_from_the_vertices_read_so_far(tmp_path):
    # two tetrahedra, each written as its vertices then faces counting back
    second = TET.replace(b" 0 0 0\n", b" 5 0 0\n").replace(b"v 1 0 0", b"v 6 0 0")
    second = second.replace(b"v 0 1 0", b"v 5 1 0").replace(b"v 0 0 1", b"v 5 0 1")
    back = b"f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n"
    data = b"o a\n" + TET + back + b"o b\n" + second + back
    vertices, faces, parts = read_obj(data, "m.obj")
    assert len(vertices) == 8 and parts is not None and len(set(parts.tolist())) == 2
    path = tmp_path / "m.obj"
    path.write_bytes(data)
    loaded = load_mesh(path)
    assert loaded.bodies == 2 and loaded.volume == pytest.approx(2 / 6, rel=1e-12)


@pytest.mark.parametrize("mesh", [icosphere(2), box((1.0, 2.0, 0.5))], ids=["ball", "box"])
def test_the_two_obj_readers_agree(mesh):
    data = mesh_bytes(mesh, ".obj")
    fast = plain_obj(data)
    assert fast is not None
    vertices, faces, parts = read_obj(data, "m.obj")
    assert np.array_equal(fast[0], vertices) and np.array_equal(fast[1], faces)
    assert parts is None


def test_material_libraries_outside_the_folder_are_never_opened(tmp_path):
    inside = tmp_path / "model"
    inside.mkdir()
    (tmp_path / "x.mtl").write_text("newmtl a\nmap_Kd secret.png\n")
    path = inside / "m.obj"
    path.write_bytes(b"mtllib ../x.mtl /etc/hostname\n" + mesh_bytes(icosphere(1), ".obj"))
    opened: list[str] = []
    active = [True]

    def hook(event, args):
        if active[0] and event == "open" and isinstance(args[0], str):
            opened.append(args[0])

    sys.addaudithook(hook)
    try:
        loaded = load_mesh(path)
    finally:
        active[0] = False
    assert not [p for p in opened if "x.mtl" in p or "hostname" in p]
    said = [w for w in loaded.warnings if "outside the model's folder" in w]
    assert len(said) == 2 and "'../x.mtl'" in said[0]


def test_a_required_extension_isochor_lacks_is_refused_naming_it(tmp_path):
    import trimesh

    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.icosphere(1)))
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    doc = json.loads(files["model.gltf"])
    read_gltf(json.dumps(doc).encode(), ".gltf", name="m.gltf", base_dir=tmp_path)
    doc["extensionsRequired"] = ["KHR_materials_unlit", "EXT_made_up"]
    with pytest.raises(IsochorError, match="requires the glTF extension 'EXT_made_up'"):
        read_gltf(json.dumps(doc).encode(), ".gltf", name="m.gltf", base_dir=tmp_path)


def _beetle() -> TriMesh:
    """32 closed pieces in one object: boxes in a grid touching along faces, edges and
    corners (their coordinates coincide), and balls touching them."""
    pieces = []
    for i, j, k in [(i, j, k) for i in range(3) for j in range(3) for k in range(3)]:
        if (i + 2 * j + k) % 3:
            b = box((1.0, 1.0, 1.0))
            pieces.append(TriMesh(b.vertices + (i, j, k), b.faces))
    while len(pieces) < 32:
        n = len(pieces)
        pieces.append(icosphere(1, 0.5, (4.0 + n, 0.5, 0.5)))
    return joined(*pieces[:32])


def test_a_model_of_many_closed_pieces_in_one_object_opens_one_body_each(tmp_path):
    beetle = _beetle()
    path = tmp_path / "beetle.obj"
    path.write_bytes(mesh_bytes(beetle, ".obj"))
    loaded = load_mesh(path)
    assert loaded.bodies == 32
    import trimesh

    expected = float(trimesh.Trimesh(beetle.vertices, beetle.faces, process=False).volume)
    assert loaded.volume == pytest.approx(expected, rel=1e-12)
