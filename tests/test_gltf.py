"""glTF 2.0 round trip (isochor.core.io.gltf): read the world-space surface of a .glb/.gltf,
write it back deformed with everything else kept, or as a morph target; refuse what cannot
be done with one line.

Files are made with trimesh (meshes, scenes with node transforms, shared accessors, UVs and
a texture, one .gltf with several external or embedded buffers) and by hand (an interleaved
vertex buffer with byteStride, tangents, colours, a points primitive, a node hierarchy).
Results are checked against trimesh's own reader and against the deformation computed here.
"""

from __future__ import annotations

import base64
import copy
import functools
import io
import json
import struct
import warnings

import numpy as np
import pytest
import trimesh

from isochor.core.errors import IsochorError
from isochor.core.io.gltf import read_gltf, rewrite_gltf
from isochor.core.io.repair import clean_closed_surface
from isochor.core.volume import signed_volume
from tests.models import model

F32 = {"rtol": 2e-6, "atol": 2e-6}  # float32 storage

# -- deformations: an affine one (non-orthogonal, det > 0) and a nonlinear one ---------------
A = np.array([[1.3, 0.4, 0.0], [-0.2, 0.9, 0.3], [0.1, 0.0, 1.1]])
B = np.array([0.5, -1.0, 2.0])


def affine(x):
    return x @ A.T + B


def affine_jacobian(x):
    return np.broadcast_to(A, (len(x), 3, 3)).copy()


def bend(x):
    """A smooth nonlinear map, invertible near the models used here."""
    x0, x1, x2 = x.T
    return np.column_stack([x0 + 0.2 * np.sin(x1), x1 + 0.1 * x2**2, x2 + 0.15 * x0 * x1])


def bend_jacobian(x):
    x0, x1, x2 = x.T
    jac = np.zeros((len(x), 3, 3))
    jac[:, 0, 0], jac[:, 0, 1] = 1.0, 0.2 * np.cos(x1)
    jac[:, 1, 1], jac[:, 1, 2] = 1.0, 0.2 * x2
    jac[:, 2, 0], jac[:, 2, 1], jac[:, 2, 2] = 0.15 * x1, 0.15 * x0, 1.0
    return jac


DEFORMS = {"affine": (affine, affine_jacobian), "bend": (bend, bend_jacobian)}


# -- glTF helpers, independent of the module under test --------------------------------------
def split_glb(glb: bytes) -> tuple[dict, bytes]:
    """(JSON document, BIN chunk) of a GLB, checking its framing."""
    magic, version, length = struct.unpack_from("<4sII", glb)
    assert (magic, version, length) == (b"glTF", 2, len(glb))
    size, kind = struct.unpack_from("<II", glb, 12)
    assert kind == 0x4E4F534A and size % 4 == 0
    doc = json.loads(glb[20 : 20 + size])
    rest = glb[20 + size :]
    if not rest:
        return doc, b""
    bin_size, bin_kind = struct.unpack_from("<II", rest)
    assert bin_kind == 0x004E4942 and bin_size % 4 == 0 and len(rest) == 8 + bin_size
    return doc, rest[8:]


