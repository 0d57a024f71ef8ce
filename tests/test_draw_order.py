"""The order the view draws a model's triangles in (app/view/modelview.py, ``draw_order``): a
permutation of them along a space-filling curve, so that neighbours in space are drawn
one after another (software OpenGL renders that faster; the picture is the same)."""

from __future__ import annotations

import numpy as np
import pytest

from isochor.app.view.modelview import draw_order
from isochor.core.scenario.shapes import torus_levels


def mean_step(points, faces, order) -> float:
    """Mean distance between consecutive triangles' centroids in ``order``."""
    c = points[faces[order]].mean(axis=1)
    return float(np.linalg.norm(np.diff(c, axis=0), axis=1).mean())


@pytest.mark.parametrize("seed", [0, 1])
def test_a_shuffled_mesh_is_drawn_with_neighbours_together(seed):
    mesh = torus_levels(6)[-1]  # 16384 triangles
    points, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    faces = faces[np.random.default_rng(seed).permutation(len(faces))]
    order = draw_order(points, faces)
    assert np.array_equal(np.sort(order), np.arange(len(faces)))  # each triangle once
    shuffled = mean_step(points, faces, np.arange(len(faces)))
    assert mean_step(points, faces, order) < shuffled / 10


@pytest.mark.parametrize("n", [0, 1, 2, 5])
def test_tiny_and_flat_meshes_get_an_order_too(n):
    """No triangles, one, or all in a plane (an axis of zero extent): still a permutation."""
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    faces = np.array([[0, 1, 2], [1, 3, 2]] * 3)[:n]
    order = draw_order(points, faces)
    assert np.array_equal(np.sort(order), np.arange(n))
