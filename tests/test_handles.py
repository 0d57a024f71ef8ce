"""Surface handles and symmetric editing (issue 12), in the core: the maths against closed
forms and finite differences, and real solves that meet them."""

from __future__ import annotations

import numpy as np
import pytest

from isochor.core.errors import IsochorError
from isochor.core.goal.handles import HANDLE_MET, Handle, HandleSystem, handle_rows, weights
from isochor.core.goal.spec import Goal
from isochor.core.goal.symmetry import Mirror
from isochor.core.lattice import Lattice
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import solve
from isochor.core.solve.solver import Coordinates
from tests.models import model
from tests.numdiff import central_gradient

SHEARED = Lattice((3, 4, 2), (0.1, -0.2, 0.3), ((1.2, 0.1, 0.0), (0.2, 0.9, 0.1), (0.0, 0.3, 0.7)))


def _random_nodes(lattice, scale=0.05, seed=0):
    rng = np.random.default_rng(seed)
    return lattice.rest_nodes + scale * lattice.size * rng.standard_normal((lattice.n_nodes, 3))


# -- the maths ----------------------------------------------------------------------------
def test_handle_weights_deform_points_as_the_lattice_does():
    rng = np.random.default_rng(1)
    points = SHEARED.origin + rng.random((7, 3)) @ SHEARED.axes
    nodes = _random_nodes(SHEARED)
    w = weights(SHEARED, points)
    assert np.allclose(w.sum(axis=1), 1.0)  # a partition of unity
    assert np.allclose(w @ nodes, SHEARED.deform(points, nodes), atol=1e-12)


def test_handle_constraints_and_their_jacobian_match_finite_differences():
    lattice = Lattice((3, 3, 3), (0, 0, 0), np.diag([2.0, 1.0, 1.5]))
    rng = np.random.default_rng(2)
    at = lattice.origin + rng.random((2, 3)) @ lattice.axes
    hs = [Handle(a, a + 0.1 * rng.standard_normal(3)) for a in at]
    nodes = _random_nodes(lattice, seed=3)
    free = np.ones((lattice.n_nodes, 3), bool)
    coords = Coordinates(free, lattice.origin, lattice.size)
    system = HandleSystem(lattice, hs, nodes, coords.reduce, spare=1, size=lattice.size)
    assert system.count == 6 and system.unreachable < 1e-12
    for i in range(system.count):
        fd = central_gradient(lambda x, i=i: system.values(x)[i], nodes)
        assert np.allclose(fd, system.jacobian[i], atol=1e-7)
    # the kept rows span what the handles ask: c = 0 exactly when every handle is met
    met = nodes.copy()
    rows, b = handle_rows(lattice, hs)
    flat = rows.reshape(len(b), -1)
    met.ravel()[:] += np.linalg.lstsq(flat, b - flat @ nodes.ravel(), rcond=None)[0]
    assert np.allclose(system.values(met), 0, atol=1e-9)
    assert max(r.miss for r in system.results(met)) < 1e-12


def test_inconsistent_handles_keep_only_what_the_free_nodes_can_reach():
    lattice = Lattice((2, 2, 2), (0, 0, 0), np.eye(3))
    p = np.array([0.5, 0.5, 0.5])
    hs = [Handle(p, p + [0, 0.2, 0]), Handle(p, p - [0, 0.2, 0])]  # one point, two places
    nodes = lattice.rest_nodes
    coords = Coordinates(np.ones((8, 3), bool), lattice.origin, lattice.size)
    system = HandleSystem(lattice, hs, nodes, coords.reduce, spare=1, size=lattice.size)
    assert system.rank == 3 and system.count == 3
    assert system.unreachable == pytest.approx(np.sqrt(2) * 0.2, rel=1e-9)
    # on a lattice with one free node (3 coordinates) and the volume to keep, only 2 rows
    one = np.zeros((8, 3), bool)
    one[7] = True
    coords = Coordinates(one, lattice.origin, lattice.size)
    system = HandleSystem(lattice, hs, nodes, coords.reduce, spare=1, size=lattice.size)
    assert system.count == 2


