"""The solve worker (isochor.app.session.worker) without a window.

The body of a solve's thread, :meth:`SolveJob.run`, is run synchronously on the test's
thread (as superqt's ``tests/test_threadworker.py`` runs its workers' ``work``): what it
emits for a solve that ends, one that is stopped while a step runs and one that raises.
Then the real thread: once :meth:`SolveWorker.stop` returns, the stopped solve emits
nothing more, counted where the signal is emitted (a direct connection, on the solver's
thread), not where a queued copy would arrive.
"""

from __future__ import annotations

import inspect
import threading
import time

import numpy as np
import pytest
from PySide6.QtCore import Qt

from isochor.app.session.worker import HOLD_LIMIT, SolveJob, SolveWorker
from isochor.core import kernels
from isochor.core.errors import IsochorError
from isochor.core.scenario.examples import example_scenario
from isochor.core.scenario.problem import build
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import solve


class Emitted:
    """Every signal of one worker, in the order emitted: ``(name, generation, payload)``."""

    def __init__(self, worker: SolveWorker, connection=Qt.ConnectionType.AutoConnection):
        self.log: list[tuple[str, int, object]] = []
        self.stopped = threading.Event()  #: set by the test once stop() returned
        self.after_stop = 0  #: signals emitted after that
        for name in ("progress", "finished", "failed"):
            getattr(worker, name).connect(
                lambda gen, payload, name=name: self._record(name, gen, payload), connection
            )

    def _record(self, name: str, gen: int, payload) -> None:
        if self.stopped.is_set():
            self.after_stop += 1
        self.log.append((name, gen, payload))

    def names(self) -> list[str]:
        return [name for name, _, _ in self.log]


def counting(n: int, closed: list[str], stop_at: int | None = None, job=None):
    """Yield 0 .. n-1 and return ``"done"``; at step ``stop_at`` stop ``job`` first (a stop
    that arrives while a step runs). ``closed`` learns how the generator ended."""
    try:
        for i in range(n):
            if i == stop_at:
                job[0].stop()
            yield i
        return "done"
    except GeneratorExit:
        closed.append("closed")
        raise
    finally:
        closed.append("finally")


@pytest.fixture
def worker(qapp):
    w = SolveWorker()
    yield w
    w.shutdown(timeout=5.0)


def test_a_solve_run_synchronously_emits_each_record_then_its_result(worker):
    problem = build(example_scenario("torus-compression"))
    s = problem.surface
    args = (s, problem.nodes, problem.fixed)
    with kernels.numpy_path():  # both runs on one evaluation path: the same numbers
        direct: list = []
        expected = run_to_end(solve(*args, options=problem.options), direct.append)
        emitted = Emitted(worker)
        job = SolveJob(worker, 7, lambda: solve(*args, options=problem.options))
        job.run()
    assert emitted.names() == ["progress"] * len(direct) + ["finished"]
    assert {gen for _, gen, _ in emitted.log} == {7}
    for (_, _, record), want in zip(emitted.log, direct, strict=False):
        np.testing.assert_array_equal(record.nodes, want.nodes)
    result = emitted.log[-1][2]
    np.testing.assert_array_equal(result.nodes, expected.nodes)
    assert result.converged
    assert abs(result.rel_volume_error) <= problem.scenario.tol_volume
    assert job.make is None, "the job lets go of the problem"
    assert not worker.stepping_now()


def test_a_stop_during_a_step_emits_nothing_more_and_closes_the_generator(worker):
    emitted = Emitted(worker)
    closed: list[str] = []
    holder: list[SolveJob] = []
    job = SolveJob(worker, 3, lambda: counting(10, closed, stop_at=4, job=holder))
    holder.append(job)
    job.run()
    # records 0-3 went out; record 4 was made by the step the stop arrived in: dropped
    assert emitted.log == [("progress", 3, i) for i in range(4)]
    assert closed == ["closed", "finally"], "closed on the thread that ran it"
    assert job.stop_flag.is_set()


def test_a_job_stopped_before_it_runs_emits_nothing(worker):
    emitted = Emitted(worker)
    closed: list[str] = []
    made = [counting(5, closed)]
    job = SolveJob(worker, 1, lambda: made[0])
    job.stop()
    job.run()
    assert emitted.log == []
    assert closed == [], "not one step ran"
    assert inspect.getgeneratorstate(made[0]) == inspect.GEN_CLOSED


def test_a_generator_that_ends_emits_what_it_returns(worker):
    emitted = Emitted(worker)
    closed: list[str] = []
    SolveJob(worker, 2, lambda: counting(3, closed)).run()
    assert emitted.log == [("progress", 2, 0), ("progress", 2, 1), ("progress", 2, 2)] + [
        ("finished", 2, "done")
    ]
    assert closed == ["finally"]


def test_failures_are_one_message(worker, capsys):
    def raising(exc):
        yield 0
        raise exc

    emitted = Emitted(worker)
    SolveJob(worker, 4, lambda: raising(IsochorError("the lattice folds"))).run()
    SolveJob(worker, 5, lambda: raising(ValueError("bad"))).run()
    assert emitted.log == [
        ("progress", 4, 0),
        ("failed", 4, "the lattice folds"),
        ("progress", 5, 0),
        ("failed", 5, "The solver failed unexpectedly: ValueError: bad"),
    ]
    err = capsys.readouterr().err
    assert "Traceback" in err and "ValueError: bad" in err, "an unexpected error is printed"
    assert "the lattice folds" not in err, "an expected one is not"


def test_a_held_worker_steps_after_the_hold_limit(worker):
    """A frame that never releases the worker holds each step at most HOLD_LIMIT."""
    emitted = Emitted(worker)
    worker.hold()
    t0 = time.perf_counter()
    SolveJob(worker, 6, lambda: counting(2, [])).run()
    waited = time.perf_counter() - t0
    assert emitted.names() == ["progress", "progress", "finished"]
    assert waited >= 3 * HOLD_LIMIT, "three steps (two records and the end), each held"
    worker.release()


def test_nothing_is_emitted_after_stop_returns_on_the_real_thread(worker):
    """A solve that yields forever, stopped while it runs: counted on the solver's thread."""
    started = threading.Event()

    def forever():
        i = 0
        while True:
            started.set()
            yield i
            i += 1

    emitted = Emitted(worker, Qt.ConnectionType.DirectConnection)
    gen = worker.run(forever)
    assert started.wait(10.0)
    deadline = time.monotonic() + 10.0
    while not emitted.log and time.monotonic() < deadline:  # a record out before the stop
        time.sleep(0.001)
    worker.stop()
    emitted.stopped.set()
    assert not worker.is_running()
    before = len(emitted.log)
    assert worker.shutdown(timeout=10.0), "the thread ended"
    assert emitted.after_stop == 0, f"{emitted.after_stop} signals after stop() returned"
    assert len(emitted.log) == before
    assert before >= 1 and {g for _, g, _ in emitted.log} == {gen}
    assert set(emitted.names()) == {"progress"}
    assert [p for _, _, p in emitted.log] == list(range(before)), "in order, none lost"
