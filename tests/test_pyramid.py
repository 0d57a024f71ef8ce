"""The level pyramid (isochor.core.solve.pyramid): QEM levels, each one checked."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

import isochor.core.solve.pyramid
from isochor.core.io.meshio import load_mesh
from isochor.core.io.repair import EdgeReport, count_bodies
from isochor.core.mesh import TriMesh
from isochor.core.solve.pyramid import MAX_OUTSIDE, build_pyramid, volume_tolerance
from isochor.core.volume import signed_volume
from tests.models import CLOSED, club, icosphere, joined, model, uv_sphere


def volume(mesh: TriMesh) -> float:
    return signed_volume(mesh.vertices, mesh.faces)


def assert_good_pyramid(levels: list[TriMesh], full: TriMesh, min_faces: int = 16) -> None:
    """Every level closed, near the full volume, inside the box; about 4x steps."""
    assert levels[-1] is full
    counts = [m.n_faces for m in levels]
    assert counts == sorted(counts) and len(set(counts)) == len(counts)
    for coarse, fine in pairwise(counts):
        assert 2.0 <= fine / coarse <= 5.0, counts
    assert counts[0] >= min_faces
    lo, hi = full.vertices.min(axis=0), full.vertices.max(axis=0)
    slack = MAX_OUTSIDE * full.size
    v_full = volume(full)
    for m in levels:
        report = EdgeReport.of(m.faces, m.n_vertices)
        assert report.boundary == 0 and report.unbalanced == 0
        assert abs(volume(m) / v_full - 1) <= volume_tolerance(m.n_faces)
        assert np.all(m.vertices >= lo - slack) and np.all(m.vertices <= hi + slack)
        assert count_bodies(m) == count_bodies(full)
        assert len(np.unique(m.faces)) == m.n_vertices  # no unused vertex


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_pyramids_of_the_shared_models(name):
    mesh = load_mesh(model(name)).mesh
    levels = build_pyramid(mesh)
    assert_good_pyramid(levels, mesh)
    assert len(levels) >= 3
    assert levels[0].n_faces <= 200  # the multi-level solve starts from a coarse level


def test_cow_pyramid_like_the_paper():
    mesh = load_mesh(model("cow.obj")).mesh
    counts = [m.n_faces for m in build_pyramid(mesh)]
    assert counts[-1] == 5804 and len(counts) == 5 and counts[0] < 64


@pytest.mark.parametrize(
    "make",
    [lambda: icosphere(5), lambda: club(5), lambda: uv_sphere(48, 96)],
    ids=["icosphere", "club", "uv-sphere"],
)
def test_pyramids_of_synthetic_shapes(make):
    mesh = make()
    levels = build_pyramid(mesh)
    assert_good_pyramid(levels, mesh)
    assert levels[0].n_faces < 64


def test_ratio_and_min_faces_are_honoured():
    mesh = icosphere(5)  # 20480 triangles
    levels = build_pyramid(mesh, min_faces=500, ratio=2)
    counts = [m.n_faces for m in levels]
    assert counts[0] >= 500 and counts[0] < 1000 * 1.1
    assert all(1.6 <= b / a <= 2.5 for a, b in pairwise(counts))


def test_small_body_survives_every_level():
    big, small = icosphere(5, 1.0), icosphere(2, 0.1, center=(3, 0, 0))
    mesh = joined(big, small)
    levels = build_pyramid(mesh)
    assert len(levels) >= 3
    assert_good_pyramid(levels, mesh)  # includes: two bodies on every level
    assert all(abs(volume(m) / volume(mesh) - 1) < 0.25 for m in levels)


def test_many_tiny_bodies_give_a_single_level():
    tets = [icosphere(0, 0.1, center=(i, 0, 0)) for i in range(10)]  # 10 x 20 triangles
    mesh = joined(*tets)
    assert build_pyramid(mesh) == [mesh]


def test_tiny_mesh_is_its_own_pyramid():
    mesh = icosphere(0)
    assert build_pyramid(mesh) == [mesh]


def test_broken_simplifier_output_is_never_used(monkeypatch):
    mesh = icosphere(4)

    def shrunk(m, target):  # a simplifier that folds: a right mesh at a third of the volume
        return TriMesh(m.vertices * 0.7, m.faces)

    def holed(m, target):
        return TriMesh(m.vertices, m.faces[1:])

    def outside(m, target):
        v = np.array(m.vertices)
        v[0] *= 1.5
        return TriMesh(v, m.faces)

    for bad, why in ((shrunk, "volume off"), (holed, "not closed"), (outside, "outside")):
        monkeypatch.setattr(isochor.core.solve.pyramid, "simplify", bad)
        notes: list[str] = []
        assert build_pyramid(mesh, notes=notes) == [mesh]
        assert len(notes) == 3 and all(why in n for n in notes), notes


def test_a_failed_level_is_retried_with_a_larger_target(monkeypatch):
    mesh = icosphere(4)  # 5120
    real = isochor.core.solve.pyramid.simplify
    calls = []

    def first_fails(m, target):
        calls.append(target)
        out = real(m, target)
        return TriMesh(out.vertices * 0.5, out.faces) if len(calls) == 1 else out

    monkeypatch.setattr(isochor.core.solve.pyramid, "simplify", first_fails)
    notes: list[str] = []
    levels = build_pyramid(mesh, notes=notes)
    assert calls[:2] == [1280, 1600]
    assert levels[-2].n_faces == 1600 and len(notes) == 1
    assert_good_pyramid(levels, mesh)


def test_pyramid_is_deterministic_and_scale_free():
    mesh = load_mesh(model("cow.obj")).mesh
    a = build_pyramid(mesh)
    b = build_pyramid(mesh)
    scaled = build_pyramid(TriMesh(mesh.vertices * 1000.0, mesh.faces))
    assert [m.n_faces for m in a] == [m.n_faces for m in b] == [m.n_faces for m in scaled]
    for x, y, z in zip(a, b, scaled):
        assert np.array_equal(x.vertices, y.vertices) and np.array_equal(x.faces, y.faces)
        assert np.array_equal(x.faces, z.faces)
        assert np.allclose(x.vertices * 1000.0, z.vertices, rtol=0, atol=1e-9 * 1000 * mesh.size)


def test_volume_tolerance_bounds():
    assert volume_tolerance(100_000) == 0.05
    assert volume_tolerance(400) == pytest.approx(0.1)
    assert volume_tolerance(20) == 0.25