def test_tied_coordinates_reduce_gradients_as_the_chain_rule_says():
    lattice = Lattice((4, 3, 2), (0, 0, 0), np.diag([2.0, 1.0, 1.0]))
    mirror = Mirror(lattice, 0)
    free = np.ones((lattice.n_nodes, 3), bool)
    free[0] = False  # a fixed node and its (fixed) partner
    free[mirror.partner[0]] = False
    nodes = _random_nodes(lattice, seed=4)
    nodes[~free.all(axis=1)] = lattice.rest_nodes[~free.all(axis=1)]  # fixed where they rest
    nodes, free_sym = mirror.symmetric(nodes, ~free)
    own, *ties = mirror.ties(~free_sym)
    coords = Coordinates(own, lattice.origin, lattice.size, tuple(ties))
    rng = np.random.default_rng(5)
    a = rng.standard_normal(nodes.shape)

    def f(x):  # any smooth function of the nodes
        return float(np.sum(a * x) + np.sum(np.sin(x) ** 2))

    def grad(x):
        return a + 2 * np.sin(x) * np.cos(x)

    y = coords.to_y(nodes)
    x = coords.to_nodes(y, nodes)
    # a tied coordinate is 2 plane - x, and its image 2 plane - (2 plane - x): two roundings
    eps = np.finfo(np.float64).eps
    assert mirror.asymmetry(x) <= eps * (2 * abs(mirror.plane) + np.abs(x).max()) / lattice.size
    fd = central_gradient(lambda z: f(coords.to_nodes(z, nodes)), y)
    assert np.allclose(fd, coords.reduce(grad(x)) * coords.size, atol=1e-6)


def test_a_mirror_pairs_nodes_and_points_across_the_mid_plane():
    lattice = Lattice((3, 4, 2), (1, 2, 3), np.diag([2.0, 3.0, 1.0]))
    for axis in range(3):
        m = Mirror(lattice, axis)
        assert np.array_equal(m.partner[m.partner], np.arange(lattice.n_nodes))
        # the rest lattice is its own image up to rounding: a node and its partner (origin +
        # i / (n - 1) axis) a few eps each, the plane one, 2 plane - x one
        rest = lattice.rest_nodes
        bound = 8 * np.finfo(np.float64).eps * (abs(m.plane) + np.abs(rest).max())
        assert m.asymmetry(rest) <= bound / lattice.size
        assert np.allclose(m.point(m.point([0.3, 0.1, 7.0])), [0.3, 0.1, 7.0])
    assert Mirror.of(lattice, "none") is None
    with pytest.raises(IsochorError, match="not aligned"):
        Mirror.of(SHEARED, "x")


def test_symmetric_edits_mirror_one_side_and_refuse_two_contradicting_moves():
    lattice = Lattice((3, 3, 3), (0, 0, 0), np.eye(3))
    m = Mirror(lattice, 0)
    nodes, fixed = lattice.rest_nodes.copy(), np.zeros((27, 3), bool)
    r = lattice.index(0, 2, 2)
    nodes[r] += [0.1, 0.2, 0.3]
    fixed[r] = True
    sym_nodes, sym_fixed = m.symmetric(nodes, fixed)
    p = m.partner[r]
    assert sym_fixed[p].all() and np.allclose(sym_nodes[p], m.point(sym_nodes[r]))
    # a node on the plane moved off it is put back on it
    mid = lattice.index(1, 0, 0)
    nodes[mid] += [0.2, 0, 0]
    fixed[mid] = True
    assert m.symmetric(nodes, fixed)[0][mid, 0] == pytest.approx(0.5)
    nodes[p] += [0.0, -0.3, 0.0]  # the partner moved too, elsewhere
    fixed[p] = True
    with pytest.raises(IsochorError, match="mirror partners"):
        m.symmetric(nodes, fixed)


# -- solves -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cow():
    return build(Scenario({"path": str(model("cow.obj"))}, lattice_nodes=(4, 3, 3)))


def _nose_and_tail(problem):
    v = problem.surface.full.vertices
    return v[np.argmax(v[:, 0])], v[np.argmin(v[:, 0])]


def _run(problem, handles=(), **goal):
    return run_to_end(
        solve(
            problem.surface,
            problem.nodes,
            problem.fixed,
            goal=Goal(**goal),
            handles=handles,
            options=problem.options,
        )
    )


def test_two_handles_on_the_cow_land_on_their_targets_and_keep_the_volume(cow):
    nose, tail = _nose_and_tail(cow)
    size = cow.surface.size
    hs = [Handle(nose, nose + [0, 0.12 * size, 0]), Handle(tail, tail + [-0.05 * size, 0, 0])]
    r = _run(cow, hs)
    assert r.converged and r.handles_met, r.message
    assert max(h.miss for h in r.handles) < 1e-3
    reached = cow.surface.lattice.deform(np.array([nose, tail]), r.nodes)
    assert np.allclose(reached, [h.to for h in hs], atol=1e-3 * size)
    assert abs(r.rel_volume_error) <= cow.options.tol_volume
    assert r.folds is not None and not r.folds.folded


