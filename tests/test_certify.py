"""The fold proof (isochor.core.goal.certify): det J's Bernstein coefficients against
det J itself, a pocket between the fold check's samples found, a fold-free result proven
and a result never called fold-free unless proven."""

from __future__ import annotations

import numpy as np
import pytest

from isochor.core.goal.certify import Occupancy, certify, determinant_coefficients
from isochor.core.goal.folds import FoldCheck, jacobian_determinants
from isochor.core.lattice import Lattice, bernstein
from tests.models import icosphere


def test_the_coefficients_are_those_of_det_j():
    """det J at random points equals the Bernstein polynomial of the coefficients (an
    oblique, non-cubic frame and an irregular lattice), to rounding."""
    rng = np.random.default_rng(1)
    axes = np.array([[2.4, 0.3, 0.0], [0.0, 2.2, 0.1], [0.2, 0.0, 2.6]])
    lat = Lattice((4, 3, 5), np.array([-1.2, -1.1, -1.3]), axes)
    nodes = lat.rest_nodes + rng.normal(0, 0.08, lat.rest_nodes.shape)
    c = determinant_coefficients(nodes.reshape(4, 3, 5, 3))
    assert c.shape == (3 * 3, 3 * 2, 3 * 4)  # degrees 3L-1, 3M-1, 3N-1
    uvw = rng.uniform(0, 1, (200, 3))
    bases = [bernstein(c.shape[a] - 1, uvw[:, a]) for a in range(3)]
    poly = np.einsum("ijk,pi,pj,pk->p", c, *bases) / np.linalg.det(axes)
    exact = jacobian_determinants(lat, lat.origin + uvw @ axes, nodes)
    np.testing.assert_allclose(poly, exact, rtol=0, atol=1e-12 * np.abs(exact).max())


def _pocket(delta: float):
    """A 5x5x5 lattice around a ball with its centre node moved ``delta`` lattice widths
    along x: det J first turns negative inside the ball (near x = 0.64), not at its
    surface, once delta passes about 6.17 (dX/du = 1 - delta * 0.162 there)."""
    mesh = icosphere(3)
    lat = Lattice.around(mesh.vertices, (5, 5, 5))
    nodes = lat.rest_nodes.copy()
    nodes[lat.index(2, 2, 2), 0] += delta * lat.axes[0, 0]
    return mesh, lat, nodes


@pytest.mark.parametrize(("delta", "folded"), [(6.1, False), (6.25, True)])
def test_a_pocket_between_the_samples_is_found_and_its_absence_proven(delta, folded):
    mesh, lat, nodes = _pocket(delta)
    dense = np.random.default_rng(0).uniform(-1, 1, (200_000, 3))
    dense = dense[np.linalg.norm(dense, axis=1) < 1]
    truth = bool((jacobian_determinants(lat, dense, nodes) <= 0).any())
    assert truth == folded  # the dense check agrees with the setup
    # samples only at the vertices: the pocket lies between them
    check = FoldCheck(lat, mesh.vertices, np.zeros((0, 3)), mesh.faces)
    folds = check.measure(nodes)
    assert folds.fraction == 0  # the samples see nothing
    assert folds.folded == folded
    if folded:
        assert folds.proven is False and folds.witness is not None
        at = np.array([folds.witness])
        assert np.linalg.norm(at) < 1  # inside the ball
        det = jacobian_determinants(lat, at, nodes)[0]
        assert det <= 0 and det == pytest.approx(folds.witness_det, abs=1e-9)
    else:
        assert folds.proven is True and folds.witness is None


def test_never_fold_free_unless_proven():
    """Random lattices, some folded: whenever the proof says fold-free, a dense check finds
    no fold inside the ball; whenever it finds a fold, det J there is <= 0 inside it."""
    mesh = icosphere(3)
    lat = Lattice.around(mesh.vertices, (4, 4, 4))
    occupancy = Occupancy(lat, mesh.vertices, mesh.faces)
    dense = np.random.default_rng(0).uniform(-1, 1, (100_000, 3))
    dense = dense[np.linalg.norm(dense, axis=1) < 0.995]
    outcomes = set()
    for seed in range(6):
        rng = np.random.default_rng(seed)
        nodes = lat.rest_nodes + rng.normal(0, 0.3 + 0.2 * seed, lat.rest_nodes.shape)
        proof = certify(lat, nodes, occupancy, max_boxes=400)
        folded_somewhere = bool((jacobian_determinants(lat, dense, nodes) <= 0).any())
        if proof.proven:
            assert not folded_somewhere, f"seed {seed}: proven fold-free but folded"
            outcomes.add("proven")
        elif proof.folded:
            assert np.linalg.norm(proof.witness) <= 1.0
            assert jacobian_determinants(lat, proof.witness[None], nodes)[0] <= 0
            outcomes.add("folded")
    assert {"proven", "folded"} <= outcomes


def test_two_threads_asking_the_occupancy_at_once_both_get_the_whole_grid(monkeypatch):
    """A stopped drag's solve may still be measuring while the next one starts: the thread
    that comes second waits for the grid the first is building (it once found the inputs
    gone and the tables not yet made: AttributeError in the window)."""
    import threading

    mesh = icosphere(2)
    lat = Lattice.around(mesh.vertices, (3, 3, 3))
    occupancy = Occupancy(lat, mesh.vertices, mesh.faces)
    building, go = threading.Event(), threading.Event()
    real = Occupancy._make

    def slow(self, *args):
        building.set()
        assert go.wait(10)
        real(self, *args)

    monkeypatch.setattr(Occupancy, "_make", slow)
    results, errors = {}, []

    def ask(name):
        try:
            results[name] = occupancy.block(np.full(3, 0.4), np.full(3, 0.6))
        except Exception as exc:  # pragma: no cover - the failure this test is for
            errors.append(exc)

    first = threading.Thread(target=ask, args=("first",))
    first.start()
    assert building.wait(10)
    second = threading.Thread(target=ask, args=("second",))
    second.start()
    second.join(0.2)
    assert second.is_alive() and not errors  # waiting for the grid, not failing
    go.set()
    first.join(10)
    second.join(10)
    assert not errors
    assert results["first"] == results["second"] == (True, True)  # the middle is solid
