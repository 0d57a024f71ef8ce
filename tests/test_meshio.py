"""Reading, cleaning, checking and writing mesh files (isochor.core.io.meshio)."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from isochor.core.errors import IsochorError
from isochor.core.io.meshio import load_mesh, mesh_bytes, save_mesh
from isochor.core.io.repair import EdgeReport, balanced, clean_closed_surface, count_bodies
from isochor.core.mesh import TriMesh
from isochor.core.scenario.problem import load_model
from isochor.core.volume import signed_volume
from tests.models import CLOSED, OPEN, REFUSED, box, icosphere, joined, model, trimesh_volume


def write_obj(path, mesh: TriMesh) -> None:
    """A plain OBJ written without isochor.core.io.meshio (so the reader is tested on its own)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces.tolist()]
    path.write_text("\n".join(lines) + "\n")


def volume(mesh: TriMesh) -> float:
    return signed_volume(mesh.vertices, mesh.faces)


# -- the shared models --------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(CLOSED))
def test_closed_models_load_unchanged_with_trimesh_volume(name):
    path = model(name)
    loaded = load_mesh(path)
    triangles, bodies = CLOSED[name]
    assert loaded.mesh.n_faces == triangles
    assert loaded.bodies == bodies
    assert loaded.warnings == []
    assert loaded.path == path
    assert loaded.volume > 0
    assert loaded.volume == pytest.approx(trimesh_volume(path), rel=1e-9)
    check = trimesh.Trimesh(loaded.mesh.vertices, loaded.mesh.faces, process=False)
    assert check.is_watertight and check.is_winding_consistent


def test_cow_keeps_its_pinched_vertex_and_vertex_order():
    path = model("cow.obj")
    loaded = load_mesh(path)
    raw = trimesh.load_mesh(str(path), process=False)
    # nothing to weld: same vertices in the same order, same triangles
    assert np.array_equal(loaded.mesh.vertices, raw.vertices)
    assert np.array_equal(loaded.mesh.faces, raw.faces)
    report = EdgeReport.of(loaded.mesh.faces, loaded.mesh.n_vertices)
    euler = loaded.mesh.n_vertices - len(report.counts) + loaded.mesh.n_faces
    assert euler == 1  # the pinched vertex (SOURCES.md): not a 2-manifold, still closed
    assert np.allclose(loaded.mesh.vertices[253], [-3.508, 1.700, 0.0], atol=1e-3)


def test_quads_rgb_and_missing_mtl_are_triangulated_and_welded():
    loaded = load_mesh(model("torus_knot_quads.obj"))
    assert loaded.mesh.n_faces == 2880 and loaded.mesh.n_vertices == 1440


def test_viewpoint_cow_polygons_are_triangulated():
    loaded = load_mesh(model("cow_viewpoint_polygons.obj"))
    assert loaded.mesh.n_faces == 5804 and loaded.mesh.n_vertices == 2903
    assert loaded.volume == pytest.approx(53.4868, rel=1e-5)


def test_inconsistent_winding_is_repaired_to_the_cows_volume():
    cow = load_mesh(model("cow.obj"))
    patched = load_mesh(model("cow_flipped_patch.obj"))
    assert any("Inconsistent winding" in w and "300" in w for w in patched.warnings)
    assert patched.volume == pytest.approx(cow.volume, rel=1e-12)
    assert np.array_equal(np.sort(patched.mesh.faces, axis=1), np.sort(cow.mesh.faces, axis=1))
    assert np.array_equal(patched.mesh.faces, cow.mesh.faces)  # same winding, face by face


def test_multibody_stl_with_inconsistent_winding_keeps_both_bodies():
    path = model("multibody_inconsistent_winding.stl")
    loaded = load_mesh(path)
    assert loaded.bodies == 2
    assert any("winding" in w for w in loaded.warnings)
    # independent check: both bodies are (nearly) convex; sum of their hull volumes
    raw = trimesh.load_mesh(str(path), process=False)
    raw.merge_vertices()
    hulls = sum(ConvexHull(np.asarray(b.vertices)).volume for b in raw.split(only_watertight=False))
    assert loaded.volume == pytest.approx(hulls, rel=3e-4)


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_surfaces_with_no_solid_are_refused_saying_why(name):
    with pytest.raises(IsochorError) as err:
        load_mesh(model(name))
    msg = str(err.value)
    assert msg.startswith(f"{name}: ") and REFUSED[name] in msg
    assert "\n" not in msg


