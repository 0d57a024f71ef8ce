"""The pipeline into Blender (issue 26 item 4): ``--sequence anim.glb`` keeps the model's
own mesh, UVs, materials and skin, with a morph target per frame and animated weights; a
``.gltf`` written away from its images re-points them; every glTF/GLB Isochor writes
validates with 0 errors in the Khronos validator (:mod:`tests.gltfcheck`)."""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

import isochor
from isochor.core.defaults import TOL_VOLUME
from tests.gltfcheck import assert_valid, validate
from tests.test_cli_goals import SMALL_TORUS, scenario, solve

#: float32 positions and deltas: a volume measured from the file is this close
F32_VOLUME = 1e-5


def glb_json(data: bytes) -> tuple[dict, bytes]:
    (length,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20 : 20 + length])
    return doc, data[20 + length + 8 :]


def make_glb(doc: dict, blob: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += bytes(-len(blob) % 4)
    doc["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0")
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body) + len(blob)) + body + blob


def accessor(doc: dict, blob: bytes, index: int) -> np.ndarray:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    dtype = {5126: "<f4", 5121: "<u1", 5123: "<u2", 5125: "<u4"}[acc["componentType"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(blob, dtype, acc["count"] * width, start).reshape(acc["count"], width)


def textured_sphere() -> trimesh.Trimesh:
    """A closed sphere with texture coordinates and a textured material."""
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    uv = np.random.default_rng(5).random((len(mesh.vertices), 2))
    image = Image.new("RGB", (4, 4), (200, 40, 10))
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=image)
    return mesh


def skinned_glb() -> bytes:
    """The textured sphere with a skin: two joints, every vertex weighted to both."""
    doc, blob = glb_json(bytes(textured_sphere().export(file_type="glb")))
    blob = bytearray(blob)
    count = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]["count"]

    def add(data: np.ndarray, component: int, kind: str) -> int:
        blob.extend(bytes(-len(blob) % 4))
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes})
        blob.extend(data.tobytes())
        doc["accessors"].append(
            {"bufferView": len(doc["bufferViews"]) - 1, "componentType": component,
             "count": len(data), "type": kind}
        )  # fmt: skip
        return len(doc["accessors"]) - 1

    joints = add(np.tile(np.array([0, 1, 0, 0], np.uint8), (count, 1)), 5121, "VEC4")
    weights = add(np.tile(np.array([0.5, 0.5, 0, 0], np.float32), (count, 1)), 5126, "VEC4")
    binds = add(np.tile(np.eye(4, dtype=np.float32).reshape(1, 16), (2, 1)), 5126, "MAT4")
    doc["meshes"][0]["primitives"][0]["attributes"] |= {"JOINTS_0": joints, "WEIGHTS_0": weights}
    mesh_node = next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n)
    first = len(doc["nodes"])
    doc["nodes"] += [{"name": "root", "children": [first + 1]}, {"name": "tip"}]
    doc["nodes"][mesh_node]["skin"] = 0
    doc["skins"] = [{"joints": [first, first + 1], "inverseBindMatrices": binds}]
    doc["scenes"][0]["nodes"].append(first)
    return make_glb(doc, bytes(blob))


def three_keys(model: dict, nodes=(3, 2, 2), end: int = 9) -> dict:
    corner = [nodes[0] - 1, 1, nodes[2] - 1]
    poses = [
        {"frame": 0},
        {"frame": 5, "moves": [{"node": corner, "by": [0.0, 0.4, 0.0]}]},
        {"frame": 9, "moves": [{"node": corner, "by": [0.3, -0.3, 0.0]}]},
    ]
    timeline = {"start": 0, "end": end, "interpolation": "smooth", "rate": 12}
    return scenario(model, nodes=nodes, version=3, poses=poses, timeline=timeline)


def frame_meshes(data: bytes) -> tuple[dict, np.ndarray, list[np.ndarray], np.ndarray]:
    """The GLB's first primitive: its doc, rest positions, each frame's (rest + target),
    faces."""
    doc, blob = glb_json(data)
    prim = doc["meshes"][0]["primitives"][0]
    rest = accessor(doc, blob, prim["attributes"]["POSITION"]).astype(float)
    frames = [rest + accessor(doc, blob, t["POSITION"]) for t in prim["targets"]]
    return doc, rest, frames, accessor(doc, blob, prim["indices"]).reshape(-1, 3)


