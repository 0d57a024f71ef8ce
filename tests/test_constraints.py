"""The constraints beyond the paper's one volume: their maths against closed forms and
finite differences, and the far-side anchor rule."""

import numpy as np
import pytest
import trimesh

from isochor.core.errors import IsochorError
from isochor.core.goal.anchor import held_face, rigid_freedom
from isochor.core.goal.constraints import CENTROID_SCALE, Bodies, Constraints, Level
from isochor.core.goal.spec import Goal
from isochor.core.lattice import Lattice
from isochor.core.mesh import TriMesh
from isochor.core.volume import MomentOperator
from tests.numdiff import central_gradient


def _mesh(t: trimesh.Trimesh) -> TriMesh:
    return TriMesh(t.vertices, t.faces)


def two_spheres() -> TriMesh:
    """A unit sphere and a sphere of radius 0.5 beside it, one mesh."""
    a = trimesh.creation.icosphere(3, radius=1.0)
    b = trimesh.creation.icosphere(3, radius=0.5)
    b.apply_translation([1.8, 0.2, 0.1])
    return _mesh(trimesh.util.concatenate([a, b]))


def test_first_moment_is_the_volume_times_the_centroid_of_a_box():
    box = trimesh.creation.box([2.0, 3.0, 4.0])
    box.apply_translation([1.0, -2.0, 0.5])
    m, _ = MomentOperator(box.faces, len(box.vertices)).value_and_gradient(box.vertices)
    np.testing.assert_allclose(m, 24.0 * np.array([1.0, -2.0, 0.5]), rtol=1e-12)
    # about another centre: M - V c
    m2, _ = MomentOperator(box.faces, len(box.vertices)).value_and_gradient(
        box.vertices, np.array([1.0, 1.0, 1.0])
    )
    np.testing.assert_allclose(m2, 24.0 * np.array([0.0, -3.0, -0.5]), atol=1e-12)


def test_first_moment_gradient_matches_finite_differences():
    rng = np.random.default_rng(3)
    s = trimesh.creation.icosphere(1)
    v = s.vertices + rng.normal(scale=0.05, size=s.vertices.shape)
    op = MomentOperator(s.faces, len(v))
    _, grad = op.value_and_gradient(v, np.array([0.1, 0.2, -0.3]))
    for i in range(3):
        fd = central_gradient(lambda x, i=i: op.value_and_gradient(x, [0.1, 0.2, -0.3])[0][i], v)
        np.testing.assert_allclose(grad[i], fd, atol=1e-8)


