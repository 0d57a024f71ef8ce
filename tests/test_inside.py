"""The grid inside test (signed ray crossings per column) against the exact winding number,
including rays that run exactly through edges and vertices."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from isochor.core import inside as inside_module
from isochor.core.bodies import winding_numbers
from isochor.core.goal.folds import interior_points
from isochor.core.inside import grid_winding
from isochor.core.mesh import TriMesh

OCTAHEDRON = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])


def _surface_distance(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(p,) distance of each point to the nearest triangle, brute force (the closest point of
    a triangle, Ericson 2005, 5.1.5: the face, else the nearest of its three edges)."""
    p = points[:, None, :]
    a, b, c = (triangles[None, :, k, :] for k in range(3))
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    den = va + vb + vc
    face = (va >= 0) & (vb >= 0) & (vc >= 0) & (den > 0)
    safe = np.where(den > 0, den, 1.0)
    q = a + ab * (vb / safe)[..., None] + ac * (vc / safe)[..., None]
    best = np.where(face, np.linalg.norm(p - q, axis=-1), np.inf)
    for s, e in ((a, b), (b, c), (c, a)):
        d = e - s
        t = np.clip(((p - s) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - s - d * t[..., None], axis=-1))
    return best.min(axis=1)


def _agreement(vertices, faces, lo, step, cells) -> tuple[float, int]:
    """Share of the grid's points off the surface where |grid winding| > 1/2 agrees with
    |exact winding| > 1/2, and how many points are inside."""
    vertices, faces = np.asarray(vertices, float), np.asarray(faces)
    got = grid_winding(vertices, faces, lo, step, cells).ravel()
    axes = [lo[k] + (np.arange(cells[k]) + 0.5) * step[k] for k in range(3)]
    grid = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    exact = winding_numbers(grid, vertices[faces])
    tri = vertices[faces]
    dist = np.concatenate(
        [_surface_distance(grid[s : s + 256], tri) for s in range(0, len(grid), 256)]
    )
    off = dist > 1e-9 * np.abs(vertices).max()  # on the surface the winding number is 1/2 or so
    assert off.sum() > 0.5 * len(grid)
    same = (np.abs(got) > 0.5)[off] == (np.abs(exact) > 0.5)[off]
    # away from the surface the crossings are the winding number itself
    np.testing.assert_allclose(got[off], np.rint(exact[off]), atol=1e-6)
    return float(same.mean()), int((np.abs(got[off]) > 0.5).sum())


def _on_lines(axis: int, cells_along: int = 13, lines: int = 5, half: float = 1.0):
    """A grid whose columns (along ``axis``, the one with the most cells) sit on the lines
    -1, -0.5, 0, 0.5, 1 (through the shapes' vertices and edges), its heights off them."""
    cells = [lines] * 3
    cells[axis] = cells_along
    step = np.full(3, 2 * half / (lines - 1))
    lo = np.full(3, -half - step[0] / 2)
    step[axis], lo[axis] = 0.21, -1.3
    return lo, step, tuple(cells)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rays_through_the_edges_and_vertices_of_a_cube(axis):
    box = trimesh.creation.box(extents=(2, 2, 2))
    share, inside = _agreement(box.vertices, box.faces, *_on_lines(axis))
    assert share == 1.0 and inside == 9 * 10  # 3 x 3 columns strictly inside, 10 heights


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rays_through_the_vertices_of_an_octahedron(axis):
    faces = trimesh.convex.convex_hull(OCTAHEDRON).faces
    share, inside = _agreement(OCTAHEDRON, faces, *_on_lines(axis, lines=9))
    assert share == 1.0 and inside > 20


def test_exact_ties_are_decided_without_falling_back(monkeypatch):
    """A column exactly through the octahedron's top and bottom vertices: the side tests are
    exactly zero there, and the perturbation decides them (no exact winding numbers)."""
    calls = []
    real = inside_module.winding_numbers
    monkeypatch.setattr(
        inside_module, "winding_numbers", lambda p, t: calls.append(len(p)) or real(p, t)
    )
    faces = trimesh.convex.convex_hull(OCTAHEDRON).faces
    lo, step = np.array([-0.5, -0.5, -1.35]), np.array([1, 1, 0.2])
    w = grid_winding(OCTAHEDRON, faces, lo, step, (1, 1, 13))
    assert not calls
    heights = lo[2] + (np.arange(13) + 0.5) * step[2]
    np.testing.assert_array_equal(np.abs(w[0, 0]), np.abs(heights) < 1)


