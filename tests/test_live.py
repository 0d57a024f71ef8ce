"""Issue 9's core: the preconditioned solver, a drag's live frames and the solve on release,
the first progress record before any slow set-up."""

from dataclasses import replace

import numpy as np
import pytest

from isochor.core.goal.folds import FoldGuard
from isochor.core.goal.spec import Goal
from isochor.core.goal.symmetry import Mirror
from isochor.core.lattice import Lattice
from isochor.core.scenario.examples import example_scenario
from isochor.core.scenario.problem import build
from isochor.core.scenario.shapes import torus_levels
from isochor.core.solve import precondition
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import EmbeddedSurface, live_level, solve
from isochor.core.solve.precondition import RIDGE, Curvature, Preconditioner
from isochor.core.solve.solver import Coordinates, SolverOptions
from isochor.core.springs import SpringNetwork
from tests.numdiff import central_gradient


def _fd_hessian(grad, x, h=1e-6):
    """Central differences of ``grad`` (flat -> flat) at flat ``x``."""
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((grad(x + e) - grad(x - e)) / (2 * h))
    return np.array(cols).T


def _rest(shape=(3, 3, 3)):
    axes = [np.linspace(0.0, 1.0, s) for s in shape]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def test_spring_hessian_is_exact_where_springs_are_stretched():
    rng = np.random.default_rng(1)
    rest = _rest((3, 2, 4))
    net = SpringNetwork.for_lattice((3, 2, 4), rest)
    x = 1.3 * rest + 0.03 * rng.standard_normal(rest.shape)  # every spring longer
    assert np.all(net.lengths(x) > net.rest_lengths)

    def grad(flat):
        return net.energy_and_gradient(flat.reshape(-1, 3))[1].ravel()

    expected = _fd_hessian(grad, x.ravel())
    np.testing.assert_allclose(net.hessian(x), expected, atol=1e-7)


def test_spring_hessian_stays_positive_semidefinite_under_compression():
    rng = np.random.default_rng(2)
    rest = _rest()
    net = SpringNetwork.for_lattice((3, 3, 3), rest)
    x = 0.6 * rest + 0.05 * rng.standard_normal(rest.shape)  # most springs shorter
    h = net.hessian(x)
    np.testing.assert_allclose(h, h.T, atol=1e-12)
    assert np.linalg.eigvalsh(h).min() > -1e-9
    # rigid translations cost nothing
    assert np.abs(h @ np.tile([1.0, 0.0, 0.0], len(rest))).max() < 1e-12


def test_fold_guard_gauss_newton_is_built_from_the_determinants_gradients():
    rng = np.random.default_rng(3)
    levels = torus_levels(3)
    lattice = Lattice.around(levels[-1].vertices, (3, 3, 3))
    guard = FoldGuard(lattice, levels[-1].vertices[::7], 0.4, 10.0)
    x = lattice.rest_nodes + 0.25 * lattice.size * rng.standard_normal((lattice.n_nodes, 3))
    dets = guard.determinants(x)
    active = np.flatnonzero(dets < 0.4)
    assert 0 < active.size < guard.n_points
    h = guard.gauss_newton(x)
    expected = np.zeros_like(h)
    for p in active:
        g = central_gradient(
            lambda flat, p=p: guard.determinants(flat.reshape(-1, 3))[p], x.ravel()
        )
        curvature = 6.0 * guard.weight / guard.n_points * (0.4 - dets[p])
        expected += curvature * np.outer(g, g)
    np.testing.assert_allclose(h, expected, rtol=1e-5, atol=1e-8 * np.abs(expected).max())
    assert not guard.gauss_newton(lattice.rest_nodes).any()  # nowhere near a fold


@pytest.mark.parametrize("axis", [None, "x", "z"])
def test_coordinates_matrix_is_the_reduction(axis):
    rng = np.random.default_rng(4)
    levels = torus_levels(2)
    lattice = Lattice.around(levels[-1].vertices, (3, 3, 3))
    free = rng.uniform(size=(lattice.n_nodes, 3)) < 0.6
    if axis is None:
        coords = Coordinates(free, np.zeros(3), 1.0)
    else:
        own, *ties = Mirror.of(lattice, axis).ties(free)
        coords = Coordinates(own, np.zeros(3), 1.0, tuple(ties))
    g = rng.standard_normal((2, lattice.n_nodes, 3))
    np.testing.assert_allclose((coords.matrix @ g.reshape(2, -1).T).T, coords.reduce(g), atol=1e-14)


