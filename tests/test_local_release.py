"""The local release (core/solve/local.py): its cells, its remembered volume and det J, and
its nodes against a tight whole solve; a Bernstein lattice and a big edit fall back."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from isochor import Session
from isochor.core.goal.anchor import held_face
from isochor.core.goal.folds import FoldCheck
from isochor.core.solve import local as release_mod
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.solver import Coordinates, Curvatures
from isochor.core.solve.surface import FOLD_MARGIN

trimesh = pytest.importorskip("trimesh")


def test_cells_reached_matches_the_windows():
    rng = np.random.default_rng(3)
    shape = (5, 4, 6)
    nodes = rng.random(int(np.prod(shape))) < 0.08
    got = release_mod.cells_reached(shape, nodes)
    grid = nodes.reshape(shape)
    for q in np.ndindex(got.shape):
        window = [np.clip(np.arange(c - 2, c + 2), 0, s - 1) for c, s in zip(q, shape)]
        want = grid[np.ix_(*window)].any()
        assert got[q] == want, q


def _session(n=8, basis="bspline"):
    s = Session(trimesh.creation.icosphere(4), lattice=(n,) * 3, basis=basis)
    s.fixed[s.lattice.grid_parameters()[:, 1] == 0] = True
    return s


def _objective(s, result):
    """The whole solve's free coordinates, energy, Hessian and shared curvature."""
    surf, lattice, size = s.problem.surface, s.lattice, s.lattice.size
    fixed = np.array(np.broadcast_to(s.fixed.reshape(lattice.n_nodes, -1), (lattice.n_nodes, 3)))
    held, _ = held_face(lattice, np.array(result.nodes), fixed)
    fixed[held] = True
    coords = Coordinates(~fixed, surf.center, surf.size)
    guard, springs = surf.fold_guard(FOLD_MARGIN), surf.springs

    def energy(x):
        e, de = springs.energy_and_gradient(x)
        q, dq = guard.value_and_gradient(x)
        return (e, de) if q == 0 else (e + q * size**2, de + dq * size**2)

    def hessian(x):
        h, g = springs.hessian(x), guard.gauss_newton(x)
        if sp.issparse(g):
            return h + g * size**2 if g.nnz else h
        return h + g * size**2

    return coords, energy, hessian, Curvatures(hessian, coords, lattice.shape)


@pytest.mark.parametrize("node", [(4, 7, 4), (7, 7, 7), (0, 7, 3)])
def test_small_edit_released_locally_reaches_the_whole_solve(node):
    s = _session()
    size = s.lattice.size
    s.move(node, by=(0, 0.1 * size, 0))
    first = s.solve()
    assert first.converged
    surf = s.problem.surface
    coords, energy, hessian, curvatures = _objective(s, first)
    release_mod.remember(surf, first, coords.free, np.array([first.lam]))
    s.move(node, by=(0.001 * size, 0, 0))
    x = s.nodes.copy()
    opts = s.problem.options
    run = release_mod.release(surf, s.goal, opts, x, coords, energy, hessian, curvatures, 0.0)
    released = run_to_end(run)
    assert released is not None and released.region < s.lattice.n_nodes
    # the full mesh's volume at the local result meets the tolerance ...
    full = surf.level(-1)
    error = (full.volume(released.nodes) - full.rest_volume) / abs(full.rest_volume)
    assert abs(error) <= opts.tol_volume
    # ... and its nodes are the whole problem's optimum (solved tight, from the edit) to
    # the accepted first-order step (tol_nodes) and as much again for the curvature's
    # approximation of the Hessian
    tight = replace(opts, gtol=1e-9, tol_volume=1e-8)
    whole = run_to_end(s.problem.solve(x, s.fixed, options=tight, start_level=-1))
    assert np.abs(released.nodes - whole.nodes).max() <= 2 * opts.tol_nodes * size
    # det J: the remembered one outside the reached cells equals a full re-measure
    dets = np.concatenate(surf.fold_check.determinants(released.nodes))
    fresh = FoldCheck(s.lattice, surf.full.vertices, surf.interior)  # measures everything
    again = np.concatenate(fresh.determinants(released.nodes))
    assert np.allclose(dets, again, rtol=0, atol=1e-12 * np.abs(again).max())


def test_touched_volume_is_the_full_volume():
    s = _session()
    size = s.lattice.size
    s.move((7, 7, 0), by=(0, 0.05 * size, 0))
    first = s.solve()
    surf = s.problem.surface
    release_mod.remember(surf, first, np.ones((s.lattice.n_nodes, 3), bool), np.array([first.lam]))
    memory = surf.recall(release_mod.MEMORY)
    x = np.array(first.nodes)
    x[s.lattice.index(7, 7, 0)] += 0.02 * size
    moving = np.zeros(s.lattice.n_nodes, bool)
    moving[s.lattice.index(7, 7, 0)] = True
    cells = release_mod.cells_reached(s.lattice.shape, moving).ravel()
    full = surf.level(-1)
    at = cells[release_mod.point_cells(s.lattice.shape, full.parameters())]
    faces = np.flatnonzero(at[surf.full.faces].any(axis=1))
    touched = release_mod.Touched(surf, faces, memory)
    assert touched.measured < surf.full.n_faces
    # the same sum of face volumes, regrouped: rounding of the order of eps * sum |v_f|
    bound = 64 * np.finfo(float).eps * surf.full.n_faces * abs(full.rest_volume)
    assert abs(touched.volume(x) - full.volume(x)) <= bound


def test_bernstein_and_a_big_edit_fall_back():
    s = _session(4, "bernstein")
    assert release_mod.applies(s.problem.surface, s.goal, None, None)
    s = _session()
    size = s.lattice.size
    s.move((4, 7, 4), by=(0, 0.1 * size, 0))
    first = s.solve()
    surf = s.problem.surface
    coords, energy, hessian, curvatures = _objective(s, first)
    release_mod.remember(surf, first, coords.free, np.array([first.lam]))
    s.move((4, 7, 4), by=(0.05 * size, 0, 0))  # moves the far nodes beyond the tolerance
    run = release_mod.release(surf, s.goal, s.problem.options, s.nodes, coords, energy, hessian,
                    curvatures, 0.0)  # fmt: skip
    assert run_to_end(run) is None