def test_rounding_doubts_fall_back_to_the_exact_winding_number(monkeypatch):
    """A cube turned so that its edges are not on the grid's lines but pass within rounding
    of the columns: those columns take the exact winding number, and all agree."""
    calls = []
    real = inside_module.winding_numbers
    monkeypatch.setattr(
        inside_module, "winding_numbers", lambda p, t: calls.append(len(p)) or real(p, t)
    )
    box = trimesh.creation.box(extents=(2, 2, 2))
    share, _ = _agreement(box.vertices, box.faces, *_on_lines(2))
    assert calls and share == 1.0  # the diagonals of the top and bottom faces are in doubt


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_turned_and_shifted_shapes_agree(seed):
    rng = np.random.default_rng(seed)
    turn = trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3]
    torus = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=10)
    for shape in (trimesh.creation.box(extents=(2, 1, 1.5)), torus):
        v = shape.vertices @ turn.T + rng.normal(size=3)
        lo, hi = v.min(axis=0) - 0.05, v.max(axis=0) + 0.05
        cells = (11, 14, 12)
        share, inside = _agreement(v, shape.faces, lo, (hi - lo) / cells, cells)
        assert share >= 0.999 and inside > 0


def test_several_bodies_a_cavity_an_overlap_and_caps():
    outer = trimesh.creation.icosphere(2)
    inner = trimesh.creation.icosphere(1, radius=0.5)
    n = len(outer.vertices)
    # a cavity (wound inward): winding 0 inside it
    v = np.concatenate([outer.vertices, inner.vertices])
    f = np.concatenate([outer.faces, inner.faces[:, ::-1] + n])
    lo, cells = np.full(3, -1.1), (13, 12, 11)
    share, _ = _agreement(v, f, lo, np.full(3, 2.2) / cells, cells)
    assert share == 1.0
    # two overlapping bodies: winding 2 where both are
    v = np.concatenate([outer.vertices, outer.vertices + [0.7, 0, 0]])
    f = np.concatenate([outer.faces, outer.faces + n])
    share, _ = _agreement(
        v, f, np.array([-1.1, -1.1, -1.1]), np.array([0.2, 0.2, 0.2]), (14, 11, 11)
    )
    assert share == 1.0
    # an open cylinder closed by caps: cap centres appended after the model's vertices
    k = 24
    angle = 2 * np.pi * np.arange(k) / k
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    v = np.concatenate([np.c_[ring, np.full(k, -1.0)], np.c_[ring, np.full(k, 1.0)]])
    nxt = (np.arange(k) + 1) % k
    side = np.concatenate(
        [np.c_[np.arange(k), nxt, nxt + k], np.c_[np.arange(k), nxt + k, np.arange(k) + k]]
    )
    v = np.concatenate([v, [[0, 0, -1.0], [0, 0, 1.0]]])  # the caps' own vertices, after
    bottom = np.c_[np.full(k, 2 * k), nxt, np.arange(k)]
    top = np.c_[np.full(k, 2 * k + 1), np.arange(k) + k, nxt + k]
    f = np.concatenate([side, bottom, top])
    assert trimesh.Trimesh(v, f, process=False).is_watertight
    share, inside = _agreement(v, f, np.full(3, -1.25), np.full(3, 0.25), (10, 10, 10))
    assert share == 1.0 and inside > 0


def test_interior_points_take_the_grids_inside_points():
    """The fold guard's samples are the grid points the exact winding number calls inside."""
    t = trimesh.creation.torus(1.0, 0.35)
    mesh = TriMesh(t.vertices, t.faces)
    points = interior_points(mesh, count=1500)
    assert len(points) > 500
    assert np.all(np.abs(winding_numbers(points, mesh.vertices[mesh.faces])) > 0.5)