def closed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)  # the UV seams closed
    return float(mesh.volume)


@pytest.fixture(scope="module")
def sequences(tmp_path_factory) -> dict[str, Path]:
    """``isochor solve --sequence anim.glb`` on a textured OBJ and on a skinned GLB."""
    folder = tmp_path_factory.mktemp("sequences")
    textured_sphere().export(folder / "ball.obj")
    (folder / "skinned.glb").write_bytes(skinned_glb())
    out = {}
    for name in ("ball.obj", "skinned.glb"):
        stem = Path(name).stem
        run = solve(folder, three_keys({"path": name}), "--sequence", f"{stem}_anim.glb", name=stem)
        assert run.returncode == 0, run
        out[name] = folder / f"{stem}_anim.glb"
    return out


@pytest.mark.parametrize("name", ["ball.obj", "skinned.glb"])
def test_a_sequence_glb_keeps_the_models_mesh_uvs_materials(sequences, name):
    data = sequences[name].read_bytes()
    doc, rest, frames, faces = frame_meshes(data)
    prim = doc["meshes"][0]["primitives"][0]
    assert "TEXCOORD_0" in prim["attributes"] and "material" in prim
    material = doc["materials"][prim["material"]]
    assert "baseColorTexture" in material["pbrMetallicRoughness"]
    assert doc["images"] and doc["textures"]
    assert len(frames) == 10 == len(doc["meshes"][0]["extras"]["targetNames"])
    names = doc["meshes"][0]["extras"]["targetNames"]
    assert names[-10:] == [f"frame {i}" for i in range(10)]
    sampler = doc["animations"][0]["samplers"][0]
    _doc, blob = glb_json(data)
    weights = accessor(doc, blob, sampler["output"]).reshape(10, -1)
    np.testing.assert_array_equal(weights[:, -10:], np.eye(10))
    times = accessor(doc, blob, sampler["input"]).ravel()
    np.testing.assert_allclose(times, np.arange(10) / 12, rtol=1e-6)
    # the model's own positions at rest; each frame keeps the rest volume
    ball = textured_sphere()
    assert closed_volume(rest, faces) == pytest.approx(ball.volume, rel=F32_VOLUME)
    assert {tuple(p) for p in np.round(rest, 5)} == {tuple(p) for p in np.round(ball.vertices, 5)}
    volumes = np.array([closed_volume(f, faces) for f in frames])
    assert np.abs(volumes / ball.volume - 1).max() <= TOL_VOLUME + F32_VOLUME, volumes
    assert np.abs(frames[5] - frames[0]).max() > 0.05  # it moves
    if name == "skinned.glb":
        assert doc["skins"][0]["joints"] and "JOINTS_0" in prim["attributes"]
        skinned = next(n for n in doc["nodes"] if "mesh" in n)
        assert skinned["skin"] == 0
    assert_valid(sequences[name])


def test_a_sequence_of_a_built_in_shape_validates(tmp_path):
    run = solve(tmp_path, three_keys(SMALL_TORUS), "--sequence", "torus.glb")
    assert run.returncode == 0, run
    assert_valid(tmp_path / "torus.glb")


