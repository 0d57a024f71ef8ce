"""The compiled pieces of the solver's own step (core/kernels/solver.py through kernels.step):
the spring energy, gradient and Hessian and the L-BFGS memory and recursion give the NumPy
path's numbers, a broken one leaves the NumPy path in place, and a solve keeps one path."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from isochor.core import kernels
from isochor.core.goal.spec import Goal
from isochor.core.kernels import step as stepkernels
from isochor.core.kernels.pairs import Pairs
from isochor.core.lattice import Lattice
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.lbfgs import lbfgs
from isochor.core.solve.multilevel import solve
from isochor.core.solve.precondition import Curvature, Product
from isochor.core.springs import SpringNetwork


def network(shape, seed):
    """A lattice's springs, its nodes moved so that some springs stretch, some compress
    and one has zero length."""
    rng = np.random.default_rng(seed)
    lat = Lattice(shape, (0.0, 0.0, 0.0), np.diag([2.0, 1.0, 1.5]))
    net = SpringNetwork.for_lattice(shape, lat.rest_nodes)
    x = lat.rest_nodes * rng.uniform(0.6, 1.4, size=3)
    x += rng.normal(scale=0.2, size=x.shape)
    a, b = net.edges[0]
    x[b] = x[a]  # a spring of zero length
    return net, x


@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 3, 3), (5, 4, 3), (8, 8, 8)])
def test_springs_match_numpy(compiled, shape):
    net, x = network(shape, sum(shape))
    e, g = net.energy_and_gradient(x)
    h = net.hessian(x)
    with kernels.numpy_path():
        e0, g0 = net.energy_and_gradient(x)
        h0 = net.hessian(x)
    assert e == pytest.approx(e0, rel=1e-12)
    assert np.abs(g - g0).max() <= 1e-12 * np.abs(g0).max()
    assert np.abs(h - h0).max() <= 1e-12 * np.abs(h0).max()
    assert np.all(np.isfinite(g)) and np.allclose(h, h.T)


def filled(n, pushes, seed, numpy):
    """Pairs of a quadratic's steps, pushed through the compiled kernel or NumPy; every
    third step has negative curvature and must be dropped."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    a = a @ a.T + n * np.eye(n)
    pairs, x, g = Pairs(5, n), np.zeros(n), np.zeros(n)
    for i in range(pushes):
        x_new = x + rng.normal(size=n)
        g_new = g + (-1 if i % 3 == 2 else 1) * a @ (x_new - x)
        if numpy:
            pairs.push(x_new, x, g_new, g)
        else:
            pairs.stored(stepkernels.push_pair(pairs, x_new, x, g_new, g))
        x, g = x_new, g_new
    return pairs, a