@pytest.mark.parametrize("name", sorted(OPEN))
def test_open_surfaces_open_capped_or_kept_apart(name):
    boundary, non_manifold = OPEN[name]
    loaded = load_mesh(model(name))
    mesh = loaded.mesh
    assert mesh.cap_faces == boundary  # one cap triangle per boundary edge
    words = " ".join(loaded.warnings)
    if boundary:
        assert f"Capped {mesh.cap_vertices} hole(s)" in words
    else:
        assert "apart" in words
    # closed, consistently wound: every directed edge run once each way
    assert balanced(mesh.faces, mesh.n_vertices)
    assert loaded.volume > 0


# -- synthetic inputs ---------------------------------------------------------------------
def blender_ply(path, vertices, polygons) -> int:
    """A binary PLY laid out as Blender writes one (normals and UVs per vertex, one
    ``uchar uint`` list of mixed triangles and quads), written by this test; returns where
    the faces start."""
    import struct

    head = (
        "ply\nformat binary_little_endian 1.0\ncomment Created in Blender version 5.0.1\n"
        f"element vertex {len(vertices)}\n"
        + "".join(f"property float {p}\n" for p in ("x", "y", "z", "nx", "ny", "nz", "s", "t"))
        + f"element face {len(polygons)}\nproperty list uchar uint vertex_indices\nend_header\n"
    ).encode()
    rows = b"".join(struct.pack("<8f", *v, 0, 0, 1, v[0], v[1]) for v in vertices)
    faces = b"".join(struct.pack(f"<B{len(f)}I", len(f), *f) for f in polygons)
    path.write_bytes(head + rows + faces)
    return len(head) + len(rows)


def test_blenders_ply_of_quads_and_triangles_opens_like_suzanne(tmp_path):
    """Blender's PLY (Suzanne's: quads and triangles mixed, which trimesh's reader refuses
    as "unexpected length"): an open box of quads (her head, open at a socket), an open
    pyramid (an eye open at the back) and a closed tetrahedron through the box's hole,
    one object: three bodies, two holes capped, the closed-form volumes."""
    box_v = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
    box_f = [(0, 2, 3, 1), (0, 1, 5, 4), (1, 3, 7, 5), (3, 2, 6, 7), (2, 0, 4, 6)]  # no top
    eye_v = [(2, 0, 0), (3, 0, 0), (3, 1, 0), (2, 1, 0), (2.5, 0.5, 1)]
    eye_f = [(8, 9, 12), (9, 10, 12), (10, 11, 12), (11, 8, 12)]  # no base
    tet_v = [(0.375, 0.375, 0.75), (0.625, 0.375, 0.75), (0.5, 0.625, 0.75), (0.5, 0.5, 1.25)]
    tet_f = [(13, 15, 14), (13, 14, 16), (14, 15, 16), (15, 13, 16)]
    path = tmp_path / "suzanne.ply"
    start = blender_ply(path, box_v + eye_v + tet_v, box_f + eye_f + tet_f)
    loaded = load_mesh(path)
    tet = 0.25 * 0.25 / 2 * 0.5 / 3  # (float32-exact corners)
    assert (loaded.bodies, loaded.mesh.cap_vertices, loaded.mesh.own_faces) == (3, 2, 18)
    assert loaded.volume == pytest.approx(1 + 1 / 3 + tet, rel=1e-12)
    assert "overlap" in " ".join(loaded.warnings)  # the tetrahedron through the box's hole
    # solved and written back: the file's own faces, byte for byte, its vertices moved
    import isochor

    session = isochor.load(path, lattice=(3, 3, 3))
    for i in range(3):
        for j in range(3):
            session.move((i, j, 2), by=(0, 0, -0.2))
    assert session.solve().converged
    out = tmp_path / "out.ply"
    session.export(out)
    written = out.read_bytes()
    assert written[start:] == path.read_bytes()[start:]
    # the capped volume kept, measured independently: the written positions (float32), each
    # polygon a fan, each hole closed by a fan to its rest centre moved by the lattice (the
    # cap the solve keeps: a cap re-made over the moved rim would bend differently)
    from tests.test_caps import capped_volume

    rest = np.array(box_v + eye_v + tet_v, dtype=np.float64)
    rows = np.frombuffer(written[start - 32 * len(rest) : start], dtype="<f4").reshape(-1, 8)
    tris = [(f[0], f[i], f[i + 1]) for f in box_f + eye_f + tet_f for i in range(1, len(f) - 1)]

    def apex(loop):
        return session.lattice.deform(rest[loop].mean(axis=0)[None], session.nodes)[0]

    kept = capped_volume(rows[:, :3].astype(np.float64), np.array(tris), apex)
    assert kept == pytest.approx(loaded.volume, rel=5e-4)