def test_a_gltf_written_away_from_its_images_repoints_them(tmp_path):
    """A .gltf with a separate image, exported into another folder: the image URI leads
    from there to the original (the validator reads it: an IO error otherwise)."""
    models = tmp_path / "models"
    models.mkdir()
    doc, blob = glb_json(bytes(textured_sphere().export(file_type="glb")))
    image = doc["images"][0]
    view = doc["bufferViews"][image.pop("bufferView")]  # left unused in the buffer
    png = blob[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
    (models / "skin tex.png").write_bytes(png)
    image["uri"] = "skin%20tex.png"
    image.pop("mimeType", None)
    doc["buffers"] = [{"byteLength": len(blob), "uri": "ball.bin"}]
    (models / "ball.bin").write_bytes(blob)
    (models / "ball.gltf").write_text(json.dumps(doc))
    session = isochor.Session(models / "ball.gltf", lattice=(3, 3, 3))
    session.move((2, 2, 2), by=(0.2, 0.2, 0.0))
    session.solve()
    (tmp_path / "out" / "deep").mkdir(parents=True)
    written = [tmp_path / "out" / "deep" / "a.gltf", models / "b.gltf", tmp_path / "c.glb"]
    notes = [session.export(path) for path in written]
    uris = [glb_json(p.read_bytes())[0] if p.suffix == ".glb" else json.loads(p.read_text())
            for p in written]  # fmt: skip
    assert uris[0]["images"][0]["uri"] == "../../models/skin%20tex.png", notes[0]
    assert uris[1]["images"][0]["uri"] == "skin%20tex.png", notes[1]
    assert uris[2]["images"][0]["uri"] == "models/skin%20tex.png", notes[2]
    assert any("point at the originals" in n for n in notes[0])
    assert any("beside it" in n for n in notes[1])
    assert validate(*written) == {p.name: [] for p in written}


def test_every_export_kind_validates(tmp_path):
    """In place, as a morph target, .glb <-> .gltf, from another format, a skinned file."""
    (tmp_path / "skinned.glb").write_bytes(skinned_glb())
    textured_sphere().export(tmp_path / "ball.obj")
    written = []
    for source in ("skinned.glb", "ball.obj"):
        session = isochor.Session(tmp_path / source, lattice=(3, 3, 3))
        session.move((2, 2, 2), by=(0.3, 0.1, 0.0))
        session.solve()
        stem = Path(source).stem
        for suffix in (".glb", ".gltf"):
            path = tmp_path / f"{stem}_out{suffix}"
            session.export(path)
            written.append(path)
            if source.endswith(".glb"):
                path = tmp_path / f"{stem}_morph{suffix}"
                session.export(path, morph_target=True)
                written.append(path)
    assert len(written) == 6
    assert_valid(*written)
    reloaded = trimesh.load(io.BytesIO(written[1].read_bytes()), file_type="glb", force="mesh")
    assert reloaded.visual.uv is not None  # the UVs kept


def test_every_rewrite_of_the_gltf_tests_files_validates(tmp_path):
    """The files tests/test_gltf.py builds (a sphere, a scene with node transforms and
    shared accessors, interleaved vertices under a hierarchy, a skinned sphere), rewritten
    in place, with a morph target, as .gltf, and animated (:func:`animate_gltf`)."""
    from isochor.core.io.gltf import animate_gltf, rewrite_gltf
    from tests.test_gltf import DEFORMS, interleaved_glb, scene_glb, sphere_glb

    sources = {
        "sphere": sphere_glb(),
        "scene": scene_glb(),
        "interleaved": interleaved_glb()[0],
        "skinned": skinned_glb(),
    }
    written = []
    for name, glb in sources.items():
        for mode, options in {
            "inplace": {},
            "morph": {"morph_target": True},
            "text": {"out_suffix": ".gltf"},
        }.items():
            data, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"], **options)
            path = tmp_path / f"{name}_{mode}.{'gltf' if mode == 'text' else 'glb'}"
            path.write_bytes(data)
            written.append(path)
        data, _notes = animate_gltf(glb, ".glb", [DEFORMS["affine"], DEFORMS["bend"]], 24.0)
        path = tmp_path / f"{name}_anim.glb"
        path.write_bytes(data)
        written.append(path)
    assert len(written) == 16
    assert_valid(*written)


def test_the_validator_sees_a_broken_file_and_a_lost_image(tmp_path):
    """The check can fail: an accessor past its buffer, an image that is not there."""
    doc, blob = glb_json(bytes(textured_sphere().export(file_type="glb")))
    doc["accessors"][0]["count"] += 10_000
    (tmp_path / "broken.glb").write_bytes(make_glb(doc, blob))
    doc, blob = glb_json(bytes(textured_sphere().export(file_type="glb")))
    image = doc["images"][0]
    image.pop("bufferView"), image.pop("mimeType", None)
    image["uri"] = "elsewhere.png"
    (tmp_path / "lost.glb").write_bytes(make_glb(doc, blob))
    found = validate(tmp_path / "broken.glb", tmp_path / "lost.glb")
    assert found["broken.glb"] and found["lost.glb"], found
    assert any("IO_ERROR" in m for m in found["lost.glb"]), found
