"""Progress: the command line's one updating line on a terminal (and nothing in a pipe),
checked out of process; the API's progress callback for loading and solving."""

from __future__ import annotations

import io
import os
import pty
import select
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh

import isochor
from isochor.app.cli.console import ProgressLine

#: the line shows at once (a built-in example loads and solves in well under a second)
AT_ONCE = {"ISOCHOR_PROGRESS_AFTER": "0", "OPENBLAS_NUM_THREADS": "1"}
COMMAND = [sys.executable, "-m", "isochor", "solve", "--example", "torus-compression", "-q"]


def _read_all(fd: int, proc: subprocess.Popen, timeout: float = 120) -> bytes:
    """Everything written to the pty's ``fd`` until the child ends."""
    out, end = b"", time.monotonic() + timeout
    while time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            try:
                data = os.read(fd, 4096)
            except OSError:  # the child closed its side
                break
            if not data:
                break
            out += data
        elif proc.poll() is not None:
            break
    return out


def test_the_progress_line_shows_on_a_terminal_and_is_wiped():
    leader, follower = pty.openpty()
    env = dict(os.environ, **AT_ONCE)
    proc = subprocess.Popen(COMMAND, stdout=subprocess.PIPE, stderr=follower, env=env)
    os.close(follower)
    try:
        seen = _read_all(leader, proc)
        proc.wait(timeout=120)
    finally:
        os.close(leader)
    assert proc.returncode == 0, seen
    text = seen.decode()
    assert "\risochor: solving" in text and "%" in text
    assert "\n" not in text  # one line, rewritten in place
    assert text.endswith("\r") and text.rsplit("\r", 2)[-2].strip() == ""  # wiped at the end
    assert proc.stdout.read() == b""  # -q: nothing on standard output


def test_nothing_extra_in_a_pipe():
    env = dict(os.environ, **AT_ONCE)
    proc = subprocess.run(COMMAND, capture_output=True, env=env, timeout=120, check=False)
    assert proc.returncode == 0
    assert proc.stderr == b"" and proc.stdout == b""


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_line_waits_for_a_stage_to_take_long():
    stream = _Terminal()
    line = ProgressLine(stream, after=0.3, tick=0.05)
    line("load", 0.1)
    assert stream.getvalue() == ""  # too early
    time.sleep(0.45)
    line("load", 0.5)
    end = time.monotonic() + 5
    while "50%" not in stream.getvalue() and time.monotonic() < end:
        time.sleep(0.05)  # the ticker redraws it (a few times a second)
    assert "\risochor: loading the model  50%" in stream.getvalue()
    line("load", 1.0)  # the stage ends: the line goes
    assert stream.getvalue().endswith("\r")
    line.close()
    quiet = io.StringIO()  # not a terminal: nothing at all
    pipe_line = ProgressLine(quiet, after=0.0)
    pipe_line("solve", 0.5)
    pipe_line.close()
    assert quiet.getvalue() == ""


def _stages(calls: list[tuple[str, float]]) -> list[str]:
    return [s for i, (s, _) in enumerate(calls) if i == 0 or calls[i - 1][0] != s]


def _check_fractions(calls: list[tuple[str, float]]) -> None:
    for stage in {s for s, _ in calls}:
        f = [x for s, x in calls if s == stage]
        assert f[0] == 0.0 and f[-1] == 1.0
        assert all(0.0 <= a <= b <= 1.0 for a, b in zip(f, f[1:])), (stage, f)


def test_load_and_session_report_loading_then_each_solve(tmp_path):
    path = tmp_path / "ball.obj"
    trimesh.creation.icosphere(3).export(path)
    calls: list[tuple[str, float]] = []
    session = isochor.load(path, progress=lambda stage, f: calls.append((stage, f)))
    assert _stages(calls) == ["load"]
    _check_fractions(calls)
    calls.clear()
    session.move((2, 1, 1), by=(0.2, 0.0, 0.0))
    assert session.solve().converged
    assert _stages(calls) == ["solve"] and len(calls) > 3
    _check_fractions(calls)


def test_deform_reports_progress_and_a_bad_callback_is_refused():
    calls: list[tuple[str, float]] = []
    ball = trimesh.creation.icosphere(3)
    out = isochor.deform(
        ball, (3, 3, 3), moves={(2, 1, 1): (0.3, 0, 0)}, progress=lambda s, f: calls.append((s, f))
    )
    assert out.converged and _stages(calls) == ["load", "solve"]
    _check_fractions(calls)
    # the same result as without a callback: progress only listens
    plain = isochor.deform(ball, (3, 3, 3), moves={(2, 1, 1): (0.3, 0, 0)})
    np.testing.assert_array_equal(out.result.nodes, plain.result.nodes)
    with pytest.raises(isochor.IsochorError, match="progress"):
        isochor.deform(ball, (3, 3, 3), progress="yes")