def test_inward_facing_mesh_is_flipped_with_a_warning(tmp_path):
    sphere = icosphere(3)
    write_obj(tmp_path / "inward.obj", TriMesh(sphere.vertices, sphere.faces[:, ::-1]))
    loaded = load_mesh(tmp_path / "inward.obj")
    assert any("inward" in w for w in loaded.warnings)
    assert loaded.volume == pytest.approx(volume(sphere), rel=1e-12)
    assert np.array_equal(loaded.mesh.faces, sphere.faces)


def test_bodies_are_oriented_one_by_one_and_volumes_add(tmp_path):
    a = icosphere(3, 1.0)
    b = icosphere(2, 0.5, center=(5, 0, 0))
    c = icosphere(2, 0.3, center=(0, 5, 0))
    faces = b.faces.copy()
    faces[:10] = faces[:10, ::-1]  # a patch wound the wrong way
    mixed = joined(TriMesh(a.vertices, a.faces[:, ::-1]), TriMesh(b.vertices, faces), c)
    write_obj(tmp_path / "three.obj", mixed)
    loaded = load_mesh(tmp_path / "three.obj")
    assert loaded.bodies == 3
    assert loaded.volume == pytest.approx(volume(a) + volume(b) + volume(c), rel=1e-12)
    assert any("winding" in w for w in loaded.warnings)
    assert any("1 of 3 bodies" in w for w in loaded.warnings)


def test_a_cavity_is_subtracted_not_added(tmp_path):
    outer, inner = icosphere(3, 1.0), icosphere(3, 0.5, center=(0.1, 0, 0))
    # both wound outward, as a careless exporter writes a hollow ball
    write_obj(tmp_path / "hollow.obj", joined(outer, inner))
    loaded = load_mesh(tmp_path / "hollow.obj")
    assert loaded.bodies == 2
    assert loaded.volume == pytest.approx(volume(outer) - volume(inner), rel=1e-12)
    assert len(loaded.warnings) == 1
    assert "turned to face inward" in loaded.warnings[0]  # not "outward": it is a cavity


def test_overlapping_bodies_load_with_a_warning_that_the_volume_counts_twice(tmp_path):
    a, b = icosphere(3, 1.0), icosphere(3, 1.0, center=(1.2, 0, 0))
    write_obj(tmp_path / "overlap.obj", joined(a, b))
    loaded = load_mesh(tmp_path / "overlap.obj")
    assert loaded.bodies == 2
    assert loaded.volume == pytest.approx(volume(a) + volume(b), rel=1e-12)
    assert [w for w in loaded.warnings if "overlap" in w and "twice" in w]
    # apart, nested or crossing: only the crossing pair is reported
    crossing = joined(
        TriMesh(box((4, 1, 1)).vertices - (2, 0.5, 0.5), box().faces),
        TriMesh(box((1, 4, 1)).vertices - (0.5, 2, 0.5), box().faces),  # a plus sign
        icosphere(2, 0.5, center=(9, 0, 0)),
    )
    write_obj(tmp_path / "plus.obj", crossing)
    words = [w for w in load_mesh(tmp_path / "plus.obj").warnings if "overlap" in w]
    assert words == [
        "Bodies 1 and 2 (of 3, in file order) overlap: the volume counts the part they share twice."
    ]
    write_obj(tmp_path / "apart.obj", joined(a, icosphere(3, 1.0, center=(2.5, 0, 0))))
    assert load_mesh(tmp_path / "apart.obj").warnings == []


@pytest.mark.parametrize("far", [1e4, 1e6, 1e9, 1e12])
def test_one_far_vertex_is_neither_flat_nor_open_but_said(tmp_path, far):
    sphere = icosphere(3)
    vertices = sphere.vertices.copy()
    vertices[5] *= far  # a spike: still closed, still a solid
    write_obj(tmp_path / "spike.obj", TriMesh(vertices, sphere.faces))
    if far >= 1e9:  # measured from the lattice's middle, the volume drowns in rounding
        with pytest.raises(IsochorError, match="cannot be measured precisely") as err:
            load_mesh(tmp_path / "spike.obj")
        assert "flat" not in str(err.value) and "closed" not in str(err.value)
        return
    loaded = load_mesh(tmp_path / "spike.obj")
    assert loaded.mesh.n_faces == sphere.n_faces  # nothing welded away
    assert loaded.volume == pytest.approx(signed_volume(vertices, sphere.faces), rel=1e-9)
    assert [w for w in loaded.warnings if "1 vertex(es) lie far from the rest" in w]


