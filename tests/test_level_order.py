"""A big pyramid level keeps its basis and operators over its vertices renumbered for
locality (:func:`isochor.core.volume.locality_order`): what it measures and the points it
gives are those of the mesh's own order."""

import numpy as np
import trimesh

from isochor.core.goal import constraints
from isochor.core.goal.constraints import Level
from isochor.core.lattice import Lattice
from isochor.core.mesh import TriMesh
from isochor.core.volume import locality_order


def test_a_big_level_in_locality_order_measures_and_deforms_as_in_the_mesh_order(monkeypatch):
    """A level past LOCALITY_TRIANGLES renumbers its vertices for the gathers: the volume,
    its gradient, the moment and the deformed points (in the mesh's order) stay the same."""
    ico = trimesh.creation.icosphere(subdivisions=3)
    mesh = TriMesh(np.asarray(ico.vertices, float), np.asarray(ico.faces, np.int64))
    # scramble the vertex numbers, as a subdivided model's are
    perm = np.random.default_rng(1).permutation(mesh.n_vertices)
    place = np.empty_like(perm)
    place[perm] = np.arange(len(perm))
    mesh = TriMesh(mesh.vertices[perm], place[mesh.faces])
    order = locality_order(mesh.faces, mesh.n_vertices)
    assert np.array_equal(np.sort(order), np.arange(mesh.n_vertices))
    # a face's corners lie close together in the new numbering (the point of it)
    renumbered = np.empty_like(order)
    renumbered[order] = np.arange(len(order))

    def spread(faces):
        return float(np.mean(faces.max(axis=1) - faces.min(axis=1)))

    assert spread(renumbered[mesh.faces]) < 0.25 * spread(mesh.faces)
    lattice = Lattice.around(mesh.vertices, (3, 3, 3))
    x = lattice.rest_nodes + 0.05 * np.random.default_rng(2).standard_normal((27, 3))
    center = mesh.vertices.mean(axis=0)
    plain = Level(lattice, mesh, center)
    monkeypatch.setattr(constraints, "LOCALITY_TRIANGLES", 0)
    local = Level(lattice, mesh, center)
    assert plain.order is None and local.order is not None
    tol = 1e-12 * abs(plain.rest_volume)
    assert abs(local.rest_volume - plain.rest_volume) <= tol
    assert abs(local.volume(x) - plain.volume(x)) <= tol
    (v1, g1), (v2, g2) = local.volume_and_gradient(x), plain.volume_and_gradient(x)
    assert abs(v1 - v2) <= tol and np.allclose(g1, g2, rtol=1e-12, atol=1e-12 * np.abs(g2).max())
    (m1, dm1), (m2, dm2) = local.moment_and_gradient(x), plain.moment_and_gradient(x)
    assert np.allclose(m1, m2, rtol=1e-12, atol=1e-14) and np.allclose(dm1, dm2, atol=1e-12)
    assert np.allclose(local.rest_centroid, plain.rest_centroid, atol=1e-12)
    # the same points in the mesh's order (the products' rounding may differ per order)
    assert np.allclose(local.deform(x), plain.deform(x), rtol=0, atol=1e-14)
    assert np.allclose(plain.deform(x), lattice.point_basis(mesh.vertices).apply(x), atol=1e-14)
