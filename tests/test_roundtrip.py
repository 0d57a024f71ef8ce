"""The round trip into the artist's pipeline (isochor.core.io.roundtrip): a model file given back
with its positions deformed and its normals transformed, everything else kept.

The maps: an affine one (a constant, non-orthogonal Jacobian with a positive determinant), a
nonlinear one whose Jacobian is checked against central differences, the identity, and the
FFD itself. The files: the shared models (skipped when ../shared is absent) and small files
written here (binary STL, big-endian PLY with normals and uv, OFF, OBJ with \\r\\n endings,
negative indices, continuations and a material library in another folder).
"""

from __future__ import annotations

import io
import re
import warnings

import numpy as np
import pytest
import trimesh

from isochor.core.errors import IsochorError
from isochor.core.io.roundtrip import ROUNDTRIP_FORMATS, Rewritten, positions, rewrite
from isochor.core.lattice import Lattice
from tests.models import CUBE_FACES, CUBE_VERTICES, icosphere, model

A = np.array([[1.3, 0.4, -0.2], [0.1, 0.8, 0.3], [-0.3, 0.2, 1.1]])  # not orthogonal
B = np.array([0.5, -1.25, 2.0])


def affine(x):
    return x @ A.T + B


def affine_jacobian(x):
    return np.broadcast_to(A, (len(x), 3, 3)).copy()


def wavy(x):
    """A nonlinear map coupling the axes: x_a + 0.1 sin(3 x_b), b the next axis."""
    return x + 0.1 * np.sin(3 * x[:, [1, 2, 0]])


def wavy_jacobian(x):
    jac = np.broadcast_to(np.eye(3), (len(x), 3, 3)).copy()
    for a, b in ((0, 1), (1, 2), (2, 0)):
        jac[:, a, b] += 0.3 * np.cos(3 * x[:, b])
    return jac


def identity(x):
    return x.copy()


def identity_jacobian(x):
    return np.broadcast_to(np.eye(3), (len(x), 3, 3)).copy()


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def inverse_transpose(jac, normals):
    """The normals a map with Jacobians ``jac`` gives: ``J^-T n``, normalised."""
    return unit(np.linalg.solve(np.swapaxes(jac, 1, 2), normals[..., None])[..., 0])


def central_jacobian(f, x, h=1e-6):
    """``J[p, a, b] = d f_a / d x_b`` by central differences."""
    steps = np.eye(3) * h
    return np.stack([(f(x + e) - f(x - e)) / (2 * h) for e in steps], axis=2)


