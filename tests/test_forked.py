"""The forked child (:mod:`isochor.core.forked`): the function's result, progress and
exceptions come back; its memory does not stay here; where the process cannot fork (another
thread running) or the child dies, the function runs here; the level pyramid made in a child
is the one made in place, bit for bit; the command forks before it loads numba.

A test process that already runs other threads (numba loading, the kernels' pool) cannot
fork: the checks that need a child then run in a fresh interpreter without numba."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from contextlib import ExitStack
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

from isochor.core import forked
from isochor.core.errors import IsochorError
from isochor.core.scenario import problem
from isochor.core.scenario.shapes import builtin_levels
from isochor.core.solve.pyramid import build_pyramid

ROOT = Path(__file__).resolve().parents[1]


def _apart(check) -> None:
    """Run ``check`` here if this process can fork, else in a fresh interpreter."""
    if forked.can_fork():
        check()
        return
    if not sys.platform.startswith("linux"):
        pytest.skip("forks only on Linux: elsewhere the function always runs in place")
    env = dict(os.environ, ISOCHOR_NO_JIT="1")
    code = f"import tests.test_forked as t; t.{check.__name__}()"
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-3000:]


def _pid(progress=None):
    for f in (0.25, 0.5, 1.0):
        progress(f)
    return os.getpid()


def _fails(progress=None):
    raise IsochorError("a message from the child")


def _big(n, progress=None):
    a = np.ones(n)  # touched: resident in whichever process runs this
    return float(a.sum())


def _dies_in_child(parent, progress=None):
    if os.getpid() != parent:
        os.kill(os.getpid(), signal.SIGKILL)
    return "here"


def _high_water_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    raise AssertionError("no VmHWM in /proc/self/status")


def check_result_and_progress_come_from_a_child():
    assert forked.can_fork()
    seen: list[float] = []
    assert forked.call(_pid, progress=seen.append) != os.getpid()
    assert seen == [0.25, 0.5, 1.0]


def check_an_error_in_the_child_is_raised_here():
    assert forked.can_fork()
    with pytest.raises(IsochorError, match="a message from the child"):
        forked.call(_fails)


def check_the_childs_memory_does_not_stay_here():
    assert forked.can_fork()
    n = 40 * 2**20  # 320 MB of float64, touched in the child only
    before = _high_water_mb()
    assert forked.call(_big, n) == float(n)
    assert _high_water_mb() < before + 100


def check_a_child_that_dies_leaves_the_work_to_this_process():
    assert forked.can_fork()
    assert forked.call(_dies_in_child, os.getpid()) == "here"


def check_the_pyramid_made_in_a_child_is_the_one_made_in_place():
    assert forked.can_fork()
    mesh = builtin_levels("torus")[-1]
    seen: list[float] = []
    with mock.patch.object(problem, "APART_TRIANGLES", 0):
        apart = problem.pyramid_of(mesh, 1, lambda stage, f: seen.append(f))
    here = build_pyramid(mesh, bodies=1)
    assert len(apart) == len(here) > 2
    assert apart[-1] is mesh
    for a, b in zip(apart, here):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert not a.vertices.flags.writeable and not a.faces.flags.writeable
    assert seen[0] == 0.0 and seen[-1] == 1.0 and seen == sorted(seen) and len(seen) > 3


def check_the_command_forks_then_loads_numba_then_builds():
    """A big model's command starts numba only once the pyramid is made (so the process
    still runs one thread when it forks) and waits for it before building the problem
    (built on the path the solve takes)."""
    from isochor.app.cli import opening
    from isochor.assets import ASSETS_DIR
    from isochor.core import api, kernels
    from isochor.core.scenario.document import Scenario

    order: list = []
    real_build, real_call = api.build, forked.call

    def call(fn, *args, **kwargs):
        order.append(("fork", forked.can_fork()))
        return real_call(fn, *args, **kwargs)

    def start(auto=False):  # (with auto: nothing, where the command turned autostart off)
        if not auto:
            order.append("start numba")

    patches = [
        mock.patch.object(kernels, "WORTH_BYTES", 0),  # the torus file is big enough
        mock.patch.object(problem, "APART_TRIANGLES", 0),
        mock.patch.object(kernels, "start", start),
        mock.patch.object(kernels, "ready", lambda timeout=None: order.append("numba")),
        mock.patch.object(forked, "call", call),
        mock.patch.object(
            api, "build", lambda *a, **k: order.append("build") or real_build(*a, **k)
        ),
    ]
    before = kernels.set_autostart(True)
    try:
        with ExitStack() as stack:
            for p in patches:
                stack.enter_context(p)
            scenario = Scenario.from_dict({"model": {"path": str(ASSETS_DIR / "torus.obj")}})
            session = opening.open_session(scenario)
        autostart = kernels.set_autostart(True)  # as the command left it (restored below)
    finally:
        kernels.set_autostart(before)
    assert session.problem.surface.full.n_faces > 0
    assert order[:2] == [("fork", True), "numba"] and "build" in order[2:], order
    assert "start numba" not in order
    assert autostart is False  # the command's own choice: numba only where it pays


def test_the_result_and_progress_come_from_a_child():
    _apart(check_result_and_progress_come_from_a_child)


def test_an_error_in_the_child_is_raised_here():
    _apart(check_an_error_in_the_child_is_raised_here)


def test_the_childs_memory_does_not_stay_here():
    _apart(check_the_childs_memory_does_not_stay_here)


def test_a_child_that_dies_leaves_the_work_to_this_process():
    _apart(check_a_child_that_dies_leaves_the_work_to_this_process)


def test_the_pyramid_made_in_a_child_is_the_one_made_in_place():
    _apart(check_the_pyramid_made_in_a_child_is_the_one_made_in_place)


def test_the_command_forks_then_loads_numba_then_builds():
    _apart(check_the_command_forks_then_loads_numba_then_builds)


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
