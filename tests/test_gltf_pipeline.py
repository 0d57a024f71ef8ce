"""The pipeline into Blender (issue 26 item 4): ``--sequence anim.glb`` keeps the model's
own mesh, UVs, materials and skin, with a morph target per frame and animated weights; a
GLB embeds its images and a ``.gltf`` keeps only the ones beside it; an OBJ as GLB keeps
its UVs and material; every glTF/GLB Isochor writes validates with 0 errors in the Khronos
validator (:mod:`tests.gltfcheck`)."""

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
from tests.gltfcheck import assert_valid, external, validate
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


def _separate_images_gltf(models: Path) -> bytes:
    """``models/ball.gltf``: the textured sphere with its buffer (ball.bin) and its image
    ("skin tex.png") as separate files; the image's bytes."""
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
    return png


def _embedded_image(path: Path) -> bytes:
    """The bytes of the file's one image, which must be in its own buffer."""
    if path.suffix == ".glb":
        doc, blob = glb_json(path.read_bytes())
    else:
        import base64

        doc = json.loads(path.read_text())
        uri = doc["buffers"][0]["uri"]
        assert uri.startswith("data:"), uri
        blob = base64.b64decode(uri.partition(",")[2])
    (image,) = doc["images"]
    assert "uri" not in image and image["mimeType"] == "image/png", image
    view = doc["bufferViews"][image["bufferView"]]
    return blob[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]


def test_a_gltf_with_separate_images_travels(tmp_path):
    """A .gltf whose image and buffer are separate files, exported: every GLB (elsewhere or
    beside the model) and a .gltf written elsewhere embed the image, so the validator sees
    no external URI and the files still validate once moved away; a .gltf written beside
    the image keeps referring to it there."""
    png = _separate_images_gltf(tmp_path / "models")
    session = isochor.Session(tmp_path / "models" / "ball.gltf", lattice=(3, 3, 3))
    session.move((2, 2, 2), by=(0.2, 0.2, 0.0))
    session.solve()
    (tmp_path / "out" / "deep").mkdir(parents=True)
    travel = [tmp_path / "out" / "deep" / "a.gltf", tmp_path / "c.glb"]
    travel.append(tmp_path / "models" / "d.glb")
    beside = tmp_path / "models" / "b.gltf"
    notes = {p.name: session.export(p) for p in [*travel, beside]}
    for path in travel:
        assert _embedded_image(path) == png, path
        assert any("are embedded in it" in n for n in notes[path.name]), notes
    assert json.loads(beside.read_text())["images"][0]["uri"] == "skin%20tex.png"
    assert any("beside it" in n for n in notes["b.gltf"]), notes
    assert external(*travel, beside) == {
        **{p.name: [] for p in travel},
        "b.gltf": ["skin%20tex.png"],
    }
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    for path in travel:
        (moved / path.name).write_bytes(path.read_bytes())
    assert validate(*(moved / p.name for p in travel), beside) == {
        **{p.name: [] for p in travel},
        "b.gltf": [],
    }


def test_a_textured_obj_as_glb_keeps_its_uvs_and_material(tmp_path):
    """``isochor solve --out ball.glb`` of an OBJ with UVs, a material and its image: the
    GLB has the OBJ's texture coordinates, the textured material and the image inside it
    (no external URI), validates, and holds the solved volume."""
    ball = textured_sphere()
    ball.export(tmp_path / "ball.obj")
    assert {p.name for p in tmp_path.iterdir()} >= {"ball.obj", "material.mtl"}
    scene = {
        "format": "isochor-scenario",
        "version": 1,
        "model": {"path": "ball.obj"},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": [2, 2, 2], "by": [0.3, 0.1, 0.0]}],
    }
    run = solve(tmp_path, scene, name="ball", out="ball.glb")
    assert run.returncode == 0, run
    assert "texture coordinates" not in run.stderr, run.stderr  # nothing lost, nothing said
    doc, blob = glb_json((tmp_path / "ball.glb").read_bytes())
    (prim,) = doc["meshes"][0]["primitives"]
    assert "TEXCOORD_0" in prim["attributes"]
    texture = doc["materials"][prim["material"]]["pbrMetallicRoughness"]["baseColorTexture"]
    image = doc["images"][doc["textures"][texture["index"]]["source"]]
    assert "bufferView" in image and "uri" not in image
    # the UVs as the OBJ has them (trimesh's reader keeps one per vertex it made)
    uv = accessor(doc, blob, prim["attributes"]["TEXCOORD_0"])
    reloaded = trimesh.load(tmp_path / "ball.obj", process=False, maintain_order=True)
    np.testing.assert_allclose(
        np.column_stack([uv[:, 0], 1 - uv[:, 1]]), reloaded.visual.uv, atol=1e-6
    )
    positions = accessor(doc, blob, prim["attributes"]["POSITION"]).astype(np.float64)
    faces = accessor(doc, blob, prim["indices"]).reshape(-1, 3).astype(np.int64)
    volume = closed_volume(positions, faces)
    assert volume / ball.volume == pytest.approx(1.0, abs=TOL_VOLUME + F32_VOLUME)
    assert np.abs(positions - reloaded.vertices).max() > 0.05  # deformed
    assert external(tmp_path / "ball.glb") == {"ball.glb": []}
    assert_valid(tmp_path / "ball.glb")


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