def faces_of(data: bytes, suffix: str) -> int:
    """How many triangles trimesh reads from a file (on its own, not through Isochor)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mesh = trimesh.load(io.BytesIO(data), file_type=suffix[1:], process=False, force="mesh")
    return len(mesh.faces)


# -- OBJ, read here independently ------------------------------------------------------------
def keyword(line: bytes) -> bytes:
    words = line.split()
    return words[0] if words else b""


def obj_rows(data: bytes, key: bytes) -> np.ndarray:
    rows = [line.split()[1:4] for line in data.splitlines() if keyword(line) == key]
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def obj_normal_vertex(data: bytes) -> np.ndarray:
    """0-based: the first vertex each vn is used with in the faces (-1: none)."""
    first, nv, nn = {}, 0, 0
    for line in data.splitlines():
        key = keyword(line)
        nv, nn = nv + (key == b"v"), nn + (key == b"vn")
        for corner in line.split()[1:] if key == b"f" else ():
            parts = corner.split(b"/")
            if len(parts) == 3 and parts[2]:
                v, n = int(parts[0]), int(parts[2])
                v, n = (v - 1 if v > 0 else nv + v), (n - 1 if n > 0 else nn + n)
                first.setdefault(n, v)
    return np.array([first.get(i, -1) for i in range(nn)], dtype=np.int64)


def check_obj(before: bytes, after: bytes, deform, jacobian) -> None:
    """Every line but v and vn byte for byte; v and vn keep their further tokens and line
    end; the positions are deform(original) exactly; the normals the inverse transpose."""
    lines, new_lines = before.splitlines(keepends=True), after.splitlines(keepends=True)
    assert len(new_lines) == len(lines)
    for old, new in zip(lines, new_lines):
        assert keyword(new) == keyword(old)
        if keyword(old) in (b"v", b"vn"):
            assert new.split()[4:] == old.split()[4:]  # w, vertex colours as written
            assert new[len(new.rstrip(b"\r\n")) :] == old[len(old.rstrip(b"\r\n")) :]
        else:
            assert new == old
    points = obj_rows(before, b"v")
    np.testing.assert_array_equal(obj_rows(after, b"v"), deform(points))
    normals = obj_rows(before, b"vn")
    if len(normals):
        at = obj_normal_vertex(before)
        where = np.where(at[:, None] >= 0, points[at], points.mean(axis=0))
        expected = inverse_transpose(jacobian(where), normals)
        np.testing.assert_allclose(obj_rows(after, b"vn"), expected, atol=1e-12)


@pytest.mark.parametrize(
    "name", ["spot_triangulated.obj", "torus_knot_quads.obj", "cow_viewpoint_polygons.obj"]
)
@pytest.mark.parametrize("maps", [(affine, affine_jacobian), (wavy, wavy_jacobian)])
def test_obj_models_keep_everything_but_positions_and_normals(name, maps):
    data = model(name).read_bytes()
    done = rewrite(data, ".obj", *maps, name=name)
    check_obj(data, done.data, *maps)
    assert len(positions(done.data, ".obj")) == len(obj_rows(data, b"v"))
    assert faces_of(done.data, ".obj") == faces_of(data, ".obj")
    polygons = [len(line.split()) for line in data.splitlines() if keyword(line) == b"f"]
    assert [len(line.split()) for line in done.data.splitlines() if keyword(line) == b"f"] == (
        polygons
    )


KINDS = (b"v", b"vt", b"vn", b"f", b"g", b"o", b"s", b"usemtl", b"mtllib", b"#", b"l", b"p")


def kinds(data: bytes) -> dict:
    words = [keyword(line) for line in data.splitlines()]
    return {kind: words.count(kind) for kind in KINDS}


@pytest.mark.parametrize(
    "name, expected",
    [
        ("spot_triangulated.obj", {b"v": 2930, b"vt": 3225, b"f": 5856}),  # UV seams
        ("torus_knot_quads.obj", {b"v": 1440, b"vn": 1440, b"f": 1440, b"mtllib": 1}),
        ("cow_viewpoint_polygons.obj", {b"vn": 3267, b"f": 3263, b"g": 173, b"s": 245}),
    ],
)
def test_obj_counts_per_kind_are_unchanged(name, expected):
    data = model(name).read_bytes()
    new = rewrite(data, ".obj", wavy, wavy_jacobian, name=name).data
    assert kinds(new) == kinds(data)
    assert expected.items() <= kinds(data).items()
    assert new.count(b"\r\n") == data.count(b"\r\n")


def test_normals_follow_the_central_difference_jacobian():
    data = model("torus_knot_quads.obj").read_bytes()
    points, normals = obj_rows(data, b"v"), obj_rows(data, b"vn")
    new = obj_rows(rewrite(data, ".obj", wavy, wavy_jacobian).data, b"vn")
    at = points[obj_normal_vertex(data)]
    # central differences, h = 1e-6: truncation h^2/6 |f'''| (|f'''| <= 0.1 * 27) and the
    # rounding of the steps and of f, at most eps (|f| + |J| |x|) / h (|J| <= 1.3)
    h, eps = 1e-6, np.finfo(np.float64).eps
    fd = h**2 / 6 * 2.7 + eps * (np.abs(wavy(at)).max() + 1.3 * np.abs(at).max()) / h
    jac = central_jacobian(wavy, at)
    np.testing.assert_allclose(jac, wavy_jacobian(at), rtol=0, atol=fd)
    # unit(J^-T n) moves at most |J^-1| |dJ| when J moves by dJ, and |dJ|_2 <= 3 fd
    inv = np.linalg.norm(np.linalg.inv(wavy_jacobian(at)), 2, axis=(1, 2)).max()
    np.testing.assert_allclose(new, inverse_transpose(jac, normals), rtol=0, atol=3 * fd * inv)
    assert np.allclose(np.linalg.norm(new, axis=1), 1.0, atol=1e-14)


def test_the_ffd_itself_rewrites_the_cow():
    data = model("cow_viewpoint_polygons.obj").read_bytes()
    points = positions(data, ".obj")
    lattice = Lattice.around(points, (4, 3, 3), padding=0.05)
    nodes = lattice.rest_nodes.copy()
    nodes[lattice.index(3, 1, 1)] += (1.0, 2.0, 0.5)
    deform = lambda x: lattice.deform(x, nodes)  # noqa: E731
    jacobian = lambda x: lattice.jacobian(x, nodes)  # noqa: E731
    done = rewrite(data, ".obj", deform, jacobian, name="cow")
    check_obj(data, done.data, deform, jacobian)
    assert not np.allclose(positions(done.data, ".obj"), points)


def test_missing_material_library_is_kept_and_said(tmp_path):
    path = model("torus_knot_quads.obj")
    data = path.read_bytes()
    done = rewrite(
        data,
        ".obj",
        affine,
        affine_jacobian,
        name=path.name,
        source_dir=path.parent,
        out_dir=tmp_path,
    )
    assert b"mtllib ./quadknot.obj.mtl\r\n" in done.data
    assert any("quadknot.obj.mtl" in note and "not found" in note for note in done.notes)


def test_material_library_in_a_subfolder_is_found_from_another_output_folder(tmp_path):
    source, out = tmp_path / "src", tmp_path / "out" / "deeper"
    (source / "materials").mkdir(parents=True)
    out.mkdir(parents=True)
    (source / "materials" / "mat.mtl").write_text("newmtl red\nKd 1 0 0\n")
    data = b"mtllib materials/mat.mtl missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n"
    done = rewrite(
        data, ".obj", affine, affine_jacobian, name="m.obj", source_dir=source, out_dir=out
    )
    first = done.data.splitlines()[0]
    assert first == b"mtllib ../../src/materials/mat.mtl missing.mtl"
    assert (out / first.split()[1].decode()).resolve() == (source / "materials" / "mat.mtl")
    assert [n for n in done.notes if "missing.mtl" in n]
    check_obj(
        data.replace(b"materials/mat.mtl", b"../../src/materials/mat.mtl"),
        done.data,
        affine,
        affine_jacobian,
    )
    # the same folder, or no folders: the line as it was
    for dirs in ({"source_dir": source, "out_dir": source}, {}):
        same = rewrite(data, ".obj", affine, affine_jacobian, **dirs)
        assert same.data.splitlines()[0] == data.splitlines()[0] and not same.notes


def test_obj_crlf_negative_indices_continuations_and_shared_normals():
    data = (
        b"# a comment\r\n"
        b"o quad\r\n"
        b"v 0 0 0\r\n"
        b"v 1 0 0 1.0\r\n"  # w
        b"v 1 \\\r\n 1 0 0.5 0.25 0.125\r\n"  # a continued line, with colours
        b"v 0 1 0\r\n"
        b"vt 0 0\r\nvt 1 0\r\nvt 1 1\r\n"
        b"vn 0 0 1\r\n"
        b"vn 0.6 0 0.8\r\n"
        b"vn 1 0 0\r\n"  # used by no face
        b"s 1\r\n"
        b"f -4/1/-3 -3/2/-3 -2/3/-2 \\\r\n -1/1/-2\r\n"  # vn 1 at v 1 and 2; vn 2 at 3, 4
        b"\r\n"
        b"l 1 2\r\n"
    )
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    np.testing.assert_array_equal(positions(data, ".obj"), points)
    done = rewrite(data, ".obj", wavy, wavy_jacobian, name="quad.obj")
    np.testing.assert_array_equal(positions(done.data, ".obj"), wavy(points))
    lines = done.data.split(b"\r\n")
    assert len(lines) == len(data.split(b"\r\n"))
    assert lines[3].endswith(b" 1.0") and lines[4].endswith(b" \\")
    assert lines[5].endswith(b" 0.5 0.25 0.125") and len(lines[5].split()) == 5
    for i in (0, 1, 7, 8, 9, 13, 14, 15, 16, 17):
        assert lines[i] == data.split(b"\r\n")[i]
    normals = obj_rows(done.data.replace(b"\\\r\n", b""), b"vn")
    original = obj_rows(data, b"vn")
    jac = wavy_jacobian(np.vstack([points[[0, 2]], points.mean(axis=0)]))
    np.testing.assert_allclose(normals, inverse_transpose(jac, original), atol=1e-12)
    assert sorted(done.notes) == sorted(
        [
            "1 normal(s) used by no face took the deformation at the centroid",
            "2 shared normal(s) took the deformation of their first vertex",
        ]
    )


def test_a_comment_ending_in_a_backslash_continues_nothing():
    data = b"# C:\\models\\\nv 0 0 0\nv 1 0 0 \\\n 0\nv 0 1 0\nf 1 2 3 # a comment \\\nv 5 5 5\n"
    np.testing.assert_array_equal(
        positions(data, ".obj"), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]]
    )
    assert rewrite(data, ".obj", affine, affine_jacobian).data.count(b"\\") == data.count(b"\\")


def test_obj_identity_is_byte_identical():
    exact = b"v 0.10000000000000001 2 -3.5\nv 1e-300 0 1\nv 4 5 6\nvn 0 0 1\nf 1//1 2//1 3//1\n"
    for data in (exact, model("spot_triangulated.obj").read_bytes()):
        assert rewrite(data, ".obj", identity, identity_jacobian).data == data
    # a map that moves nothing in value keeps every token, whatever its spelling
    spelled = b"v 1.50 +2 3e0\nv 0 0 0\nv 1 1 1\nf 1 2 3\n"
    assert rewrite(spelled, ".obj", lambda x: x + 0.0, identity_jacobian).data == spelled


# -- PLY --------------------------------------------------------------------------------------
def test_ascii_ply_keeps_its_extra_properties_and_faces():
    path = model("stanford_bunny_flipped_vtk.ply")
    data = path.read_bytes()
    done = rewrite(data, ".ply", affine, affine_jacobian, name=path.name)
    end = data.index(b"end_header\n") + len(b"end_header\n")
    assert done.data[:end] == data[:end]
    old_lines, new_lines = data[end:].splitlines(), done.data[end:].splitlines()
    assert len(new_lines) == len(old_lines) and new_lines[35947:] == old_lines[35947:]
    old = np.array([line.split() for line in old_lines[:35947]], dtype=np.float64)
    new = np.array([line.split() for line in new_lines[:35947]], dtype=np.float64)
    expected = affine(old[:, :3]).astype(np.float32)  # declared float: float32 rounding
    np.testing.assert_array_equal(new[:, :3].astype(np.float32), expected)
    extra = [line.split()[3:] for line in old_lines[:35947]]  # confidence, intensity: as text
    assert [line.split()[3:] for line in new_lines[:35947]] == extra
    assert faces_of(done.data, ".ply") == faces_of(data, ".ply") == 69451
    assert rewrite(data, ".ply", identity, identity_jacobian).data == data


def test_binary_ply_of_346k_triangles_is_exact():
    """(How fast: the benchmark's row "armadillo 346k: its PLY given back deformed".)"""
    data = model("armadillo_loop1_346k.ply").read_bytes()
    points = positions(data, ".ply")
    assert points.shape == (172966, 3)
    raw = trimesh.load(io.BytesIO(data), file_type="ply", process=False)
    np.testing.assert_array_equal(points, raw.vertices)
    calls = []

    def deform(x):
        calls.append(len(x))
        return affine(x)

    done = rewrite(data, ".ply", deform, pytest.fail)  # no normals: no Jacobian
    assert calls == [len(points)]  # the map is called once, on every position
    end = data.index(b"end_header\n") + 11
    block = end + 12 * len(points)
    assert done.data[:end] == data[:end] and done.data[block:] == data[block:]
    moved = np.frombuffer(done.data[end:block], "<f4").reshape(-1, 3)
    np.testing.assert_array_equal(moved, affine(points).astype(np.float32))
    assert faces_of(done.data, ".ply") == 345928
    assert rewrite(data, ".ply", identity, identity_jacobian).data == data


def big_endian_ply(mesh, list_in_vertex=False, extras=True) -> tuple[bytes, dict]:
    """A binary big-endian PLY whose vertices have normals, uv and a colour (and a list of
    weights); ``extras``: a material element (with a list) before the vertices, and faces
    with a flag byte (trimesh reads neither)."""
    v, f = mesh.vertices, mesh.faces
    weights = "property list uchar float weights\n" if list_in_vertex else ""
    header = (
        "ply\nformat binary_big_endian 1.0\ncomment written by test_roundtrip\nobj_info x\n"
        + "element material 2\nproperty list uchar uchar name\nproperty float shininess\n" * extras
        + f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"{weights}property float nx\nproperty float ny\nproperty float nz\n"
        "property float s\nproperty float t\nproperty uchar red\n"
        f"element face {len(f)}\nproperty list uchar int vertex_indices\n"
        + "property uchar flags\n" * extras
        + "end_header\n"
    ).encode()
    materials = (b"\x03red>\x80\x00\x00" + b"\x05green?\x00\x00\x00") * extras
    normals = unit(v)
    uv = np.column_stack([np.arctan2(v[:, 1], v[:, 0]), v[:, 2]])
    rows = []
    for i, p in enumerate(v):
        row = p.astype(">f4").tobytes()
        row += bytes([i % 3]) + np.full(i % 3, 0.25, ">f4").tobytes() if list_in_vertex else b""
        rows.append(row + np.r_[normals[i], uv[i]].astype(">f4").tobytes() + bytes([i % 256]))
    face = np.zeros(len(f), dtype=[("n", "u1"), ("i", ">i4", (3,)), ("flag", "u1")][: 2 + extras])
    face["n"], face["i"] = 3, f
    parts = {"header": header + materials, "vertices": b"".join(rows), "faces": face.tobytes()}
    return b"".join(parts.values()), parts


@pytest.mark.parametrize("extras", [True, False])
def test_big_endian_ply_with_normals_uv_and_elements_before_the_vertices(extras):
    mesh = icosphere(2, radius=2.0, center=(0.5, 0.0, -1.0))
    data, parts = big_endian_ply(mesh, extras=extras)
    np.testing.assert_array_equal(positions(data, ".ply"), mesh.vertices.astype(">f4"))
    done = rewrite(data, ".ply", affine, affine_jacobian, name="ball.ply")
    head, tail = len(parts["header"]), len(parts["faces"])
    assert done.data[:head] == parts["header"] and done.data[-tail:] == parts["faces"]
    assert len(done.data) == len(data)
    rows = done.data[head:-tail]
    table = np.frombuffer(rows, dtype=[("f", ">f4", 8), ("red", "u1")])
    assert len(table) == len(mesh.vertices) and table.itemsize == 33
    stored = mesh.vertices.astype(np.float32).astype(np.float64)  # what the file holds
    np.testing.assert_array_equal(table["f"][:, :3], affine(stored).astype(np.float32))
    normals = unit(mesh.vertices).astype(np.float32).astype(np.float64)
    expected = inverse_transpose(affine_jacobian(stored), normals)
    np.testing.assert_allclose(table["f"][:, 3:6], expected, atol=2e-7)
    uv = np.column_stack(
        [np.arctan2(mesh.vertices[:, 1], mesh.vertices[:, 0]), mesh.vertices[:, 2]]
    )
    np.testing.assert_array_equal(table["f"][:, 6:], uv.astype(np.float32))
    np.testing.assert_array_equal(table["red"], np.arange(len(table)) % 256)
    if not extras:
        assert faces_of(done.data, ".ply") == faces_of(data, ".ply") == len(mesh.faces)
    assert rewrite(data, ".ply", identity, identity_jacobian).data == data


def test_ply_vertices_with_a_list_property_are_refused():
    data, _ = big_endian_ply(icosphere(1), list_in_vertex=True)
    with pytest.raises(IsochorError, match=r"^w\.ply: .* list properties$"):
        rewrite(data, ".ply", affine, affine_jacobian, name="w.ply")


# -- STL --------------------------------------------------------------------------------------
def test_ascii_stl_keeps_its_solids_and_layout():
    path = model("multibody_inconsistent_winding.stl")
    data = path.read_bytes()
    done = rewrite(data, ".stl", wavy, wavy_jacobian, name=path.name)
    lines, new = data.splitlines(), done.data.splitlines()
    assert len(new) == len(lines)
    indent = lambda line: line[: len(line) - len(line.lstrip())]  # noqa: E731
    for old_line, new_line in zip(lines, new):
        if keyword(old_line) in (b"vertex", b"facet"):
            assert new_line.split()[:-3] == old_line.split()[:-3]
            assert indent(new_line) == indent(old_line)
        else:
            assert new_line == old_line  # solid bodyB ... endsolid, outer loop, endloop
    corners = np.array([ln.split()[1:] for ln in lines if keyword(ln) == b"vertex"], dtype=float)
    moved = np.array([ln.split()[1:] for ln in new if keyword(ln) == b"vertex"], dtype=float)
    np.testing.assert_array_equal(moved, wavy(corners))
    np.testing.assert_array_equal(positions(data, ".stl"), corners)
    tri = moved.reshape(-1, 3, 3)
    normals = np.array([ln.split()[2:] for ln in new if keyword(ln) == b"facet"], dtype=float)
    expected = unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    np.testing.assert_allclose(normals, expected, atol=1e-15)
    assert faces_of(done.data, ".stl") == faces_of(data, ".stl") == 32
    assert rewrite(data, ".stl", identity, identity_jacobian).data == data


def binary_stl(tri: np.ndarray, header: bytes = b"test header, binary") -> bytes:
    rows = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rows["v"], rows["a"] = tri, np.arange(len(tri)) + 1000
    stored = rows["v"].astype(np.float64)
    rows["n"] = unit(np.cross(stored[:, 1] - stored[:, 0], stored[:, 2] - stored[:, 0]))
    return header.ljust(80, b"\0") + np.uint32(len(tri)).tobytes() + rows.tobytes()


@pytest.mark.parametrize("header", [b"test header, binary", b"solid but binary"])
def test_binary_stl_keeps_its_header_and_attributes(header):
    mesh = icosphere(2)
    data = binary_stl(mesh.vertices[mesh.faces], header)
    done = rewrite(data, ".stl", affine, pytest.fail, name="ball.stl")
    assert done.data[:84] == data[:84] and len(done.data) == len(data)
    rows = np.frombuffer(
        done.data, [("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")], offset=84
    )
    np.testing.assert_array_equal(rows["a"], np.arange(len(rows)) + 1000)
    corners = mesh.vertices[mesh.faces].astype(np.float32).astype(np.float64)
    np.testing.assert_array_equal(rows["v"], affine(corners).astype(np.float32))
    tri = rows["v"].astype(np.float64)
    expected = unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    np.testing.assert_allclose(rows["n"], expected, atol=1e-7)
    assert faces_of(done.data, ".stl") == len(mesh.faces)
    assert rewrite(data, ".stl", identity, identity_jacobian).data == data


def test_a_facet_made_degenerate_gets_a_zero_normal_and_a_note():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 0, 1], [0, 1, 1]]], float)
    flatten = lambda x: x * (1.0, 0.0, 1.0)  # noqa: E731  (every triangle in y = 0)
    done = rewrite(binary_stl(tri), ".stl", flatten, pytest.fail)
    rows = np.frombuffer(
        done.data, [("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")], offset=84
    )
    assert not rows["n"].any()
    assert done.notes == ["2 facet(s) are degenerate after the deformation; their normals are 0"]