def make_glb(doc: dict, blob: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += bytes(-len(blob) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    body += struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def edit(glb: bytes, change) -> bytes:
    doc, blob = split_glb(glb)
    change(doc)
    return make_glb(doc, blob)


SIZES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def element_bytes(doc: dict, blob: bytes, index: int) -> list[bytes]:
    """The bytes of each element of an accessor (buffer 0), honouring byteStride."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    size = SIZES[acc["componentType"]] * WIDTHS[acc["type"]]
    step = view.get("byteStride", size)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return [blob[start + i * step : start + i * step + size] for i in range(acc["count"])]


def values(doc: dict, blob: bytes, index: int) -> np.ndarray:
    acc = doc["accessors"][index]
    dtype = {5121: "<u1", 5123: "<u2", 5125: "<u4", 5126: "<f4"}[acc["componentType"]]
    raw = b"".join(element_bytes(doc, blob, index))
    return np.frombuffer(raw, dtype).reshape(acc["count"], -1).astype(np.float64)


def trimesh_points(data: bytes, file_type: str = "glb") -> np.ndarray:
    loaded = trimesh.load(io.BytesIO(data), file_type=file_type, force="mesh", process=False)
    return np.asarray(loaded.vertices, dtype=np.float64)


def rows_sorted(points: np.ndarray) -> np.ndarray:
    return points[np.lexsort(np.round(points, 5).T[::-1])]


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def expected_normals(normals, points_world, world, jacobian):
    """normalise((L^-1 J L)^-T n): the local-frame normal under the world deformation."""
    lin = world[:3, :3]
    local = np.linalg.inv(lin) @ jacobian(points_world) @ lin
    return unit(np.einsum("pba,pb->pa", np.linalg.inv(local), normals))


def trs(translation, quaternion_xyzw, scale) -> np.ndarray:
    x, y, z, w = np.asarray(quaternion_xyzw, float) / np.linalg.norm(quaternion_xyzw)
    rot = trimesh.transformations.quaternion_matrix([w, x, y, z])
    return trimesh.transformations.translation_matrix(translation) @ rot @ np.diag([*scale, 1])


# -- test files --------------------------------------------------------------------------------
def sphere_glb(normals: bool = True) -> bytes:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.5)
    return mesh.export(file_type="glb", include_normals=normals)


def textured_box() -> trimesh.Trimesh:
    from PIL import Image

    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    uv = np.random.default_rng(3).random((len(box.vertices), 2))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.new("RGB", (4, 4), (9, 99, 199)))
    return box


ROTATED = trs([0.5, -1.0, 2.0], [0.3, -0.2, 0.5, 0.8], [1.5, 0.7, 1.2])


def scene_glb() -> bytes:
    """Two meshes under different node transforms (rotation + scale + translation); trimesh
    writes identical geometry once, so the two sphere instances share their accessors."""
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.icosphere(2), node_name="a", transform=ROTATED)
    scene.add_geometry(
        textured_box(), node_name="b", transform=trs([3, 0, 0], [0, 0, 0, 1], [1] * 3)
    )
    scene.add_geometry(
        trimesh.creation.icosphere(2),
        node_name="c",
        transform=trs([0, 4, 0], [0, 0, 1, 1], [2] * 3),
    )
    return scene.export(file_type="glb", include_normals=True)


OCTAHEDRON = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
OCTA_FACES = np.array(
    [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
)
CHILD = trs([0.2, 0.1, -0.3], [0.1, 0.7, -0.2, 0.6], [1.2, 0.8, 1.5])
ROOT = trs([1.0, 2.0, 3.0], [0, 0, 0, 1], [1, 1, 1])
INTERLEAVED = np.dtype(
    [("p", "<f4", 3), ("n", "<f4", 3), ("uv", "<f4", 2), ("t", "<f4", 4), ("pad", "<u4")]
)


def interleaved_glb() -> tuple[bytes, np.recarray]:
    """By hand: POSITION, NORMAL, TEXCOORD_0, TANGENT interleaved with 52-byte stride (and
    4 bytes of padding), u16 indices, u8 normalised colours, a points primitive, a node
    hierarchy with a column-major matrix under a translated root, extras everywhere."""
    rng = np.random.default_rng(7)
    rows = np.zeros(6, INTERLEAVED)
    rows["p"] = OCTAHEDRON * [1.0, 2.0, 0.5]
    rows["n"] = unit(OCTAHEDRON / [1.0, 2.0, 0.5])
    rows["uv"] = rng.random((6, 2))
    rows["t"][:, :3] = unit(np.cross(rows["n"], [0.3, 0.5, 0.8]))
    rows["t"][:, 3] = [1, -1, 1, -1, 1, 1]
    rows["pad"] = 0xDEADBEEF
    indices = OCTA_FACES.astype("<u2").tobytes()
    colors = rng.integers(0, 256, (6, 4)).astype("<u1").tobytes()
    points = rng.random((3, 3)).astype("<f4")
    blob = rows.tobytes() + indices + colors + points.tobytes()
    views = [
        {"buffer": 0, "byteOffset": 0, "byteLength": 312, "byteStride": 52, "target": 34962},
        {"buffer": 0, "byteOffset": 312, "byteLength": 48, "target": 34963},
        {"buffer": 0, "byteOffset": 360, "byteLength": 24},
        {"buffer": 0, "byteOffset": 384, "byteLength": 36},
    ]
    low, high = rows["p"].min(0).tolist(), rows["p"].max(0).tolist()
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": low,
         "max": high},
        {"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 6, "type": "VEC3"},
        {"bufferView": 0, "byteOffset": 24, "componentType": 5126, "count": 6, "type": "VEC2"},
        {"bufferView": 0, "byteOffset": 32, "componentType": 5126, "count": 6, "type": "VEC4"},
        {"bufferView": 1, "componentType": 5123, "count": 24, "type": "SCALAR"},
        {"bufferView": 2, "componentType": 5121, "normalized": True, "count": 6, "type": "VEC4"},
        {
            "bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC3",
            "min": points.min(0).tolist(), "max": points.max(0).tolist(),
        },
    ]  # fmt: skip
    surface = {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TANGENT": 3, "COLOR_0": 5}
    doc = {
        "asset": {"version": "2.0", "generator": "by hand"},
        "scene": 0,
        "scenes": [{"nodes": [0], "extras": {"kept": "scene"}}],
        "nodes": [
            {"name": "root", "children": [1], "translation": ROOT[:3, 3].tolist()},
            {"name": "child", "mesh": 0, "matrix": CHILD.T.reshape(-1).tolist()},
        ],
        "meshes": [
            {
                "name": "octa",
                "extras": {"kept": "mesh"},
                "primitives": [
                    {"attributes": surface, "indices": 4, "material": 0, "extras": {"k": 1}},
                    {"attributes": {"POSITION": 6}, "mode": 0},
                ],
            }
        ],
        "materials": [{"name": "paint", "extras": {"kept": "material"}}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    return make_glb(doc, blob), rows


def gltf_with_data_uri(glb: bytes) -> bytes:
    doc, blob = split_glb(glb)
    uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    doc["buffers"] = [{"byteLength": doc["buffers"][0]["byteLength"], "uri": uri}]
    return json.dumps(doc).encode()


def one_line_error(call, name: str) -> str:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(IsochorError) as caught:
            call()
    message = str(caught.value)
    assert message.startswith(f"{name}: ") and "\n" not in message, message
    return message


# -- reading -----------------------------------------------------------------------------------
def test_read_matches_trimesh_in_order():
    glb = edit(sphere_glb(), lambda d: d["nodes"][0].update(matrix=ROTATED.T.reshape(-1).tolist()))
    vertices, faces = read_gltf(glb, ".glb", name="s.glb")
    assert vertices.dtype == np.float64 and faces.dtype == np.int64
    np.testing.assert_allclose(vertices, trimesh_points(glb), **F32)
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.5)
    np.testing.assert_array_equal(faces, sphere.faces)
    mesh, _warns, bodies = clean_closed_surface(vertices, faces)
    assert bodies == 1 and signed_volume(mesh.vertices, mesh.faces) > 0


def test_read_scene_applies_node_transforms():
    glb = scene_glb()
    vertices, faces = read_gltf(glb, ".glb")
    expected = trimesh_points(glb)
    assert vertices.shape == expected.shape and len(faces) == 2 * 320 + 12
    np.testing.assert_allclose(rows_sorted(vertices), rows_sorted(expected), **F32)


def test_read_interleaved_hierarchy_skips_points():
    glb, rows = interleaved_glb()
    vertices, faces = read_gltf(glb, ".glb")
    world = ROOT @ CHILD
    np.testing.assert_allclose(vertices, rows["p"] @ world[:3, :3].T + world[:3, 3], **F32)
    np.testing.assert_array_equal(faces, OCTA_FACES)  # the points primitive is not surface
    np.testing.assert_allclose(rows_sorted(vertices), rows_sorted(trimesh_points(glb)), **F32)


def test_read_mirroring_node_reverses_winding():
    glb = edit(sphere_glb(), lambda d: d["nodes"][0].update(scale=[-1.0, 1.0, 1.0]))
    vertices, faces = read_gltf(glb, ".glb")
    assert signed_volume(vertices, faces) > 0  # counter-clockwise in the mirrored frame
    np.testing.assert_allclose(rows_sorted(vertices), rows_sorted(trimesh_points(glb)), **F32)


def test_read_without_scenes_uses_root_nodes():
    glb, _rows = interleaved_glb()
    plain = edit(glb, lambda d: (d.pop("scene"), d.pop("scenes")))
    np.testing.assert_array_equal(read_gltf(plain, ".glb")[0], read_gltf(glb, ".glb")[0])


# -- rewriting ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", sorted(DEFORMS))
def test_rewrite_positions_and_normals(kind):
    deform, jacobian = DEFORMS[kind]
    glb = edit(sphere_glb(), lambda d: d["nodes"][0].update(matrix=ROTATED.T.reshape(-1).tolist()))
    calls = []
    before, faces = read_gltf(glb, ".glb")
    out, notes = rewrite_gltf(
        glb, ".glb", lambda x: calls.append(len(x)) or deform(x), jacobian, name="s.glb"
    )
    assert calls == [len(before)] and notes == []
    after, faces_after = read_gltf(out, ".glb")
    np.testing.assert_allclose(after, deform(before), **F32)  # same count and order
    np.testing.assert_array_equal(faces_after, faces)
    np.testing.assert_allclose(trimesh_points(out), deform(before), **F32)

    doc0, bin0 = split_glb(glb)
    doc1, bin1 = split_glb(out)
    attrs = doc1["meshes"][0]["primitives"][0]["attributes"]
    assert attrs == doc0["meshes"][0]["primitives"][0]["attributes"] and len(bin1) == len(bin0)
    normals = values(doc1, bin1, attrs["NORMAL"])
    expected = expected_normals(values(doc0, bin0, attrs["NORMAL"]), before, ROTATED, jacobian)
    np.testing.assert_allclose(normals, expected, atol=1e-6)
    indices = doc0["meshes"][0]["primitives"][0]["indices"]
    assert element_bytes(doc1, bin1, indices) == element_bytes(doc0, bin0, indices)
    pos = doc1["accessors"][attrs["POSITION"]]
    local = values(doc1, bin1, attrs["POSITION"])
    assert pos["min"] == local.min(0).tolist() and pos["max"] == local.max(0).tolist()


def test_rewrite_keeps_uvs_materials_images():
    glb = textured_box().export(file_type="glb")
    out, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"])
    doc0, bin0 = split_glb(glb)
    doc1, bin1 = split_glb(out)
    uv = doc0["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]
    assert element_bytes(doc1, bin1, uv) == element_bytes(doc0, bin0, uv)
    for key in ("materials", "images", "textures", "nodes", "scenes"):
        assert doc1[key] == doc0[key], key
    image = doc0["images"][0]["bufferView"]
    view = doc0["bufferViews"][image]
    start, end = view["byteOffset"], view["byteOffset"] + view["byteLength"]
    assert bin1[start:end] == bin0[start:end]
    reloaded = trimesh.load(io.BytesIO(out), file_type="glb", force="mesh", process=False)
    original = trimesh.load(io.BytesIO(glb), file_type="glb", force="mesh", process=False)
    np.testing.assert_array_equal(reloaded.visual.uv, original.visual.uv)
    np.testing.assert_allclose(reloaded.vertices, bend(original.vertices), **F32)


def test_rewrite_scene_with_shared_accessors():
    """trimesh writes the two spheres' geometry once: the second transform gets its own
    accessors, the first is written in place."""
    glb = scene_glb()
    before, faces = read_gltf(glb, ".glb")
    out, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"])
    after, faces_after = read_gltf(out, ".glb")
    np.testing.assert_allclose(after, bend(before), **F32)
    np.testing.assert_array_equal(faces_after, faces)
    np.testing.assert_allclose(rows_sorted(trimesh_points(out)), rows_sorted(bend(before)), **F32)
    doc0, _ = split_glb(glb)
    doc1, _ = split_glb(out)
    assert len(doc1["accessors"]) == len(doc0["accessors"]) + 2  # POSITION, NORMAL once more


def test_rewrite_instanced_mesh_gets_a_copy_per_transform():
    def instance(doc):
        doc["nodes"].append({"name": "twin", "mesh": 0, "translation": [4.0, 0.0, 0.0]})
        doc["nodes"].append({"name": "same", "mesh": 0})  # the same transform as node 0
        doc["scenes"][0]["nodes"] += [1, 2]

    glb = edit(sphere_glb(), instance)
    before, _faces = read_gltf(glb, ".glb")
    out, notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"])
    assert any("2 transforms" in n for n in notes), notes
    np.testing.assert_allclose(read_gltf(out, ".glb")[0], bend(before), **F32)
    doc, _ = split_glb(out)
    assert [n["mesh"] for n in doc["nodes"]] == [0, 1, 0] and len(doc["meshes"]) == 2


def test_rewrite_interleaved_tangents_colors_points():
    glb, rows = interleaved_glb()
    world = ROOT @ CHILD
    out, notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"], name="octa.glb")
    assert notes == []
    doc0, bin0 = split_glb(glb)
    doc1, bin1 = split_glb(out)
    assert {k: v for k, v in doc1.items() if k != "accessors"} == {
        k: v for k, v in doc0.items() if k != "accessors"
    }  # same views, buffers, nodes, meshes, materials, extras
    new = np.frombuffer(bin1[:312], INTERLEAVED)
    np.testing.assert_array_equal(new["uv"], rows["uv"])
    np.testing.assert_array_equal(new["pad"], rows["pad"])
    assert bin1[312:384] == bin0[312:384]  # indices, colours
    points_world = rows["p"] @ world[:3, :3].T + world[:3, 3]
    moved = bend(points_world)
    np.testing.assert_allclose(new["p"] @ world[:3, :3].T + world[:3, 3], moved, **F32)
    lin = world[:3, :3]
    local = np.linalg.inv(lin) @ bend_jacobian(points_world) @ lin
    normals = expected_normals(rows["n"], points_world, world, bend_jacobian)
    np.testing.assert_allclose(new["n"], normals, atol=1e-6)
    tangents = unit(np.einsum("pab,pb->pa", local, rows["t"][:, :3]))
    np.testing.assert_allclose(new["t"][:, :3], tangents, atol=1e-6)
    np.testing.assert_array_equal(new["t"][:, 3], rows["t"][:, 3])
    dots = np.einsum("pa,pa->p", new["n"], new["t"][:, :3])
    assert np.abs(dots).max() < 1e-5  # still perpendicular: J t . J^-T n = t . n = 0
    cloud = np.frombuffer(bin0[384:420], "<f4").reshape(3, 3)
    expected = (bend(cloud @ world[:3, :3].T + world[:3, 3]) - world[:3, 3]) @ np.linalg.inv(lin).T
    np.testing.assert_allclose(np.frombuffer(bin1[384:420], "<f4").reshape(3, 3), expected, **F32)
    assert (
        doc1["accessors"][6]["max"]
        == np.frombuffer(bin1[384:420], "<f4").reshape(3, 3).max(0).tolist()
    )
    np.testing.assert_allclose(rows_sorted(trimesh_points(out)), rows_sorted(moved), **F32)


def test_morph_target_mode():
    glb = edit(sphere_glb(), lambda d: d["nodes"][0].update(matrix=ROTATED.T.reshape(-1).tolist()))
    before, _faces = read_gltf(glb, ".glb")
    out, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"], morph_target=True)
    doc0, bin0 = split_glb(glb)
    doc1, bin1 = split_glb(out)
    assert bin1[: len(bin0)] == bin0  # the original data untouched
    np.testing.assert_allclose(read_gltf(out, ".glb")[0], before)  # base positions unchanged
    mesh = doc1["meshes"][0]
    assert mesh["weights"] == [1.0] and mesh["extras"]["targetNames"] == ["isochor"]
    prim = mesh["primitives"][0]
    (target,) = prim["targets"]
    assert set(target) == {"POSITION", "NORMAL"}
    lin, move = ROTATED[:3, :3], ROTATED[:3, 3]
    local = values(doc0, bin0, prim["attributes"]["POSITION"])
    deformed_local = (bend(before) - move) @ np.linalg.inv(lin).T
    np.testing.assert_allclose(
        values(doc1, bin1, target["POSITION"]), deformed_local - local, **F32
    )
    acc = doc1["accessors"][target["POSITION"]]
    delta = values(doc1, bin1, target["POSITION"])
    assert acc["min"] == delta.min(0).tolist() and acc["max"] == delta.max(0).tolist()
    normals = values(doc0, bin0, prim["attributes"]["NORMAL"])
    new_normals = expected_normals(normals, before, ROTATED, bend_jacobian)
    np.testing.assert_allclose(
        values(doc1, bin1, target["NORMAL"]), new_normals - normals, atol=1e-6
    )


def test_morph_target_after_existing_targets():
    glb, _rows = interleaved_glb()

    def targets(doc):
        prims = doc["meshes"][0]["primitives"]
        prims[0]["targets"], prims[1]["targets"] = [{"POSITION": 1}], [{"POSITION": 6}]
        doc["meshes"][0]["weights"] = [0.5]
        doc["nodes"][1]["weights"] = [0.25]

    glb = edit(glb, targets)
    out, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["affine"], morph_target=True)
    doc, _ = split_glb(out)
    mesh = doc["meshes"][0]
    assert [len(p["targets"]) for p in mesh["primitives"]] == [2, 2]
    assert set(mesh["primitives"][0]["targets"][1]) == {"POSITION", "NORMAL", "TANGENT"}
    assert mesh["weights"] == [0.5, 1.0] and doc["nodes"][1]["weights"] == [0.25, 1.0]
    assert mesh["extras"] == {"kept": "mesh", "targetNames": ["target", "isochor"]}

    _out, notes = rewrite_gltf(glb, ".glb", *DEFORMS["affine"])
    assert any("morph targets of mesh 'octa' were kept" in n for n in notes), notes

    def animate(doc):
        doc["animations"] = [
            {"channels": [{"sampler": 0, "target": {"node": 1, "path": "weights"}}]}
        ]

    message = one_line_error(
        lambda: rewrite_gltf(edit(glb, animate), ".glb", *DEFORMS["affine"], morph_target=True),
        "model",
    )
    assert "animated" in message


def test_notes_for_skins_and_meshes_outside_the_scene():
    def change(doc):
        doc["nodes"][0]["skin"] = 0
        doc["skins"] = [{"joints": [0]}]
        doc["meshes"].append(copy.deepcopy(doc["meshes"][0]) | {"name": "spare"})

    glb = edit(sphere_glb(), change)
    out, notes = rewrite_gltf(glb, ".glb", *DEFORMS["affine"])
    assert notes == [
        "mesh 'spare' is not in the default scene; it was kept",
        "mesh 'geometry_0' is skinned; its skeleton (the joints) was not moved",
    ]
    doc0, bin0 = split_glb(glb)
    doc1, bin1 = split_glb(out)
    assert doc1["skins"] == [{"joints": [0]}] and doc1["meshes"][1] == doc0["meshes"][1]
    spare = doc0["meshes"][1]["primitives"][0]["attributes"]  # shared with mesh 0 by trimesh
    assert spare == doc0["meshes"][0]["primitives"][0]["attributes"]
    for index in spare.values():
        assert element_bytes(doc1, bin1, index) == element_bytes(doc0, bin0, index)
    before = read_gltf(glb, ".glb")[0]
    np.testing.assert_allclose(read_gltf(out, ".glb")[0], affine(before), **F32)


def test_gltf_with_data_uri_round_trip():
    glb = scene_glb()
    text = gltf_with_data_uri(glb)
    np.testing.assert_array_equal(read_gltf(text, ".gltf")[0], read_gltf(glb, ".glb")[0])
    out, notes = rewrite_gltf(text, ".GLTF", *DEFORMS["affine"])
    assert notes == []
    doc = json.loads(out)
    assert len(doc["buffers"]) == 1 and doc["buffers"][0]["uri"].startswith("data:")
    before = read_gltf(glb, ".glb")[0]
    np.testing.assert_allclose(read_gltf(out, ".gltf")[0], affine(before), **F32)
    np.testing.assert_allclose(
        rows_sorted(trimesh_points(out, "gltf")), rows_sorted(affine(before)), **F32
    )


def test_other_container_keeps_everything():
    """out_suffix: a .glb written as .gltf (and back) by the same writer, morph target kept."""
    glb, _rows = interleaved_glb()
    text, _notes = rewrite_gltf(
        glb, ".glb", *DEFORMS["bend"], morph_target=True, out_suffix=".gltf"
    )
    doc = json.loads(text)
    assert doc["meshes"][0]["extras"]["targetNames"] == ["isochor"]
    assert doc["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")
    same, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"], morph_target=True)
    assert split_glb(same)[0] == {**doc, "buffers": split_glb(same)[0]["buffers"]}
    back, _notes = rewrite_gltf(
        gltf_with_data_uri(glb), ".gltf", *DEFORMS["bend"], out_suffix=".glb"
    )
    plain, _notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"])
    assert back == plain


def test_gltf_with_external_buffers(tmp_path):
    """trimesh writes one .bin per buffer view: four external buffers, merged on writing."""
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(textured_box()), include_normals=True)
    for file_name, data in files.items():
        (tmp_path / file_name).write_bytes(data)
    text = files["model.gltf"]
    assert len(json.loads(text)["buffers"]) > 1
    before, faces = read_gltf(text, ".gltf", name="box.gltf", base_dir=tmp_path)
    np.testing.assert_allclose(before, textured_box().vertices, **F32)
    out, notes = rewrite_gltf(text, ".gltf", *DEFORMS["bend"], name="box.gltf", base_dir=tmp_path)
    assert sum("is now embedded" in n for n in notes) == len(json.loads(text)["buffers"])
    doc = json.loads(out)
    assert len(doc["buffers"]) == 1 and doc["buffers"][0]["uri"].startswith("data:")
    after, faces_after = read_gltf(out, ".gltf")  # needs no folder any more
    np.testing.assert_allclose(after, bend(before), **F32)
    np.testing.assert_array_equal(faces_after, faces)

    message = one_line_error(lambda: read_gltf(text, ".gltf", name="box.gltf"), "box.gltf")
    assert "gltf_buffer_0.bin" in message and "folder" in message
    (tmp_path / "gltf_buffer_1.bin").unlink()
    with pytest.raises(IsochorError, match="gltf_buffer_1.bin") as caught:
        read_gltf(text, ".gltf", name="box.gltf", base_dir=tmp_path)
    assert "\n" not in str(caught.value)


def test_real_model_round_trip():
    path = model("spot_triangulated.obj")
    spot = trimesh.load(path, process=False)
    assert spot.visual.uv is not None
    glb = spot.export(file_type="glb", include_normals=True)
    vertices, faces = read_gltf(glb, ".glb", name="spot.glb")
    np.testing.assert_allclose(vertices, trimesh_points(glb), **F32)
    mesh, _warns, bodies = clean_closed_surface(vertices, faces)
    assert bodies == 1 and len(mesh.faces) == len(faces)

    out, notes = rewrite_gltf(glb, ".glb", *DEFORMS["bend"], name="spot.glb")
    assert notes == []
    after, faces_after = read_gltf(out, ".glb")
    np.testing.assert_allclose(after, bend(vertices), **F32)
    np.testing.assert_array_equal(faces_after, faces)
    doc0, bin0 = split_glb(glb)
    doc1, bin1 = split_glb(out)
    uv = doc0["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]
    assert element_bytes(doc1, bin1, uv) == element_bytes(doc0, bin0, uv)
    reloaded = trimesh.load(io.BytesIO(out), file_type="glb", force="mesh", process=False)
    np.testing.assert_allclose(reloaded.vertices, bend(vertices), **F32)


# -- refusals: one line naming the file, no warning --------------------------------------------
def _set(path: str, value):
    def change(doc):
        *parents, last = path.split("/")
        target = doc
        for key in parents:
            target = target[int(key) if key.isdigit() else key]
        target[int(last) if last.isdigit() else last] = value

    return change


def _drop(path: str):
    def change(doc):
        *parents, last = path.split("/")
        target = doc
        for key in parents:
            target = target[int(key) if key.isdigit() else key]
        del target[int(last) if last.isdigit() else last]

    return change


REFUSED_DOCS = {
    "draco": (_set("extensionsUsed", ["KHR_draco_mesh_compression"]), "compressed meshes"),
    "meshopt": (_set("extensionsRequired", ["EXT_meshopt_compression"]), "compressed meshes"),
    "sparse": (_set("accessors/1/sparse", {"count": 1}), "sparse or data-less accessors"),
    "quantized": (_set("accessors/1/componentType", 5122), "quantized"),
    "instancing": (_set("nodes/0/extensions", {"EXT_mesh_gpu_instancing": {}}), "GPU instancing"),
    "out of range": (_set("accessors/1/count", 10**6), "out of the range of its buffer"),
    "negative index": (_set("meshes/0/primitives/0/attributes/POSITION", -1), "out of range"),
    "mesh missing": (_set("nodes/0/mesh", 5), "meshes index 5 is out of range"),
    "cycle": (_set("nodes/0/children", [0]), "reached twice"),
    "version": (_set("asset/version", "1.0"), "glTF version 1.0 is not supported"),
    "matrix": (_set("nodes/0/matrix", [1, 2]), "matrix must be 16 finite numbers"),
    "no primitives": (_drop("meshes/0/primitives"), "missing 'primitives'"),
    "no buffer data": (_drop("buffers/0/byteLength"), "missing 'byteLength'"),
    "stale index min/max": (_set("accessors/0/max", [0]), None),  # harmless, not refused
    "bad stride": (_set("bufferViews/1/byteStride", 4), "out of the range of its buffer"),
    "no scene": (_set("scene", 3), "scenes index 3 is out of range"),
}


@pytest.mark.parametrize("case", sorted(REFUSED_DOCS))
def test_refusals_of_the_document(case):
    change, words = REFUSED_DOCS[case]
    glb = edit(sphere_glb(), change)
    for call in (
        lambda: read_gltf(glb, ".glb", name="cow.glb"),
        lambda: rewrite_gltf(glb, ".glb", *DEFORMS["affine"], name="cow.glb"),
    ):
        if words is None:
            call()
            continue
        message = one_line_error(call, "cow.glb")
        assert words in message, message


def _truncate_json(glb: bytes) -> bytes:
    size = struct.unpack_from("<I", glb, 12)[0]
    return glb[:20] + glb[20 : 20 + size].replace(b"{", b"[", 1) + glb[20 + size :]


def _framed(glb: bytes) -> bytes:
    """The GLB with its header's total length set to its size."""
    return glb[:8] + struct.pack("<I", len(glb)) + glb[12:]


def _longer_bin_chunk(glb: bytes) -> bytes:
    at = 20 + struct.unpack_from("<I", glb, 12)[0]
    size = struct.unpack_from("<I", glb, at)[0]
    return glb[:at] + struct.pack("<I", size + 64) + glb[at + 4 :]


REFUSED_BYTES = {
    "empty": (lambda g: b"", ".glb", "not a GLB file"),
    "bad magic": (lambda g: b"glTX" + g[4:], ".glb", "not a GLB file"),
    "truncated": (lambda g: g[:-100], ".glb", "truncated"),
    "chunk past end": (_longer_bin_chunk, ".glb", "a chunk runs past its end"),
    "no json chunk": (lambda g: g[:16] + b"XXXX" + g[20:], ".glb", "first chunk is not JSON"),
    "json error": (_truncate_json, ".glb", "not valid glTF JSON"),
    "binary as gltf": (lambda g: g, ".gltf", "not valid glTF JSON"),
    "json not object": (lambda g: b"[1, 2]", ".gltf", "its JSON is not an object"),
    "obj suffix": (lambda g: g, ".obj", "not a glTF file suffix"),
    "no bin chunk": (lambda g: _framed(g[: 20 + struct.unpack_from("<I", g, 12)[0]]), ".glb",
                     "no data"),
    "bad base64": (lambda g: json.dumps({**split_glb(g)[0], "buffers": [
        {"byteLength": 8, "uri": "data:application/octet-stream;base64,@@@"}]}).encode(),
        ".gltf", "not a valid glTF file"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(REFUSED_BYTES))
def test_refusals_of_the_bytes(case):
    change, suffix, words = REFUSED_BYTES[case]
    data = change(sphere_glb())
    for call in (
        lambda: read_gltf(data, suffix, name="cow.glb"),
        lambda: rewrite_gltf(data, suffix, *DEFORMS["affine"], name="cow.glb"),
    ):
        message = one_line_error(call, "cow.glb")
        assert words in message, message


def test_no_triangles_and_no_mesh():
    glb, _rows = interleaved_glb()
    points_only = edit(glb, lambda d: d["meshes"][0]["primitives"].pop(0))
    assert "no triangles found" in one_line_error(lambda: read_gltf(points_only, ".glb"), "model")
    out, _ = rewrite_gltf(points_only, ".glb", *DEFORMS["affine"])  # points are deformed
    doc, blob = split_glb(out)
    assert not np.allclose(values(doc, blob, 6), values(*split_glb(glb), 6))
    no_mesh = edit(glb, lambda d: d["nodes"][1].pop("mesh"))
    message = one_line_error(lambda: rewrite_gltf(no_mesh, ".glb", *DEFORMS["affine"]), "model")
    assert "no mesh in the default scene" in message


def test_callback_errors_are_not_file_errors():
    def broken(x):
        raise ZeroDivisionError("a bug in the deformation")

    with pytest.raises(ZeroDivisionError):
        rewrite_gltf(sphere_glb(), ".glb", broken, affine_jacobian)
    with pytest.raises(ValueError, match="shapes"):
        rewrite_gltf(sphere_glb(), ".glb", lambda x: x[:, :2], affine_jacobian)


def _mutations(doc, rng, count):
    """Documents with one field replaced by junk or deleted, at random."""
    paths = []

    def walk(node, path):
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for key, value in items:
            paths.append((*path, key))
            if isinstance(value, (dict, list)):
                walk(value, (*path, key))

    walk(doc, ())
    junk = [None, -1, 0, 3, 2**40, 1.5, "x", [], {}, [0, 0], {"a": 1}, True, float("nan")]
    for _ in range(count):
        mutated = copy.deepcopy(doc)
        *parents, last = paths[rng.integers(len(paths))]
        target = mutated
        for key in parents:
            target = target[key]
        if rng.random() < 0.2 and isinstance(target, dict):
            del target[last]
        else:
            target[last] = junk[rng.integers(len(junk))]
        yield mutated


def test_fuzzed_documents_fail_with_one_line_or_load():
    rng = np.random.default_rng(2024)
    for glb in (interleaved_glb()[0], scene_glb()):
        doc, blob = split_glb(glb)
        for mutated in _mutations(doc, rng, 150):
            data = make_glb(mutated, blob)
            for call in (
                functools.partial(read_gltf, data, ".glb", name="f.glb"),
                functools.partial(rewrite_gltf, data, ".glb", *DEFORMS["bend"], name="f.glb"),
            ):
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    try:
                        call()
                    except IsochorError as exc:
                        assert str(exc).startswith("f.glb: ") and "\n" not in str(exc), str(exc)
