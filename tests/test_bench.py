"""The benchmark's building blocks on tiny sizes, and the fast evaluation against the
straightforward per-face formula. No timing is asserted: times only have to be positive."""

import itertools
import math

import numpy as np
import pytest

from core import bench
from core import lattice as lat_mod
from core import volume as vol_mod
from core.lattice import Lattice
from core.mesh import TriMesh
from core.shapes import sphere_levels, torus
from core.volume import VolumeOperator, signed_volume


@pytest.fixture(scope="module")
def small_case():
    case = bench.example_case("torus-compression")
    case.levels = case.levels[:4]  # 16 .. 1024 triangles
    return case


def test_table1_rows_are_sane(small_case):
    rows = bench.table1_rows(small_case, repeats=1, log=lambda *a: None)
    rows.append(bench.table1_row(small_case, 1, "paper size", 2))  # cut at 256 triangles
    assert rows[0].variant.startswith("estimate") and rows[-1].variant == "paper size"
    for r in rows:
        assert r.t1.median > 0 and r.t2.median > 0 and r.t2_cold > 0
        assert math.isfinite(r.speedup) and r.speedup > 0
        assert r.converged1 and r.converged2
        assert abs(r.dv_full) <= 5e-4 and abs(r.dv_terminal) <= 5e-4 and abs(r.dv_t1) <= 5e-4
        assert r.terminal_tri in [m.n_faces for m in small_case.levels]
        assert r.steps1 > 0 and r.steps2 > 0
    # a paper-size row solves every level of the cut pyramid
    assert rows[-1].terminal_tri == rows[-1].finest_tri == 256

    t2 = bench.table2(rows[0])
    ks = [k for k, *_ in t2]
    assert ks == list(range(ks[0], ks[0] + len(ks)))
    cum = [tc for *_, tc in t2]
    assert all(b >= a > 0 for a, b in itertools.pairwise(cum))
    assert all(steps >= 0 and dx >= 0 for _, _, dx, steps, _, _ in t2)

    run = bench.median_run(rows[0].t2_runs)
    err = bench.node_error(run, small_case.size)
    assert len(err) == len(run.times) > 2 and err[-1] < 1e-12 and err.max() > 1e-3
    assert np.all(np.diff(run.times) >= 0) and 0 < run.first_record <= run.wall

    targets = bench.evaluate_targets(rows, [], None, {"torus": (run.first_record, 0.001)})
    assert all(t.met in (True, False, None) and t.measured for t in targets)
    text = bench.render(bench.environment(), True, 1, rows, t2, None, [], [], None,
                        {"torus": (0.01, 0.001)}, targets, [], ["a note"], "")
    assert "## Table 1" in text and "## Table 2" in text and bench.KEEP_MARKER in text


def test_profile_counts_the_work_of_every_level(small_case):
    rows, total, _ = bench.profile_solve(small_case)
    assert total > 0 and len(rows) >= 1
    for p in rows:
        assert p.steps <= p.evals and p.eval_s > 0 and p.time_s > 0


@pytest.mark.parametrize("shape", [(3, 3, 3), (5, 2, 2)])
def test_scale_row_agrees_with_the_reference(shape, monkeypatch):
    mesh = torus(16, 8)
    row = bench.scale_row(mesh, shape, repeats=1)  # raises if the numbers disagree
    assert row.triangles == 256 and row.t_eval.median > 0 and row.t_reference.median > 0
    # the factored basis and the blocked volume loop, with blocks much smaller than the mesh
    monkeypatch.setattr(lat_mod, "DENSE_LIMIT", 0)
    monkeypatch.setattr(lat_mod, "BASIS_BLOCK", 37)
    monkeypatch.setattr(vol_mod, "BLOCK", 29)
    monkeypatch.setattr(vol_mod, "SMALL", 0)
    row = bench.scale_row(mesh, shape, repeats=1)
    assert row.form == "factored"


def _per_face(vertices, faces, center):
    v = vertices - center
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    grad = np.zeros_like(v)
    np.add.at(grad, faces[:, 0], np.cross(b, c) / 6)
    np.add.at(grad, faces[:, 1], np.cross(c, a) / 6)
    np.add.at(grad, faces[:, 2], np.cross(a, b) / 6)
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6), grad


def _awkward_meshes():
    rng = np.random.default_rng(7)
    sphere = sphere_levels(3)[-1]
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    yield "closed", sphere.vertices, sphere.faces
    yield "open (a hole)", sphere.vertices, sphere.faces[5:]
    flipped = sphere.faces.copy()
    flipped[::7] = flipped[::7, ::-1]
    yield "inconsistent winding", sphere.vertices, flipped
    # two tetrahedra sharing an edge: four faces on that edge; plus an unused vertex
    v = np.vstack([rng.normal(size=(4, 3)), rng.normal(size=(3, 3)) + 2.0, [[9, 9, 9]]])
    t2 = np.array([[0, 4, 1], [0, 1, 5], [1, 4, 5], [0, 5, 4]])  # shares vertices 0, 1
    yield "non-manifold edge", v, np.vstack([tet, t2])
    yield "degenerate and duplicate faces", sphere.vertices, np.vstack(
        [sphere.faces, sphere.faces[:3], [[0, 0, 1], [2, 3, 3]]])


