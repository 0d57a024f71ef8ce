"""Lattice: Bernstein basis, frame, node order, deform, factored basis."""

import numpy as np
import pytest

from isochor.core import lattice as lat_mod
from isochor.core.errors import IsochorError
from isochor.core.lattice import Lattice, bernstein


def test_bernstein_partition_of_unity_and_endpoints():
    t = np.linspace(0, 1, 11)
    for n in range(1, 10):
        b = bernstein(n, t)
        assert np.allclose(b.sum(axis=1), 1.0)
        assert np.allclose(b[0], np.eye(n + 1)[0]) and np.allclose(b[-1], np.eye(n + 1)[-1])


def test_node_order_is_i_slowest_k_fastest():
    lat = Lattice((4, 3, 2), (1.0, 2.0, 3.0), np.diag([3.0, 2.0, 1.0]))
    rest = lat.rest_nodes
    assert lat.index(0, 0, 1) == 1 and lat.index(0, 1, 0) == 2 and lat.index(1, 0, 0) == 6
    assert lat.ijk(lat.index(3, 2, 1)) == (3, 2, 1)
    assert np.allclose(rest[lat.index(1, 0, 0)], (2.0, 2.0, 3.0))
    assert np.allclose(rest[lat.index(0, 0, 1)], (1.0, 2.0, 4.0))
    with pytest.raises(IndexError):
        lat.index(4, 0, 0)


@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 3, 3), (5, 2, 2), (10, 4, 7)])
def test_rest_lattice_is_identity_and_points_inside(shape):
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(200, 3)) * (3.0, 1.0, 0.2) + 50.0
    lat = Lattice.around(pts, shape, padding=0.05)
    assert lat.contains(pts).all()
    uvw = lat.to_parameters(pts)
    assert uvw.min() > 0 and uvw.max() < 1  # strictly inside
    assert np.allclose(lat.deform(pts, lat.rest_nodes), pts, atol=1e-9)


def test_deform_matches_explicit_triple_sum_for_a_skewed_frame():
    rng = np.random.default_rng(2)
    axes = np.array([[2.0, 0.3, 0.0], [0.1, 1.5, 0.2], [0.0, -0.4, 1.0]])
    lat = Lattice((3, 4, 2), (0.5, -1.0, 2.0), axes)
    nodes = lat.rest_nodes + rng.normal(scale=0.3, size=(lat.n_nodes, 3))
    uvw = rng.uniform(size=(7, 3))
    pts = lat.origin + uvw @ axes
    expected = np.zeros((7, 3))
    for r in range(lat.n_nodes):
        i, j, k = lat.ijk(r)
        w = (
            bernstein(2, uvw[:, 0])[:, i]
            * bernstein(3, uvw[:, 1])[:, j]
            * bernstein(1, uvw[:, 2])[:, k]
        )
        expected += w[:, None] * nodes[r]
    assert np.allclose(lat.deform(pts, nodes), expected, atol=1e-12)


def test_factored_basis_equals_dense_and_uses_less_memory(monkeypatch):
    rng = np.random.default_rng(3)
    pts = rng.uniform(size=(5000, 3))
    lat = Lattice.around(pts, (5, 5, 5))
    nodes = lat.rest_nodes + rng.normal(scale=0.05, size=(125, 3))
    g = rng.normal(size=(5000, 3))
    dense = lat.point_basis(pts)
    monkeypatch.setattr(lat_mod, "DENSE_LIMIT", 0)
    factored = lat.point_basis(pts)
    assert dense.dense is not None and factored.dense is None
    assert np.allclose(factored.apply(nodes), dense.apply(nodes), atol=1e-12)
    assert np.allclose(factored.apply_transpose(g), dense.apply_transpose(g), atol=1e-10)
    # 25 + 5 numbers per point instead of 125
    assert factored.nbytes < 0.25 * dense.nbytes


def test_bad_lattices_are_refused_with_a_message():
    with pytest.raises(IsochorError, match="2 to 10"):
        Lattice((1, 3, 3), (0, 0, 0), np.eye(3))
    with pytest.raises(IsochorError, match="2 to 10"):
        Lattice((11, 3, 3), (0, 0, 0), np.eye(3))
    with pytest.raises(IsochorError, match="singular"):
        Lattice((3, 3, 3), (0, 0, 0), [[1, 0, 0], [0, 1, 0], [1, 1, 0]])
    with pytest.raises(IsochorError, match="no extent"):
        Lattice.around(np.ones((4, 3)))


@pytest.mark.parametrize("shape", [(2, 2, 2), (4, 3, 3), (6, 2, 5)])
def test_jacobian_matches_central_differences_in_a_skewed_frame(shape, monkeypatch):
    monkeypatch.setattr(lat_mod, "BASIS_BLOCK", 16)  # several blocks
    rng = np.random.default_rng(3)
    lat = Lattice(shape, [0.1, -0.2, 0.3], [[2, 0.1, 0], [0.2, 1.5, 0], [0, 0.3, 1.2]])
    nodes = lat.rest_nodes + 0.2 * rng.standard_normal((lat.n_nodes, 3))
    points = lat.origin + rng.uniform(-0.1, 1.1, (50, 3)) @ lat.axes  # inside and out
    h = 1e-6
    numeric = np.stack(
        [
            (lat.deform(points + h * e, nodes) - lat.deform(points - h * e, nodes)) / (2 * h)
            for e in np.eye(3)
        ],
        axis=2,
    )
    np.testing.assert_allclose(lat.jacobian(points, nodes), numeric, atol=1e-8)
    # at rest the map is the identity; an affine node map has its matrix as Jacobian
    np.testing.assert_allclose(
        lat.jacobian(points, lat.rest_nodes), np.tile(np.eye(3), (50, 1, 1)), atol=1e-12
    )
    a = np.array([[1.2, 0.3, 0.0], [-0.1, 0.9, 0.2], [0.0, 0.4, 1.1]])
    np.testing.assert_allclose(
        lat.jacobian(points, lat.rest_nodes @ a.T), np.tile(a, (50, 1, 1)), atol=1e-12
    )


def test_a_basis_keeps_the_lattice_coordinates_of_its_points():
    """The compiled kernels (core/kernels/) evaluate the basis from them."""
    rng = np.random.default_rng(5)
    lat = Lattice((3, 4, 2), (0.5, -1.0, 2.0), [[2.0, 0.3, 0.0], [0.1, 1.5, 0.2], [0, -0.4, 1]])
    pts = lat.origin + rng.uniform(size=(40, 3)) @ lat.axes
    basis = lat.point_basis(pts)
    assert basis.uvw.shape == (3, 40) and basis.uvw.flags.c_contiguous
    np.testing.assert_allclose(basis.uvw.T, lat.to_parameters(pts), atol=1e-14)