def test_one_handle_deforms_the_model_instead_of_carrying_it_away(cow):
    nose, _ = _nose_and_tail(cow)
    r = _run(cow, [Handle(nose, nose + [0, 0.15 * cow.surface.size, 0])])
    assert r.converged and r.held_face  # the far side is held: the cow does not drift
    moved = np.linalg.norm(r.nodes - cow.nodes, axis=1)
    assert np.all(moved[list(r.held)] == 0) and moved.max() > 0.05 * cow.surface.size


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_a_symmetric_edit_gives_a_symmetric_lattice(cow, axis):
    lattice = cow.surface.lattice
    nodes, fixed = cow.nodes.copy(), cow.fixed.copy()
    r0 = lattice.index(3, 2, 2)
    nodes[r0] += 0.15 * lattice.size * np.array([1.0, 0.5, -0.5])
    fixed[r0] = True
    nose, _ = _nose_and_tail(cow)
    h = Handle(nose, nose + [0.0, 0.05 * lattice.size, 0.02 * lattice.size])
    result = run_to_end(solve(cow.surface, nodes, fixed, goal=Goal(symmetry=axis), handles=[h]))
    assert result.converged, result.message
    assert result.asymmetry < 1e-9
    assert Mirror.of(lattice, axis).asymmetry(result.nodes) < 1e-9
    assert abs(result.rel_volume_error) <= cow.options.tol_volume


def test_handles_that_cannot_all_be_met_are_fitted_and_said_so(cow):
    nose, _ = _nose_and_tail(cow)
    size = cow.surface.size
    apart = [Handle(nose, nose + [0, 0.1 * size, 0]), Handle(nose, nose - [0, 0.1 * size, 0])]
    r = _run(cow, apart)
    assert r.converged and not r.handles_met
    assert "cannot all be met: fitted by least squares" in r.message
    # the least-squares fit of one point sent to two places is the middle
    assert [h.miss for h in r.handles] == pytest.approx([0.1, 0.1], abs=HANDLE_MET)


def test_more_handles_than_a_small_lattice_can_hold_end_without_a_hang():
    problem = build(Scenario({"builtin": "sphere"}, lattice_nodes=(2, 2, 2)))
    v = problem.surface.full.vertices
    rng = np.random.default_rng(6)
    hs = [Handle(v[i], v[i] + 0.02 * rng.standard_normal(3)) for i in rng.choice(len(v), 12)]
    r = _run(problem, hs)  # 36 equations on 24 coordinates, and the volume to keep
    assert len(r.handles) == 12
    if r.converged:
        assert abs(r.rel_volume_error) <= problem.options.tol_volume
        assert r.handles_met or "least squares" in r.message
    else:
        assert r.message


# -- the scenario and the Python API ------------------------------------------------------
def test_a_scenario_keeps_its_handles_and_symmetry_as_version_3(tmp_path):
    h = Handle((0.1, 0.2, 0.3), (0.1, 0.5, 0.3))
    sc = Scenario({"builtin": "sphere"}, handles=(h,), goal=Goal(symmetry="z"))
    assert sc.version == 3 and sc.goal.symmetry == "z"
    sc.write(tmp_path / "s.json")
    again = Scenario.read(tmp_path / "s.json")
    assert again.handles == (h,) and again.goal.symmetry == "z"
    assert Scenario({"builtin": "sphere"}).to_dict()["version"] == 1
    with pytest.raises(IsochorError, match="handle"):
        Handle.of({"at": [0, 0, 0]})


def test_a_session_places_moves_and_solves_handles():
    import trimesh

    from isochor.core.api import Session, deform

    s = Session(trimesh.creation.icosphere(subdivisions=2), lattice=(3, 3, 3))
    top = np.array([0.0, 0.0, 1.0])
    k = s.add_handle(top)
    assert np.allclose(s.handles[k].to, s.lattice.deform(top[None], s.nodes)[0])
    s.move_handle(k, top + [0.0, 0.0, 0.3])
    r = s.solve()
    assert r.converged and r.handles_met
    assert np.allclose(s.lattice.deform(top[None], s.nodes)[0], top + [0, 0, 0.3], atol=2e-3)
    assert s.scenario().handles == tuple(s.handles)
    out = deform(
        trimesh.creation.icosphere(subdivisions=2),
        (3, 3, 3),
        handles=[{"at": top, "to": top + [0.2, 0.0, 0.0]}],
        symmetry="y",
    )
    assert out.converged and out.report["asymmetry"] < 1e-9
    assert out.report["handles"][0]["miss"] < 1e-3