# -- OFF --------------------------------------------------------------------------------------
def cube_off(key: str = "COFF", counts_inline: bool = False) -> bytes:
    normals = "N" in key
    lines = ["# a cube, with comments", f"{key} 8 12 0" if counts_inline else key]
    lines += [] if counts_inline else ["# vertices faces edges", "8 12 0"]
    for i, p in enumerate(CUBE_VERTICES):
        n = " ".join(f"{c:g}" for c in unit(p - 0.5)) + " " if normals else ""
        lines.append(" ".join(f"{c:g}" for c in p) + f" {n}{i * 30} 0 0 255  # corner {i}")
    lines += [f"3 {a} {b} {c} 0.5 0.5 0.5" for a, b, c in CUBE_FACES]
    return ("\n".join(lines) + "\n").encode()


@pytest.mark.parametrize("key, inline", [("COFF", False), ("OFF", True), ("NOFF", False)])
def test_off_keeps_its_header_comments_colours_and_faces(key, inline):
    data = cube_off(key, inline)
    np.testing.assert_array_equal(positions(data, ".off"), CUBE_VERTICES)
    done = rewrite(data, ".off", wavy, wavy_jacobian, name="cube.off")
    lines, new = data.splitlines(), done.data.splitlines()
    first = 2 if inline else 4
    assert new[:first] == lines[:first] and new[first + 8 :] == lines[first + 8 :]
    count = 6 if key == "NOFF" else 3
    for old_line, new_line in zip(lines[first : first + 8], new[first : first + 8]):
        assert new_line.split()[count:] == old_line.split()[count:]  # colours, comments
    moved = np.array([line.split()[:3] for line in new[first : first + 8]], dtype=float)
    np.testing.assert_array_equal(moved, wavy(CUBE_VERTICES))
    if key == "NOFF":
        normals = np.array([line.split()[3:6] for line in new[first : first + 8]], dtype=float)
        old = np.array([line.split()[3:6] for line in lines[first : first + 8]], dtype=float)
        expected = inverse_transpose(wavy_jacobian(CUBE_VERTICES), old)
        np.testing.assert_allclose(normals, expected, atol=1e-12)
    else:
        assert faces_of(done.data, ".off") == 12
    assert rewrite(data, ".off", identity, identity_jacobian).data == data


