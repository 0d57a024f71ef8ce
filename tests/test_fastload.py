"""The fast paths of loading a large model give what the general ones give: the direct
binary PLY reader (isochor.core.io.meshio.binary_ply) what trimesh reads, the sparse edge
numbering and body labels what sorting gives, the hashed "anything to weld / drop?" test,
the blocked tetrahedron volumes and the pyramid's closedness test."""

from __future__ import annotations

import io

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components

from isochor.core.bodies import tetra_volumes
from isochor.core.io.meshio import binary_ply, load_mesh, mesh_bytes
from isochor.core.io.repair import (
    EdgeReport,
    any_repeated_row,
    balanced,
    body_labels,
    drop_duplicates,
    group_rows,
    weld,
)
from isochor.core.mesh import TriMesh
from isochor.core.scenario.problem import load_model
from isochor.core.solve.pyramid import build_pyramid
from isochor.core.volume import face_volumes
from tests.models import box, icosphere, joined


# -- the binary PLY reader ----------------------------------------------------------------
def _ply(
    vertex_props, face_prop, rows: bytes, faces: bytes, nv: int, nf: int, fmt="binary_little_endian"
):
    head = ["ply", f"format {fmt} 1.0", "comment made by a test", f"element vertex {nv}"]
    head += [f"property {t} {n}" for t, n in vertex_props]
    head += [f"element face {nf}", face_prop, "end_header"]
    return ("\n".join(head) + "\n").encode() + rows + faces


