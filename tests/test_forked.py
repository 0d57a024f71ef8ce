"""The forked child (:mod:`isochor.core.forked`): the function's result, progress and
exceptions come back; its memory does not stay here; where the process cannot fork (another
thread running) or the child dies, the function runs here; the level pyramid made in a child
is the one made in place, bit for bit."""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest

from isochor.core import forked
from isochor.core.errors import IsochorError
from isochor.core.scenario import problem
from isochor.core.scenario.shapes import builtin_levels
from isochor.core.solve.pyramid import build_pyramid

needs_fork = pytest.mark.skipif(
    not forked.can_fork(), reason="this process cannot fork safely (no os.fork, or threads)"
)


def _pid(progress=None):
    for f in (0.25, 0.5, 1.0):
        progress(f)
    return os.getpid()


def _fails(progress=None):
    raise IsochorError("a message from the child")


def _big(n, progress=None):
    a = np.ones(n)  # touched: resident in whichever process runs this
    return float(a.sum())


def _high_water_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    pytest.skip("no /proc/self/status here")


@needs_fork
def test_the_result_and_progress_come_from_a_child():
    seen: list[float] = []
    pid = forked.call(_pid, progress=seen.append)
    assert pid != os.getpid()
    assert seen == [0.25, 0.5, 1.0]


@needs_fork
def test_an_error_in_the_child_is_raised_here():
    with pytest.raises(IsochorError, match="a message from the child"):
        forked.call(_fails)


@needs_fork
def test_the_childs_memory_does_not_stay_here():
    n = 40 * 2**20 // 8 * 8  # 320 MB of float64, touched in the child only
    before = _high_water_mb()
    assert forked.call(_big, n) == float(n)
    assert _high_water_mb() < before + 100


def test_with_another_thread_running_it_runs_here():
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert not forked.can_fork()
        assert forked.call(_pid, progress=lambda f: None) == os.getpid()
    finally:
        stop.set()
        other.join()


def _dies_in_child(parent, progress=None):
    if os.getpid() != parent:
        os.kill(os.getpid(), signal.SIGKILL)
    return "here"


@needs_fork
def test_a_child_that_dies_leaves_the_work_to_this_process():
    assert forked.call(_dies_in_child, os.getpid()) == "here"


@needs_fork
def test_the_pyramid_made_in_a_child_is_the_one_made_in_place(monkeypatch):
    mesh = builtin_levels("torus")[-1]
    monkeypatch.setattr(problem, "APART_TRIANGLES", 0)
    seen: list[tuple[str, float]] = []
    apart = problem.pyramid_of(mesh, 1, lambda stage, f: seen.append((stage, f)))
    here = build_pyramid(mesh, bodies=1)
    assert len(apart) == len(here) > 2
    assert apart[-1] is mesh
    for a, b in zip(apart, here):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert not a.vertices.flags.writeable and not a.faces.flags.writeable
    fractions = [f for _, f in seen]
    assert fractions[0] == 0.0 and fractions[-1] == 1.0 and fractions == sorted(fractions)