# -- the contract: one call, one-line errors ------------------------------------------------
def test_deform_once_and_the_jacobian_once_only_for_files_with_normals():
    calls = {"deform": 0, "jacobian": 0}

    def deform(x):
        calls["deform"] += 1
        return affine(x)

    def jacobian(x):
        calls["jacobian"] += 1
        return affine_jacobian(x)

    rewrite(model("torus_knot_quads.obj").read_bytes(), ".obj", deform, jacobian)
    assert calls == {"deform": 1, "jacobian": 1}
    rewrite(model("spot_triangulated.obj").read_bytes(), ".obj", deform, jacobian)
    assert calls == {"deform": 2, "jacobian": 1}
    assert ROUNDTRIP_FORMATS == (".obj", ".ply", ".stl", ".off")
    assert isinstance(rewrite(cube_off(), ".OFF", deform, jacobian), Rewritten)


BAD = [
    (".obj", b"v 1 2\nf 1 1 1\n", "line 1"),
    (".obj", b"# x\nv 1 x 3\n", "line 2"),
    (".obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n", "line 5"),
    (".obj", b"v 0 0 0\nv nan 0 0\n", "vertex 2"),
    (".obj", b"vt 0 0\nf 1 2 3\n", "no vertices"),
    (".obj", b"", "empty"),
    (".obj", b"v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r", "line 1 ends in a lone carriage return"),
    (".ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\nend_header\n", "flaot"),
    (".ply", b"ply\nformat ascii 1.0\nelement face 0\nend_header\n", "no vertices"),
    (
        ".ply",
        b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        b"property float z\nend_header\n1 2 3\n4 5\n",
        "do not hold 3 values each",
    ),
    (
        ".ply",
        b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        b"property float z\nend_header\n1 2 3 0\n4 5 6\n",
        "do not hold 3 values each",
    ),
    (
        ".ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
        b"property float y\nproperty float z\nend_header\n" + bytes(20),
        "truncated",
    ),
    (
        ".ply",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nproperty int y\n"
        b"property int z\nend_header\n1 2 3\n",
        "float or double",
    ),
    (".ply", b"PK\x03\x04 a zip", "not a PLY"),
    (".stl", bytes(80) + np.uint32(5).tobytes() + bytes(100), "5 binary STL triangles"),
    (
        ".stl",
        b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        b"vertex 0 1 0\nvertex 1 1 0\nendloop\nendfacet\nendsolid x\n",
        "three vertices",
    ),
    (
        ".stl",
        b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 zero\n"
        b"vertex 0 1 0\nendloop\nendfacet\nendsolid x\n",
        "facet 1",
    ),
    (".stl", b"tiny", "not an STL"),
    (".off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n", "ends before"),
    (".off", b"4OFF\n1 0 0\n0 0 0 1\n", "3D ASCII OFF"),
    (".off", b"OFF BINARY\n" + bytes(40), "3D ASCII OFF"),
    (".off", b"OFF\n# nothing more\n", "OFF"),
    (".off", b"OFF\nthree 1 0\n", "OFF"),
    (".gltf", b"{}", "cannot rewrite"),
]


