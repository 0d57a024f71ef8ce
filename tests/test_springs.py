"""Spring network: 14 neighbours, rigid-motion invariance, gradient."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from isochor.core.lattice import Lattice
from isochor.core.springs import SpringNetwork, lattice_springs
from tests.numdiff import central_gradient


def test_interior_node_has_fourteen_neighbours_and_network_is_mirror_symmetric():
    edges = lattice_springs((3, 3, 3))
    degree = np.bincount(edges.ravel(), minlength=27)
    assert degree[13] == 14  # the centre node (1, 1, 1)
    assert len({tuple(sorted(e)) for e in edges.tolist()}) == len(edges)  # no duplicates
    # mirror i -> 2 - i maps the spring set onto itself
    ijk = np.array(np.unravel_index(np.arange(27), (3, 3, 3))).T
    mirror = lambda r: np.ravel_multi_index((2 - ijk[r, 0], ijk[r, 1], ijk[r, 2]), (3, 3, 3))  # noqa: E731
    springs = {tuple(sorted(e)) for e in edges.tolist()}
    assert {tuple(sorted((mirror(a), mirror(b)))) for a, b in springs} == springs


def _network(shape=(4, 3, 3)):
    lat = Lattice((shape), (0.0, 0.0, 0.0), np.diag([4.0, 2.0, 1.5]))
    return lat, SpringNetwork.for_lattice(lat.shape, lat.rest_nodes)


def test_energy_vanishes_under_rigid_motion_and_rises_when_a_node_moves():
    lat, net = _network()
    rng = np.random.default_rng(6)
    for _ in range(5):
        rot = Rotation.random(random_state=rng).as_matrix()
        moved = lat.rest_nodes @ rot.T + rng.normal(size=3) * 10
        e, g = net.energy_and_gradient(moved)
        assert e == pytest.approx(0.0, abs=1e-20)
        assert np.max(np.abs(g)) < 1e-12
    bumped = lat.rest_nodes.copy()
    bumped[7] += (0.1, 0.0, 0.0)
    assert net.energy(bumped) > 1e-4


def test_spring_gradient_matches_central_differences():
    lat, net = _network((3, 4, 2))
    rng = np.random.default_rng(7)
    x = lat.rest_nodes + rng.normal(scale=0.2, size=(lat.n_nodes, 3))
    _, g = net.energy_and_gradient(x)
    num = central_gradient(net.energy, x)
    assert np.max(np.abs(num - g)) <= 1e-6 * np.max(np.abs(g))