@pytest.mark.parametrize(
    "goal",
    [
        Goal(0.8),
        Goal(1.3, preserve="per-body"),
        Goal(0.7, keep_centroid=True),
        Goal(1.0, preserve="per-body", keep_centroid=True),
    ],
    ids=["total", "per-body", "centroid", "per-body+centroid"],
)
def test_constraint_jacobian_matches_finite_differences(goal):
    rng = np.random.default_rng(5)
    mesh = two_spheres()
    lat = Lattice(
        (3, 4, 2),
        [-1.3, -1.2, -1.1],
        [[3.8, 0.3, 0.0], [-0.2, 2.6, 0.1], [0.0, 0.2, 2.4]],  # a sheared frame
    )
    level = Level(lat, mesh, mesh.center)
    cons = Constraints(level, goal, Bodies.of(mesh), 5.0, mesh.size)
    nodes = lat.rest_nodes + rng.normal(scale=0.1, size=(lat.n_nodes, 3))
    c, dc = cons.values_and_jacobian(nodes)
    np.testing.assert_allclose(c, cons.values(nodes), rtol=1e-12, atol=1e-14)
    assert (
        len(c)
        == cons.count
        == (2 if goal.preserve == "per-body" else 1) + (3 if goal.keep_centroid else 0)
    )
    for i in range(len(c)):
        fd = central_gradient(lambda x, i=i: cons.values(x)[i], nodes, h=1e-6)
        np.testing.assert_allclose(dc[i], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_constraints_are_zero_at_rest_and_measure_what_they_say():
    mesh = two_spheres()
    lat = Lattice.around(mesh.vertices, (3, 3, 3))
    level = Level(lat, mesh, mesh.center)
    bodies = Bodies.of(mesh)
    assert bodies.count == 2
    np.testing.assert_allclose(
        sorted(bodies.volumes), [4 / 3 * np.pi / 8, 4 / 3 * np.pi], rtol=0.03
    )
    # at rest, with the target ratio 1, every constraint is met exactly
    goal = Goal(1.0, preserve="per-body", keep_centroid=True)
    cons = Constraints(level, goal, bodies, level.rest_volume, mesh.size)
    assert np.max(np.abs(cons.values(lat.rest_nodes))) < 1e-12
    # a translation of every node keeps the volumes and moves the centroid by the offset
    shift = np.array([0.0, 0.0, 1e-3 * mesh.size])
    c = cons.values(lat.rest_nodes + shift)
    assert np.max(np.abs(c[:2])) < 1e-12
    expected = shift / (CENTROID_SCALE * mesh.size)  # V C / (0.1 V size)
    np.testing.assert_allclose(c[2:], expected, rtol=1e-9, atol=1e-12)


def test_a_shrinking_target_measures_against_the_target():
    mesh = _mesh(trimesh.creation.icosphere(2))
    lat = Lattice.around(mesh.vertices, (3, 3, 3))
    level = Level(lat, mesh, mesh.center)
    cons = Constraints(level, Goal(0.1), None, level.rest_volume, mesh.size)
    # nodes scaled so that the volume is 0.11 of the rest volume: 10% off the target
    scale = 0.11 ** (1 / 3)
    nodes = mesh.center + scale * (lat.rest_nodes - mesh.center)
    assert cons.values(nodes)[0] == pytest.approx(0.1, rel=1e-6)


def test_bodies_count_a_cavity_with_its_shell():
    outer = trimesh.creation.icosphere(3, radius=1.0)
    inner = trimesh.creation.icosphere(2, radius=0.5)
    inner.invert()  # a cavity faces inward
    far = trimesh.creation.icosphere(2, radius=0.3)
    far.apply_translation([3.0, 0, 0])
    bodies = Bodies.of(_mesh(trimesh.util.concatenate([outer, inner, far])))
    assert bodies.count == 2
    assert bodies.solid_of_shell[0] == bodies.solid_of_shell[1] != bodies.solid_of_shell[2]
    np.testing.assert_allclose(
        sorted(bodies.volumes), [4 / 3 * np.pi * 0.3**3, 4 / 3 * np.pi * (1 - 0.125)], rtol=0.05
    )


@pytest.mark.parametrize(
    ("ratio", "ok"), [(0.05, True), (20.0, True), (0.01, False), (1e-6, False), (25.0, False)]
)
def test_goal_bounds_the_ratio_with_a_message(ratio, ok):
    if ok:
        assert Goal(ratio).target_ratio == ratio
    else:
        with pytest.raises(IsochorError, match=r"outside 0\.05\.\.20.*inside out"):
            Goal(ratio)


def test_goal_rejects_unknown_words():
    with pytest.raises(IsochorError, match="preserve"):
        Goal(preserve="each")
    with pytest.raises(IsochorError, match="anchor"):
        Goal(anchor="corner")


def test_rigid_freedom_counts_what_the_fixed_coordinates_leave():
    lat = Lattice.around(np.array([[0, 0, 0], [2, 1, 1.0]]), (3, 3, 3))
    x = lat.rest_nodes
    none = np.zeros((lat.n_nodes, 3), bool)
    assert rigid_freedom(x, none) == 6
    one = none.copy()
    one[0] = True
    assert rigid_freedom(x, one) == 3  # it can still turn about the node
    two = one.copy()
    two[lat.index(2, 2, 2)] = True
    assert rigid_freedom(x, two) == 1  # ... about the line through both
    three = two.copy()
    three[lat.index(2, 0, 0)] = True
    assert rigid_freedom(x, three) == 0
    z_only = none.copy()
    z_only[[lat.index(0, 0, 0), lat.index(2, 0, 0), lat.index(0, 2, 0)], 2] = True
    assert rigid_freedom(x, z_only) == 3  # x, y sliding and turning about z remain


def test_far_side_holds_the_face_farthest_from_the_moved_node():
    lat = Lattice.around(np.array([[0, 0, 0], [4, 1, 2.0]]), (4, 3, 3))
    x = lat.rest_nodes.copy()
    fixed = np.zeros((lat.n_nodes, 3), bool)
    hold, name = held_face(lat, x, fixed)
    assert not hold.any() and name == ""  # nothing moved: nothing to hold
    r = lat.index(0, 0, 0)
    x[r] += [0.3, 0.2, 0.1]
    fixed[r] = True
    hold, name = held_face(lat, x, fixed)
    assert name == "x max"  # the longest extent: the face farthest from the corner
    assert {lat.ijk(i)[0] for i in np.flatnonzero(hold)} == {3} and hold.sum() == 9
    # pushing down one top edge (it could still turn about that edge) holds the bottom
    x = lat.rest_nodes.copy()
    fixed[:] = False
    edge = [lat.index(i, 0, 2) for i in range(4)]
    x[edge, 2] -= 0.5
    fixed[edge] = True
    assert held_face(lat, x, fixed)[1] == "z min"
    # a whole layer moved leaves no rigid motion: nothing is added
    top = [lat.index(i, j, 2) for i in range(4) for j in range(3)]
    fixed[top] = True
    assert held_face(lat, x, fixed)[1] == ""
    # enough pins of the user's own: nothing is added
    x = lat.rest_nodes.copy()
    fixed[:] = False
    x[r] += 0.3
    for ijk in [(0, 0, 0), (3, 0, 0), (3, 2, 0), (0, 2, 2)]:
        fixed[lat.index(*ijk)] = True
    assert not held_face(lat, x, fixed)[0].any()