@pytest.mark.parametrize(
    "suffix, data, says", BAD, ids=[f"{s}-{i}" for i, (s, *_) in enumerate(BAD)]
)
def test_malformed_files_give_one_line_naming_the_file(suffix, data, says):
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        with pytest.raises(IsochorError) as info:
            rewrite(data, suffix, affine, affine_jacobian, name="bad" + suffix)
    message = str(info.value)
    assert message.startswith(f"bad{suffix}: ") and "\n" not in message and says in message


def test_a_map_that_is_not_finite_is_said():
    data = cube_off()
    with pytest.raises(IsochorError, match=r"^c\.off: the deformation is not finite at 8 of 8"):
        rewrite(data, ".off", lambda x: x / 0.0, affine_jacobian, name="c.off")
    noff = cube_off("NOFF")
    with pytest.raises(IsochorError, match="the Jacobian is not finite"):
        rewrite(noff, ".off", affine, lambda x: affine_jacobian(x) * np.nan, name="c.off")


def fuzz_inputs():
    """Small files of every kind, cut short and with bytes changed (seeded)."""
    sphere = icosphere(1)
    files = [
        (".obj", model("torus_knot_quads.obj").read_bytes()[:6000]),
        (".obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//-1\n"),
        (".ply", big_endian_ply(sphere)[0]),
        (".ply", big_endian_ply(sphere, list_in_vertex=True)[0]),
        (".ply", model("stanford_bunny_flipped_vtk.ply").read_bytes()[:3000]),
        (".stl", binary_stl(sphere.vertices[sphere.faces])),
        (".stl", model("multibody_inconsistent_winding.stl").read_bytes()),
        (".off", cube_off("NOFF")),
    ]
    rng = np.random.default_rng(10)
    for suffix, data in files:
        for _ in range(40):
            cut = bytearray(data[: rng.integers(0, len(data) + 1)])
            for _ in range(rng.integers(0, 4)):
                if cut:
                    cut[rng.integers(len(cut))] = rng.choice(list(b"0-9 .\n/#\\e\x00\xff"))
            yield suffix, bytes(cut)


def test_damaged_files_give_a_file_or_one_line():
    for suffix, data in fuzz_inputs():
        try:
            with warnings.catch_warnings(), np.errstate(all="raise"):
                warnings.simplefilter("error")
                done = rewrite(data, suffix, wavy, wavy_jacobian, name="f" + suffix)
        except IsochorError as exc:
            assert str(exc).startswith(f"f{suffix}: ") and "\n" not in str(exc)
        else:
            assert isinstance(done.data, bytes)
            assert len(positions(done.data, suffix)) == len(positions(data, suffix))


def test_obj_positions_are_the_v_lines_even_where_trimesh_splits_seams():
    data = model("spot_triangulated.obj").read_bytes()
    points = positions(data, ".obj")
    assert points.shape == (2930, 3)
    np.testing.assert_array_equal(points, obj_rows(data, b"v"))
    assert re.search(rb"^vt ", data, re.M)