def _trimesh(data: bytes):
    m = trimesh.load_mesh(io.BytesIO(data), file_type="ply", process=False)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _layouts():
    mesh = icosphere(2)
    v, f = mesh.vertices, mesh.faces
    rng = np.random.default_rng(1)
    out = {"own writer (double, uchar int)": mesh_bytes(mesh, ".ply")}
    # float32 with normals and colours; uint indices with a uint8 count
    vt = np.dtype([("x", "<f4"), ("nx", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1")])
    rows = np.zeros(len(v), vt)
    rows["x"], rows["y"], rows["z"] = v.T
    rows["nx"], rows["red"] = rng.random(len(v)), 7
    ft = np.dtype([("n", "u1"), ("i", "<u4", (3,))])
    tris = np.zeros(len(f), ft)
    tris["n"], tris["i"] = 3, f
    props = [("float", "x"), ("float", "nx"), ("float", "y"), ("float", "z"), ("uchar", "red")]
    out["float32 + extras, uint"] = _ply(
        props,
        "property list uint8 uint vertex_index",
        rows.tobytes(),
        tris.tobytes(),
        len(v),
        len(f),
    )
    return out


@pytest.mark.parametrize("name", ["own writer (double, uchar int)", "float32 + extras, uint"])
def test_binary_ply_reads_what_trimesh_reads(name):
    data = _layouts()[name]
    direct = binary_ply(data)
    assert direct is not None
    tv, tf = _trimesh(data)
    assert np.array_equal(direct[0], tv) and direct[0].dtype == np.float64
    assert np.array_equal(direct[1], tf) and direct[1].dtype == np.int64


def test_binary_ply_leaves_other_files_to_trimesh(tmp_path):
    good = mesh_bytes(icosphere(1), ".ply")
    head, body = good.split(b"end_header\n", 1)
    cases = {
        "ascii": good.replace(b"binary_little_endian", b"ascii"),
        "big endian": good.replace(b"binary_little_endian", b"binary_big_endian"),
        "trailing bytes": good + b"\n",
        "truncated": good[:-5],
        "crlf": head.replace(b"\n", b"\r\n") + b"end_header\r\n" + body,
        "an edge element": head + b"element edge 0\nproperty int vertex1\nend_header\n" + body,
    }
    for name, data in cases.items():
        assert binary_ply(data) is None, name
    # a quad among the triangles: read by trimesh, which splits it
    square = box()
    v = square.vertices
    quads = [[0, 1, 2, 3], [4, 5, 6, 7]]
    ft = np.dtype([("n", "u1"), ("i", "<i4", (4,))])
    rows = np.zeros(2, ft)
    rows["n"], rows["i"] = 4, quads
    data = _ply(
        [("double", "x"), ("double", "y"), ("double", "z")],
        "property list uchar int vertex_indices",
        v.astype("<f8").tobytes(),
        rows.tobytes(),
        len(v),
        2,
    )
    assert binary_ply(data) is None
    path = tmp_path / "s.ply"
    path.write_bytes(mesh_bytes(icosphere(2), ".ply"))
    loaded = load_mesh(path)
    assert np.array_equal(loaded.mesh.vertices, icosphere(2).vertices)
    assert np.array_equal(loaded.mesh.faces, icosphere(2).faces)


# -- edges, bodies, repeats -----------------------------------------------------------------
def _reference_report(faces, n):
    """EdgeReport as it was first written: np.unique of lo * n + hi."""
    b = np.roll(faces, -1, axis=1)
    lo, hi = np.minimum(faces, b), np.maximum(faces, b)
    _, inverse, counts = np.unique((lo * n + hi).ravel(), return_inverse=True, return_counts=True)
    sign = np.where(faces < b, 1, -1).ravel()
    balance = np.bincount(inverse.ravel(), weights=sign, minlength=len(counts)).astype(int)
    return inverse.reshape(faces.shape), counts, balance


def _reference_labels(faces, edges):
    order = np.argsort(edges.ravel(), kind="stable")
    on_edge = np.repeat(np.arange(len(faces)), 3)[order]
    same = edges.ravel()[order][1:] == edges.ravel()[order][:-1]
    n = len(faces)
    g = sp.coo_matrix((np.ones(int(same.sum())), (on_edge[:-1][same], on_edge[1:][same])), (n, n))
    return connected_components(g, directed=False)[::-1]


def _messy_meshes():
    rng = np.random.default_rng(3)
    two = joined(icosphere(2), icosphere(1, center=(3.0, 0, 0)), box())
    # non-manifold: one face repeated, one flipped, a random triangle soup
    bad = np.concatenate([two.faces, two.faces[:5], two.faces[5:9, ::-1]])
    soup = rng.integers(0, 40, (300, 3))
    return [two.faces, bad, soup, rng.permutation(two.faces)]


@pytest.mark.parametrize("case", range(4))
def test_edge_report_and_body_labels_match_sorting(case):
    faces = _messy_meshes()[case]
    n = int(faces.max()) + 1
    report = EdgeReport.of(faces, n)
    inverse, counts, balance = _reference_report(faces, n)
    assert np.array_equal(report.edge_of_corner, inverse)
    assert np.array_equal(report.counts, counts) and np.array_equal(report.balance, balance)
    labels, count = body_labels(faces, report)
    ref_labels, ref_count = _reference_labels(faces, inverse)
    assert count == ref_count and np.array_equal(labels, ref_labels)
    closed = report.boundary == 0 and report.unbalanced == 0
    assert balanced(faces, n) == closed


def test_repeated_rows_are_never_missed():
    rng = np.random.default_rng(5)
    for _ in range(50):
        rows = rng.integers(0, 6, (rng.integers(1, 60), 3))
        exact = bool(np.any(group_rows(rows)[2] > 1))
        if exact:
            assert any_repeated_row(rows)
    rows = np.arange(30).reshape(10, 3)
    assert not any_repeated_row(rows) and not any_repeated_row(rows[:1])
    assert any_repeated_row(np.concatenate([rows, rows[3:4]]))


def test_weld_and_duplicates_fast_paths_keep_everything_in_order():
    mesh = icosphere(3)
    v, f = weld(mesh.vertices, mesh.faces)
    assert np.array_equal(v, mesh.vertices) and np.array_equal(f, mesh.faces)
    kept, dropped = drop_duplicates(mesh.faces)
    assert kept is mesh.faces and dropped == 0
    # an unused vertex in front: dropped, the others renumbered
    v2, f2 = weld(np.concatenate([[[9.0, 9, 9]], mesh.vertices]), mesh.faces + 1)
    assert np.array_equal(v2, mesh.vertices) and np.array_equal(f2, mesh.faces)


def test_tetra_volumes_are_face_volumes():
    mesh = joined(icosphere(3), box((2.0, 1.0, 0.5)))
    for origin in (None, np.array([0.3, -2.0, 5.0])):
        fast = tetra_volumes(mesh.vertices, mesh.faces, origin)
        slow = face_volumes(mesh.vertices, mesh.faces, origin)
        assert np.allclose(fast, slow, rtol=1e-13, atol=1e-16 * np.abs(slow).max())


# -- the pyramid knowing the bodies -----------------------------------------------------------
def test_pyramid_told_one_body_is_the_same(tmp_path):
    mesh = icosphere(5)
    told = build_pyramid(mesh, bodies=1)
    found = build_pyramid(mesh)
    assert [m.n_faces for m in told] == [m.n_faces for m in found]
    for a, b in zip(told, found):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
    path = tmp_path / "s.ply"
    path.write_bytes(mesh_bytes(mesh, ".ply"))
    levels = load_model(path).levels
    assert [m.n_faces for m in levels] == [m.n_faces for m in found]
    assert isinstance(levels[-1], TriMesh)