def test_files_that_cannot_be_of_their_format_fail_at_once(tmp_path, monkeypatch):
    import isochor.core.io.meshio as meshio

    for name in ("zeros.ply", "zeros.stl", "zeros.obj", "zeros.off"):
        with open(tmp_path / name, "wb") as fh:
            fh.truncate(50 * 2**20)  # sparse: 50 MB of zero bytes
        with pytest.raises(IsochorError, match=f"{name}: not a") as err:
            load_mesh(tmp_path / name)
        assert "\n" not in str(err.value)
    monkeypatch.setattr(meshio, "MAX_MODEL_BYTES", 2**20)
    with pytest.raises(
        IsochorError, match=r"zeros.ply: 50.0 MB is more than Isochor reads as a model \(1.0 MB\)"
    ):
        load_mesh(tmp_path / "zeros.ply")


def test_a_coordinate_beyond_any_model_is_refused(tmp_path):
    sphere = icosphere(1)
    vertices = sphere.vertices.copy()
    vertices[0, 0] = 1e300
    write_obj(tmp_path / "huge.obj", TriMesh(vertices, sphere.faces))
    with pytest.raises(IsochorError, match=r"huge.obj: a vertex coordinate of 1e\+300 is beyond"):
        load_mesh(tmp_path / "huge.obj")


def test_degenerate_and_duplicate_triangles_are_dropped(tmp_path):
    s = icosphere(2)
    f = s.faces
    extra = np.array([f[0], f[1][::-1], f[1], f[2], f[2][::-1], [0, 0, 5]])
    # f0 twice (same way): keep one. f1 reversed + f1 + f1: net one copy kept. f2 + reversed
    # f2 + f2: net one. [0, 0, 5]: degenerate.
    write_obj(tmp_path / "dups.obj", TriMesh(s.vertices, np.concatenate([f, extra])))
    loaded = load_mesh(tmp_path / "dups.obj")
    assert loaded.mesh.n_faces == s.n_faces
    assert loaded.volume == pytest.approx(volume(s), rel=1e-12)
    assert any("degenerate" in w for w in loaded.warnings)
    assert any("5 duplicate" in w for w in loaded.warnings)


def test_an_internal_double_wall_cancels(tmp_path):
    s = icosphere(2)
    wall = np.array([[0, 1, 2], [0, 2, 1]])  # the same triangle both ways
    write_obj(tmp_path / "wall.obj", TriMesh(s.vertices, np.concatenate([s.faces, wall])))
    loaded = load_mesh(tmp_path / "wall.obj")
    assert loaded.mesh.n_faces == s.n_faces


def test_weld_is_relative_to_the_model_size(tmp_path):
    s = icosphere(2)
    # an STL repeats every corner; at any scale it must weld back to the same sphere
    for scale in (1e-6, 1.0, 1e6):
        mesh = TriMesh(s.vertices * scale, s.faces)
        save_mesh(tmp_path / "s.stl", mesh)
        loaded = load_mesh(tmp_path / "s.stl")
        assert loaded.mesh.n_vertices == s.n_vertices
        assert loaded.volume == pytest.approx(volume(s) * scale**3, rel=1e-5)


def test_non_orientable_surface_is_refused():
    # a Klein bottle grid: closed, every edge on two triangles, no consistent winding
    n, m = 8, 6

    def vid(i, j):
        if i == n:
            i, j = 0, (m - j) % m
        return i * m + (j % m)

    faces = []
    for i in range(n):
        for j in range(m):
            a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
            faces += [(a, b, c), (a, c, d)]
    verts = np.random.default_rng(1).normal(size=(n * m, 3))
    with pytest.raises(IsochorError, match="cannot be oriented"):
        clean_closed_surface(verts, np.array(faces))


def test_flat_closed_surface_is_refused():
    # a tetrahedron with its four corners in one plane: closed, consistently wound, no
    # duplicate triangles (nothing cancels), so the flatness check itself must refuse it
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 0.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with pytest.raises(IsochorError, match="flat"):
        clean_closed_surface(verts, faces)