@pytest.mark.parametrize(
    "pinned", [2, 1, 0], ids=["two layers pinned", "layer pinned", "nothing pinned"]
)
@pytest.mark.parametrize("explicit", [True, False], ids=["explicit", "solves"])
@pytest.mark.parametrize("rows", [1, 2], ids=["volume", "two constraints"])
def test_preconditioner_inverts_the_gauss_newton_matrix(pinned, explicit, rows, monkeypatch):
    """``M^-1`` for ``M = H + ridge + sigma J^T J``, by Woodbury on the factored ``H +
    ridge``, for several sigmas; with nothing pinned ``H`` is singular along the rigid
    motions and the Jacobian has a part along them (a centre of mass moves with them).
    Two layers pinned leave 27 variables: the compiled small inverse where the kernels are
    in use; one constraint takes the scalar Woodbury term."""
    monkeypatch.setattr(precondition, "EXPLICIT", 10_000 if explicit else 0)
    rng = np.random.default_rng(5)
    rest = _rest()
    net = SpringNetwork.for_lattice((3, 3, 3), rest)
    free = np.ones((27, 3), bool)
    free[: 9 * pinned] = False  # layers pinned
    coords = Coordinates(free, np.zeros(3), 1.0)
    h = coords.restrict(net.hessian(rest))
    jac = rng.standard_normal((2, coords.count))
    jac[1] += 3.0 * np.tile([1.0, 0.0, 0.0], coords.count // 3)  # along a translation
    jac = jac[2 - rows :]
    pre = Preconditioner(Curvature(h), jac)
    assert (pre.curvature.inverse is not None) == explicit
    a = h + RIDGE * np.trace(h) / len(h) * np.eye(len(h))  # the ridge keeps it invertible
    n, eps = coords.count, np.finfo(np.float64).eps
    for sigma in (7.0, 700.0, 7.0):
        m = a + sigma * jac.T @ jac
        v = rng.standard_normal(coords.count)
        residual = np.linalg.norm(m @ pre.at(sigma)(v) - v) / np.linalg.norm(v)
        # M^-1 v is A^-1 v less the Woodbury correction. Along the rigid motions (nothing
        # pinned) both are about |A^-1 v|, far larger than their difference, and each
        # carries rounding of n eps |A^-1 v| at most (sums of n products); M maps that
        # error to a residual of at most |M| n eps |A^-1 v|. With layers pinned A is well
        # conditioned and the same bound is tiny.
        bound = np.linalg.norm(m, 2) * n * eps * np.linalg.norm(np.linalg.solve(a, v))
        assert residual <= bound / np.linalg.norm(v), (residual, bound)
    assert pre.at(7.0) is pre.at(7.0)  # one product per sigma


@pytest.mark.parametrize(
    "name", ["torus-compression", "torus-stretch", "club-bend", "club-compression"]
)
def test_the_preconditioned_solve_meets_the_goal_in_fewer_steps_never_worse(name):
    problem = build(example_scenario(name))
    s = problem.surface
    results = {
        on: run_to_end(
            solve(
                s,
                problem.nodes,
                problem.fixed,
                goal=problem.scenario.goal,
                options=replace(problem.options, precondition=on),
            )
        )
        for on in (False, True)
    }
    plain, pre = results[False], results[True]
    assert plain.converged and pre.converged, (plain.message, pre.message)
    assert abs(pre.rel_volume_error) <= problem.options.tol_volume
    # never a worse minimum of the spring energy (within the solver's tolerances); the
    # torus stretch has a symmetric saddle at 0.3137 that a solve can stop on
    assert pre.energy <= plain.energy * (1 + 2e-3)
    steps = {on: sum(lv.steps for lv in r.levels) for on, r in results.items()}
    if name != "torus-stretch":  # (where the plain solve may stop early, on the saddle)
        assert steps[True] < steps[False], steps


def _dragged(problem):
    lattice = problem.surface.lattice
    x, fixed = problem.nodes.copy(), problem.fixed.copy()
    r = lattice.index(2, 2, 2)
    fixed[r] = True
    x[r] += 0.08 * lattice.size
    return x, fixed, r


@pytest.fixture(scope="module")
def fine_torus():
    """The torus example on a pyramid whose finest level is above the live limit."""
    problem = build(example_scenario("torus-compression"))
    opts = SolverOptions(live_triangles=4096)
    assert problem.surface.levels[-1].n_faces > opts.live_triangles
    return problem, opts


def test_live_frames_never_touch_the_full_mesh_and_release_measures_it(fine_torus):
    problem, opts = fine_torus
    surface = EmbeddedSurface(problem.surface.lattice, problem.surface.levels)
    x, fixed, r = _dragged(problem)
    top = live_level(surface, opts.live_triangles)
    assert surface.levels[top].n_faces <= opts.live_triangles < surface.levels[top + 1].n_faces
    result = None
    for _ in range(5):  # five frames of a drag, each from the frame before
        result = run_to_end(solve(surface, x, fixed, options=opts, live=True))
        assert result.preview and result.converged, result.message
        assert result.terminal_level == top
        assert result.folds is None
        assert abs(result.constraint_error) <= opts.tol_volume
        x = np.array(result.nodes)
        x[r] += 0.003 * surface.lattice.size
    full = len(surface.levels) - 1
    assert full not in surface._cache, "a live frame built the full level"
    assert "fold_check" not in surface.__dict__
    # the solve on release starts near the last frame and measures the full mesh
    release = run_to_end(solve(surface, np.array(result.nodes), fixed, options=opts, near=True))
    assert release.converged and not release.preview, release.message
    assert abs(release.rel_volume_error) <= opts.tol_volume
    assert release.folds is not None and not release.folds.folded
    # released from the drag or solved afresh: the same edit, the same spring energy
    fresh = run_to_end(solve(surface, np.array(result.nodes), fixed, options=opts))
    assert release.energy == pytest.approx(fresh.energy, rel=2e-3)


def test_a_live_frame_on_a_small_model_solves_its_full_mesh(fine_torus):
    problem, _ = fine_torus
    opts = SolverOptions(live_triangles=10**9)
    x, fixed, _ = _dragged(problem)
    result = run_to_end(solve(problem.surface, x, fixed, options=opts, live=True))
    assert result.preview and result.converged
    assert result.terminal_level == len(problem.surface.levels) - 1


def test_the_first_record_comes_before_the_fold_guard_samples(fine_torus):
    problem, opts = fine_torus
    surface = EmbeddedSurface(problem.surface.lattice, problem.surface.levels)
    assert "rest_volume" in surface.__dict__  # measured when the surface is made
    x, fixed, _ = _dragged(problem)
    run = solve(surface, x, fixed, options=opts, goal=Goal())
    first = next(run)
    assert first.step == 0
    assert "interior" not in surface.__dict__  # the slow part comes after
    run.close()


def test_prepare_sets_up_what_the_first_solve_needs(fine_torus):
    problem, opts = fine_torus
    surface = EmbeddedSurface(problem.surface.lattice, problem.surface.levels).prepare(opts)
    assert {"springs", "bodies", "interior", "fold_check"} <= set(surface.__dict__)
    full = len(surface.levels) - 1
    assert full in surface._cache and live_level(surface, opts.live_triangles) in surface._cache


def test_a_drag_shares_the_curvature_and_a_fresh_solve_takes_its_own(
    fine_torus, monkeypatch, evaluation_path
):
    """A drag's frames and its release take the preconditioner's curvature from the solve
    before while the nodes stay near; a fresh solve makes its own, so solving the same
    edit again gives the same nodes whatever was solved in between. (On one evaluation
    path throughout: the compiled one rounds differently.)"""
    from isochor.core.solve import solver

    made = []
    real = solver.Curvature
    monkeypatch.setattr(solver, "Curvature", lambda h: made.append(1) or real(h))
    problem, opts = fine_torus
    surface = EmbeddedSurface(problem.surface.lattice, problem.surface.levels)
    x, fixed, r = _dragged(problem)
    first = run_to_end(solve(surface, x, fixed, options=opts))
    assert first.converged and made
    result, before = first, len(made)
    for _ in range(5):  # frames of 0.1% of the size: all near the curvature taken
        nodes = np.array(result.nodes)
        nodes[r] += 1e-3 * surface.lattice.size
        result = run_to_end(solve(surface, nodes, fixed, options=opts, live=True))
        assert result.converged
    release = run_to_end(solve(surface, np.array(result.nodes), fixed, options=opts, near=True))
    assert release.converged and len(made) == before
    edit = np.array(release.nodes)  # a new edit, near where the drag's curvature was taken
    edit[r] += 1e-4 * surface.lattice.size
    again = run_to_end(solve(surface, edit, fixed, options=opts))
    assert len(made) > before
    elsewhere = EmbeddedSurface(surface.lattice, surface.levels)  # nothing solved before
    assert np.array_equal(
        again.nodes, run_to_end(solve(elsewhere, edit, fixed, options=opts)).nodes
    )