@pytest.mark.parametrize("small", [True, False], ids=["whole-array", "blocked"])
def test_volume_operator_equals_the_per_face_formula_on_any_triangles(small, monkeypatch):
    if not small:
        monkeypatch.setattr(vol_mod, "SMALL", 0)
        monkeypatch.setattr(vol_mod, "BLOCK", 17)
    rng = np.random.default_rng(3)
    for name, verts, faces in _awkward_meshes():
        verts = verts + rng.normal(scale=0.01, size=verts.shape)
        center = rng.normal(size=3)
        op = VolumeOperator(faces, len(verts))
        v_ref, g_ref = _per_face(verts, faces, center)
        for layout in (np.ascontiguousarray(verts), np.asfortranarray(verts)):
            v, g = op.value_and_gradient(layout, center)
            assert v == pytest.approx(v_ref, rel=1e-12, abs=1e-14), name
            assert np.allclose(g, g_ref, rtol=1e-12, atol=1e-14), name
            assert op(layout, center) == pytest.approx(v_ref, rel=1e-12, abs=1e-14), name
        v_mean, _ = _per_face(verts, faces, verts.mean(axis=0))
        assert signed_volume(verts, faces) == pytest.approx(v_mean, rel=1e-12, abs=1e-14)


def test_volume_operator_with_more_than_a_million_vertices():
    """Above 2**20 vertices the edge key does not pack into 64 bits: the argsort path."""
    sphere = sphere_levels(2)[-1]
    n = (1 << 21) + 3
    verts = np.zeros((n, 3))
    verts[-len(sphere.vertices):] = sphere.vertices + 0.1
    faces = sphere.faces + (n - len(sphere.vertices))
    op = VolumeOperator(faces, n)
    v, g = op.value_and_gradient(verts)
    v_ref, g_ref = _per_face(verts, faces, np.zeros(3))
    assert v == pytest.approx(v_ref, rel=1e-12)
    assert np.allclose(g, g_ref, rtol=1e-12, atol=1e-14)


def test_volume_operator_refuses_indices_out_of_range():
    with pytest.raises(ValueError, match="face indices"):
        VolumeOperator(np.array([[0, 1, 5]]), 3)
    op = VolumeOperator(np.zeros((0, 3), dtype=int), 4)
    v, g = op.value_and_gradient(np.ones((4, 3)))
    assert v == 0.0 and g.shape == (4, 3) and not g.any()


def test_basis_output_layout_and_values(monkeypatch):
    rng = np.random.default_rng(4)
    pts = rng.uniform(size=(300, 3))
    lat = Lattice.around(pts, (4, 3, 5))
    nodes = lat.rest_nodes + rng.normal(scale=0.05, size=(lat.n_nodes, 3))
    g = rng.normal(size=(300, 3))
    dense = lat.basis(pts)
    monkeypatch.setattr(lat_mod, "DENSE_LIMIT", 0)
    monkeypatch.setattr(lat_mod, "BASIS_BLOCK", 64)
    factored = lat.basis(pts)
    for b in (dense, factored):
        out = b.apply(nodes)
        assert out.shape == (300, 3) and out.T.flags.c_contiguous  # coordinate-major rows
        assert np.allclose(out, dense.dense @ nodes, atol=1e-12)
        for gl in (g, np.asfortranarray(g)):
            tr = b.apply_transpose(gl)
            assert tr.shape == (lat.n_nodes, 3) and tr.flags.c_contiguous
            assert np.allclose(tr, dense.dense.T @ g, atol=1e-12)


def test_armadillo_bend_pins_one_end_and_turns_the_other():
    levels = [TriMesh(*_box())]
    lattice, nodes, fixed = bench.armadillo_bend(levels, shape=(3, 5, 3), angle_deg=30)
    grid = lattice.grid_parameters()
    assert fixed.sum() == 18 and np.all(fixed == np.isin(grid[:, 1], (0.0, 1.0)))
    moved = ~np.all(np.isclose(nodes, lattice.rest_nodes), axis=1)
    assert np.all(moved == np.isclose(grid[:, 1], 1.0))


def _box():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 3, 0], [0, 3, 0],
                  [0, 0, 2], [1, 0, 2], [1, 3, 2], [0, 3, 2]], dtype=float)
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, f
