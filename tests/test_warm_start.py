"""Where a solve starts: a drag that changed the volume is seen on the levels below the full
mesh, so the full mesh is evaluated once (for the result), never on the way in."""

import numpy as np
import pytest

from isochor.core import kernels
from isochor.core.goal.spec import Goal
from isochor.core.scenario.examples import example_scenario
from isochor.core.scenario.problem import build
from isochor.core.solve import multilevel
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.solver import SolverOptions

EXAMPLES = ("torus-compression", "torus-stretch", "club-compression")
#: the volume alone, and with the centre of mass (three more constraints per level)
GOALS = {"volume": Goal(), "centroid": Goal(keep_centroid=True)}


class _Counting:
    """A volume operator that counts its volume-only evaluations."""

    def __init__(self, op) -> None:
        self.op, self.calls = op, 0

    def __call__(self, *args):
        self.calls += 1
        return self.op(*args)

    def __getattr__(self, name):
        return getattr(self.op, name)


def _solve(problem, nodes=None, goal=None):
    records = []
    start = problem.nodes if nodes is None else nodes
    gen = multilevel.solve(problem.surface, start, problem.fixed, goal=goal)
    return records, run_to_end(gen, records.append)


@pytest.fixture(scope="module", params=EXAMPLES)
def solved(request):
    problem = build(example_scenario(request.param))
    _, result = _solve(problem)
    assert result.converged
    return problem, result


@pytest.fixture(scope="module", params=[(e, g) for e in EXAMPLES for g in GOALS])
def solved_goal(request):
    example, goal = request.param
    problem = build(example_scenario(example))
    _, result = _solve(problem, goal=GOALS[goal])
    assert result.converged
    return problem, result, GOALS[goal]


def _first(surface) -> int:
    opts = SolverOptions()
    return next(
        (k for k, m in enumerate(surface.levels) if m.n_faces >= opts.start_triangles),
        len(surface.levels) - 1,
    )


def test_a_drag_evaluates_the_full_mesh_once_and_solves_as_before(solved, monkeypatch):
    problem, _ = solved
    full = problem.surface.level(-1)
    counting = _Counting(full.volume_op)
    monkeypatch.setattr(full, "volume_op", counting)
    # both solves on one evaluation path: the compiled kernels may finish loading between
    # them, and the two paths agree to rounding only, not bit for bit
    with kernels.numpy_path():
        full._last = (None, 0.0)  # forget the memo of an earlier solve
        records, result = _solve(problem)
        # the result's measurement, after the last record; none where the solve ended on
        # the full mesh (its last evaluation there left the volume in the level's memo)
        measured = 0 if result.terminal_level == len(problem.surface.levels) - 1 else 1
        assert counting.calls == measured
        # the same solve as when the full mesh decides where to start
        monkeypatch.setattr(multilevel, "_missed", lambda *args: False)
        full._last = (None, 0.0)
        before, again = _solve(problem)
    assert counting.calls == 2 * measured + 1  # the start, then the result as before
    assert [r.level for r in records] == [r.level for r in before]
    assert np.array_equal(result.nodes, again.nodes) and result.converged == again.converged


def test_a_level_proves_a_miss_only_where_the_full_mesh_misses(solved_goal):
    """Between the user's edit and the converged result, and around the result at random,
    a level below the full mesh says "missed" only where the full mesh misses the goal,
    and says it for the edit itself."""
    problem, result, goal = solved_goal
    surface, opts = problem.surface, SolverOptions()
    n = len(surface.levels)

    def constraints(k):
        return surface.constraints(k, goal)

    def full_misses(x):
        return np.max(np.abs(constraints(n - 1).values(x))) > opts.tol_volume

    def missed(x):
        return multilevel._missed(constraints, n, x, opts, _first(surface))

    edit, done = problem.nodes, result.nodes
    assert missed(edit) and full_misses(edit)
    assert not missed(done) and not full_misses(done)
    rng = np.random.default_rng(3)
    free = ~problem.fixed
    cases = [done + t * (edit - done) for t in np.geomspace(1e-4, 1.0, 25)]
    for scale in np.geomspace(1e-4, 3e-2, 12):
        nudge = np.where(free, rng.standard_normal(done.shape), 0.0)
        cases.append(done + scale * surface.size * nudge)
    proved = [missed(x) for x in cases]
    assert all(full_misses(x) for x, p in zip(cases, proved) if p)
    assert any(proved) and not all(proved)  # the sweep crosses the tolerance


def test_a_converged_result_restarts_without_steps(solved):
    problem, result = solved
    _, again = _solve(problem, result.nodes)
    assert again.converged and sum(s.steps for s in again.levels) <= 5