# -- files that are not meshes ------------------------------------------------------------
def _bad_files(tmp_path):
    sphere = icosphere(2)
    good_ply = mesh_bytes(sphere, ".ply")
    good_obj = mesh_bytes(sphere, ".obj")
    rng = np.random.default_rng(0)
    return {
        "empty.obj": b"",
        "blank.stl": b"  \n\n",
        "garbage.obj": b"hello, this is not a mesh\n",
        "garbage.off": b"nonsense\n",
        "garbage.ply": b"not a ply at all\n",
        "random.stl": rng.bytes(3000),
        "random.ply": rng.bytes(3000),
        "truncated.ply": good_ply[: len(good_ply) // 2],
        "truncated.obj": good_obj[: len(good_obj) * 2 // 3],
        "truncated.off": b"OFF\n4 4 0\n0 0 0\n1 0 0\n",
        "badindex.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        "nan.obj": b"v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n",
        "points.ply": b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
        b"property float y\nproperty float z\nend_header\n0 0 0\n1 1 1\n",
        "model.xyz": b"0 0 0\n",
        "model.glb": b"glTF",
        "noextension": b"v 0 0 0\n",
    }


def test_every_bad_file_gives_one_error_naming_it(tmp_path):
    for name, data in _bad_files(tmp_path).items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(IsochorError) as err:
            load_mesh(tmp_path / name)
        msg = str(err.value)
        assert name in msg, msg
        assert "\n" not in msg and len(msg) < 300, msg


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(IsochorError, match="nothing.obj: no such model file"):
        load_mesh(tmp_path / "nothing.obj")
    (tmp_path / "dir.obj").mkdir()
    with pytest.raises(IsochorError, match="not a file"):
        load_mesh(tmp_path / "dir.obj")


# -- writing ------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl", ".OBJ", ".off", ".glb", ".gltf"])
def test_save_then_load_gives_the_same_mesh(tmp_path, suffix):
    mesh = icosphere(3, 1.7, center=(1e3, -2.5, 1 / 3))
    path = tmp_path / f"out{suffix}"
    save_mesh(path, mesh)
    back = trimesh.load(str(path), process=False, force="mesh")
    back.merge_vertices()
    assert len(back.faces) == mesh.n_faces
    assert back.is_watertight and back.is_winding_consistent
    exact = suffix.lower() not in (".stl", ".glb", ".gltf")  # float32 by their definitions
    assert back.volume == pytest.approx(volume(mesh), rel=1e-12 if exact else 1e-5)
    ours = load_mesh(path).mesh
    if exact:
        assert np.array_equal(ours.vertices, mesh.vertices)
        assert np.array_equal(ours.faces, mesh.faces)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


def test_save_refuses_unknown_formats_and_missing_folders(tmp_path):
    mesh = icosphere(1)
    with pytest.raises(IsochorError, match="OBJ, PLY, STL, OFF, GLB, GLTF"):
        save_mesh(tmp_path / "out.3ds", mesh)
    with pytest.raises(IsochorError, match="does not exist"):
        save_mesh(tmp_path / "no" / "such" / "out.ply", mesh)
    assert list(tmp_path.iterdir()) == []


def test_save_is_atomic_and_keeps_normal_permissions(tmp_path, monkeypatch):
    path = tmp_path / "out.ply"
    save_mesh(path, icosphere(1))
    mode = stat.S_IMODE(os.stat(path).st_mode)
    assert mode & stat.S_IRGRP or os.name == "nt"  # not the 0600 of a temporary file
    before = path.read_bytes()

    import isochor.core.scenario.document

    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(isochor.core.io.atomic.os, "replace", boom)
    with pytest.raises(KeyboardInterrupt):
        save_mesh(path, icosphere(2))
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["out.ply"]


def test_load_model_gives_a_pyramid_ending_with_the_full_mesh(tmp_path):
    sphere = icosphere(4)
    save_mesh(tmp_path / "s.ply", sphere)
    model_ = load_model(tmp_path / "s.ply")
    levels, warns = list(model_.levels), list(model_.warnings)
    assert warns == []
    assert np.array_equal(levels[-1].vertices, sphere.vertices)
    assert [m.n_faces for m in levels][-1] == sphere.n_faces
    assert len(levels) >= 3 and levels[0].n_faces < 100
    assert count_bodies(levels[0]) == 1
