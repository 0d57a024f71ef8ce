"""The solver's BLAS threads (isochor.core.blas): one while a solve step runs in a program
that did not choose, the program's own setting between the steps and after, untouched
where the user set them; without threadpoolctl everything works unlimited."""

from __future__ import annotations

import sys

import pytest

from isochor.core import blas
from isochor.core.scenario.examples import example_scenario
from isochor.core.scenario.problem import build
from isochor.core.solve.generators import run_to_end
from isochor.core.springs import SpringNetwork

threadpoolctl = pytest.importorskip("threadpoolctl")


def _threads() -> list[int]:
    """Each loaded BLAS library's threads now."""
    blas_libs = threadpoolctl.ThreadpoolController().select(user_api="blas")
    return [lib.num_threads for lib in blas_libs.lib_controllers]


@pytest.fixture
def two_threads(monkeypatch):
    """BLAS on two threads, as NumPy starts in a program that set nothing (skips where a
    library cannot run two); the environment says nothing about threads."""
    for name in blas.CHOICES:
        monkeypatch.delenv(name, raising=False)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        if min(_threads(), default=0) < 2:
            pytest.skip("BLAS cannot run two threads here")
        blas.forget()
        yield
    blas.forget()


@pytest.fixture
def seen_in_steps(monkeypatch):
    """The BLAS threads seen from inside the solve's energy evaluations."""
    seen: list[list[int]] = []
    energy = SpringNetwork.energy_and_gradient

    def watched(self, x):
        if len(seen) < 3:
            seen.append(_threads())
        return energy(self, x)

    monkeypatch.setattr(SpringNetwork, "energy_and_gradient", watched)
    return seen


def test_a_solve_step_runs_blas_on_one_thread_and_gives_the_threads_back(
    two_threads, seen_in_steps
):
    run = build(example_scenario("cup-squeeze")).solve()
    first = next(run)  # the start record: between steps, the program's own threads
    assert first.step == 0 and min(_threads()) == 2
    result = run_to_end(run)
    assert result.converged
    assert seen_in_steps and all(t == [1] * len(t) for t in seen_in_steps), seen_in_steps
    assert min(_threads()) == 2  # after the solve: as the program had them


def test_a_user_who_set_the_threads_keeps_them(two_threads, seen_in_steps, monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    assert run_to_end(build(example_scenario("cup-squeeze")).solve()).converged
    assert seen_in_steps and all(min(t) == 2 for t in seen_in_steps), seen_in_steps


def test_without_threadpoolctl_nothing_is_limited_and_the_solve_works(
    two_threads, seen_in_steps, monkeypatch
):
    monkeypatch.setitem(sys.modules, "threadpoolctl", None)  # import fails
    blas.forget()
    assert run_to_end(build(example_scenario("cup-squeeze")).solve()).converged
    assert seen_in_steps and all(min(t) == 2 for t in seen_in_steps), seen_in_steps


def test_interleaved_solves_share_one_limit_and_leave_none_behind(two_threads):
    """Two solves driven step by step in turn (a program's two sessions), and a step
    that raises: the threads are the program's between every step and after."""
    runs = [build(example_scenario(name)).solve() for name in ("cup-squeeze", "club-bend")]
    done = [False, False]
    while not all(done):
        for i, run in enumerate(runs):
            if done[i]:
                continue
            try:
                next(run)
            except StopIteration:
                done[i] = True
            assert min(_threads()) == 2
    with pytest.raises(ValueError), blas.one_thread():
        assert _threads() == [1] * len(_threads())
        raise ValueError
    assert min(_threads()) == 2


def test_nested_limits_restore_once_at_the_outermost(two_threads):
    with blas.one_thread():
        with blas.one_thread():
            assert max(_threads()) == 1
        assert max(_threads()) == 1  # the inner one left: still limited
    assert min(_threads()) == 2


def test_a_library_that_refuses_the_limit_never_fails_the_solve(two_threads, monkeypatch):
    """threadpoolctl raising as it sets the threads (a BLAS it cannot drive): the solve
    converges unlimited, and the limit is not tried again."""
    calls = []

    def refuse(self, *args, **kwargs):
        calls.append(1)
        raise RuntimeError("this BLAS cannot be limited")

    monkeypatch.setattr(threadpoolctl.ThreadpoolController, "limit", refuse)
    for _ in range(2):
        assert run_to_end(build(example_scenario("cup-squeeze")).solve()).converged
    assert calls == [1]
    assert min(_threads()) == 2


@pytest.mark.parametrize("entry", ["isochor.app.cli.main", "isochor.app.cli.launch"])
def test_the_command_and_the_editor_start_with_one_blas_thread_unless_the_user_chose(entry):
    """Out of process: the ``isochor`` command's module and the ``isochor-editor`` script's
    set one thread before NumPy loads; a user's own variable is kept, and the others are
    then left unset."""
    import os
    import subprocess

    code = (
        f"import os, {entry}, numpy\n"
        "from threadpoolctl import threadpool_info\n"
        "blas = [i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas']\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), min(blas))\n"
    )
    clean = {k: v for k, v in os.environ.items() if k not in blas.CHOICES}
    out = subprocess.run(
        [sys.executable, "-c", code], env=clean, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1", "1"]
    chosen = subprocess.run(
        [sys.executable, "-c", code],
        env={**clean, "OMP_NUM_THREADS": "2"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert chosen.returncode == 0, chosen.stderr
    assert chosen.stdout.split()[0] == "None"  # nothing set beside the user's choice
    if (os.cpu_count() or 1) >= 2:
        assert chosen.stdout.split()[1] == "2"  # OpenBLAS took the user's OMP_NUM_THREADS