@pytest.mark.parametrize("pushes", [0, 1, 4, 9, 17])
def test_the_memory_and_the_recursion_match_numpy(compiled, pushes):
    n = 23
    fast, a = filled(n, pushes, pushes, numpy=False)
    slow, _ = filled(n, pushes, pushes, numpy=True)
    assert (fast.head, fast.count) == (slow.head, slow.count)
    assert fast.count == min(5, pushes - pushes // 3)  # the negative pairs were dropped
    live = [(fast.head - 1 - i) % 5 for i in range(fast.count)]
    assert np.array_equal(fast.s[live], slow.s[live])
    assert np.allclose(fast.rho[live], slow.rho[live])
    g = np.random.default_rng(1).normal(size=n)
    inverse = np.linalg.inv(a)
    for h0 in (None, Product(inverse), inverse.__matmul__):
        kept = g.copy()
        d, g_max, slope = stepkernels.two_loop(fast, g, h0)
        assert np.array_equal(g, kept)  # the gradient is left as it was
        d0 = slow.direction(g.copy(), h0)
        assert np.abs(d - d0).max() <= 1e-12 * np.abs(d0).max()
        assert g_max == np.abs(g).max() and slope == pytest.approx(g @ d0, rel=1e-12)
        if h0 is not None and fast.count == 0:
            assert np.allclose(d, -inverse @ g)  # no pairs: the start matrix alone
        assert g @ d < 0  # a descent direction


def test_lbfgs_with_a_broken_kernel_falls_back_and_converges(compiled, monkeypatch):
    def broken(*args):
        raise RuntimeError("boom")

    fake = SimpleNamespace(two_loop=broken, push_pair=broken, spring_energy_gradient=broken)
    for name, value in (("kernels", fake), ("status", "ready"), ("reason", "")):
        monkeypatch.setattr(kernels._state, name, value)
    rng = np.random.default_rng(3)
    a = rng.normal(size=(12, 12))
    a = a @ a.T + np.eye(12)
    b = rng.normal(size=12)

    def fun(x):
        return 0.5 * x @ a @ x - b @ x, a @ x - b, (0.0, 0.0)

    run = lbfgs(fun, np.zeros(12), gtol=1e-8, max_iter=200)
    try:
        while True:
            next(run)
    except StopIteration as stop:
        x, _, converged = stop.value
    assert converged and np.allclose(x, np.linalg.solve(a, b))
    assert kernels.status().startswith("failed: two_loop: RuntimeError")


@pytest.mark.parametrize("first", ["numpy", "auto"])
def test_a_solve_keeps_the_path_it_started_on(compiled, first):
    """The kernels arriving (or leaving) in the middle of a solve do not change where it
    ends: the two paths round differently, and the same command must give the same nodes."""
    scenario = Scenario({"builtin": "torus", "n_levels": 3}, goal=Goal(target_ratio=10))
    problem = build(scenario)

    def run(switch: bool) -> np.ndarray:
        previous = kernels.set_mode(first)
        try:
            gen = solve(
                problem.surface,
                problem.nodes,
                problem.fixed,
                goal=problem.scenario.goal,
                options=problem.options,
            )
            for _ in range(10):  # into the first level's steps
                next(gen)
            if switch:
                kernels.set_mode("auto" if first == "numpy" else "numpy")
            return run_to_end(gen).nodes
        finally:
            kernels.set_mode(previous)

    assert np.array_equal(run(switch=True), run(switch=False))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_the_recursion_reports_a_gradient_that_is_not_finite(compiled, bad):
    pairs, _ = filled(6, 4, 0, numpy=False)
    g = np.ones(6)
    g[2] = bad
    for h0 in (None, Product(np.eye(6))):
        _, g_max, _ = stepkernels.two_loop(pairs, g, h0)
        assert not np.isfinite(g_max)


@pytest.mark.parametrize("n", [1, 2, 9, 27, stepkernels.SMALL_INVERSE])
def test_the_small_inverse_matches_lapack(compiled, n):
    """The compiled inverse of a small curvature matrix against SciPy's Cholesky path: a
    stiff, badly scaled matrix with a near-null direction (a free rigid motion), which
    only the ridge keeps invertible."""
    rng = np.random.default_rng(n)
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    a = (q * np.geomspace(1e4, 1e-3, n)) @ q.T
    a[:, -1] = a[-1, :] = 0.0  # a free direction
    fast = Curvature(a)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(stepkernels, "SMALL_INVERSE", 0)
        slow = Curvature(a)
    assert fast.ok and slow.ok and slow._factor is not None and fast._factor is None
    ridged = a + 1e-6 * max(np.trace(a) / n, 1e-12) * np.eye(n)
    assert np.abs(fast.inverse @ ridged - np.eye(n)).max() < 1e-6
    assert np.abs(fast.inverse - slow.inverse).max() <= 1e-8 * np.abs(slow.inverse).max()
    assert np.array_equal(fast.inverse, fast.inverse.T)


@pytest.mark.parametrize("how", ["indefinite", "nan", "inf", "large"])
def test_the_small_inverse_refuses_what_is_not_positive_definite(compiled, how):
    n = 12
    a = np.eye(n) * 2.0
    if how == "indefinite":
        a[3, 3] = -1.0
    elif how in ("nan", "inf"):
        a[7, 2] = a[2, 7] = np.nan if how == "nan" else np.inf
    else:  # beyond SMALL_INVERSE: LAPACK's path, which refuses the same way
        n = stepkernels.SMALL_INVERSE + 5
        a = np.eye(n)
        a[0, 0] = -1.0
    assert stepkernels.spd_inverse(a, 1e-6) is (None if how == "large" else False)
    curvature = Curvature(a)
    assert not curvature.ok and curvature.inverse is None
