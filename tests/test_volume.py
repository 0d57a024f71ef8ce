"""Volume and its gradient: closed forms, finite differences, the O(1/N) claim."""

import numpy as np
import pytest

from isochor.core.lattice import Lattice
from isochor.core.scenario.shapes import sphere_levels, sphere_volume, torus_levels, torus_volume
from isochor.core.solve.multilevel import EmbeddedSurface
from isochor.core.volume import VolumeOperator, signed_volume
from tests.models import CUBE_FACES, CUBE_VERTICES
from tests.numdiff import central_gradient, check_vertex_gradient

CUBE_V, CUBE_F = CUBE_VERTICES, CUBE_FACES


def test_cube_volume_is_exact_anywhere_and_sign_follows_winding():
    for shift in (0.0, 1e6):
        v = CUBE_V * (2.0, 3.0, 4.0) + shift
        assert signed_volume(v, CUBE_F) == pytest.approx(24.0, rel=1e-12)
        assert signed_volume(v, CUBE_F[:, ::-1]) == pytest.approx(-24.0, rel=1e-12)


def test_volume_gradient_matches_central_differences(evaluation_path):
    rng = np.random.default_rng(4)
    mesh = sphere_levels(3)[-1]
    verts = mesh.vertices + rng.normal(scale=0.05, size=mesh.vertices.shape)
    op = VolumeOperator(mesh.faces, len(verts))
    v, grad = op.value_and_gradient(verts)
    assert v == pytest.approx(signed_volume(verts, mesh.faces), rel=1e-12)
    check_vertex_gradient(op, verts, grad, rng)


def test_volume_gradient_wrt_nodes_matches_central_differences(evaluation_path):
    rng = np.random.default_rng(5)
    levels = torus_levels(4)
    lat = Lattice.around(levels[-1].vertices, (4, 3, 3))
    surface = EmbeddedSurface(lat, levels)
    nodes = lat.rest_nodes + rng.normal(scale=0.05, size=(lat.n_nodes, 3))
    _, grad = surface.level(-1).volume_and_gradient(nodes)
    num = central_gradient(surface.volume, nodes)
    assert np.max(np.abs(num - grad)) <= 1e-6 * np.max(np.abs(grad))


@pytest.mark.parametrize(
    "levels, exact",
    [(torus_levels(6), torus_volume()), (sphere_levels(6), sphere_volume())],
    ids=["torus", "sphere"],
)
def test_sampled_volume_converges_as_one_over_n(levels, exact):
    """Paper Sec 4.2: the triangle approximation's error is O(1/N_tri)."""
    fine = levels[-3:]  # three levels, each 4 times finer
    errors = [exact - signed_volume(m.vertices, m.faces) for m in fine]
    assert all(e > 0 for e in errors)  # inscribed polyhedra lose volume
    ratios = [errors[i] / errors[i + 1] for i in range(2)]
    for r, m0, m1 in zip(ratios, fine, fine[1:]):
        assert r == pytest.approx(m1.n_faces / m0.n_faces, rel=0.05)
    # error * N is about constant: that constant is C of Eq 28
    c = [e * m.n_faces for e, m in zip(errors, fine)]
    assert max(c) / min(c) < 1.1


def test_builtin_shape_parameters_are_checked():
    from isochor.core.errors import IsochorError
    from isochor.core.scenario.shapes import builtin_levels

    assert [m.n_faces for m in builtin_levels("torus", n_levels=2)] == [16, 64]
    for bad in (
        {"n_levels": 14},
        {"n_levels": 0},
        {"n_levels": 2.5},
        {"minor": "x"},
        {"major": -1.0},
    ):
        with pytest.raises(IsochorError, match="model."):
            builtin_levels("torus", **bad)
    with pytest.raises(IsochorError, match="Unknown built-in shape"):
        builtin_levels("teapot")
