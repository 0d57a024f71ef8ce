"""The recovery file (issue 29 item 2), headless: written atomically into the state folder,
read back to the same scenario, offered only when its process is gone."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from isochor.app.editor import recovery
from isochor.core.errors import IsochorError
from isochor.core.scenario.examples import example_scenario


@pytest.fixture
def state(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    return tmp_path / "isochor"


def test_written_read_back_and_offered_only_when_its_process_is_gone(state, tmp_path):
    sc = example_scenario("torus-stretch")
    mine = recovery.write(sc, title="example", path=tmp_path / "s.json")
    assert mine == recovery.own_file() and mine.is_file()
    assert mine.parent == state and mine.name.startswith(f"recovery-{os.getpid()}-")
    assert recovery.files_of(os.getpid()) == [mine]
    assert not list(state.glob(".*.tmp")), "no temporary file left"
    back = recovery.read(mine)
    assert back.scenario.moves == sc.moves and back.title == "example"
    assert back.path == tmp_path / "s.json"
    assert recovery.left_behind() == [], "this process is running: nothing to offer"
    # a process that ended: its file is offered
    done = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    dead = state / f"recovery-{int(done.stdout)}.json"  # an older version's name
    dead.write_text(mine.read_text())
    assert recovery.left_behind() == [dead]
    recovery.remove(dead)
    recovery.remove(dead)  # twice: nothing to remove
    assert recovery.left_behind() == []
    recovery.remove(mine)
    assert not mine.exists() and not mine.with_suffix(".lock").exists()


_CHILD = """
import os, sys
from isochor.app.editor import recovery
from isochor.core.scenario.examples import example_scenario
f = recovery.write(example_scenario("torus-stretch"), title="child", path=None)
print(f, flush=True)
sys.stdin.readline()
"""


def test_a_killed_writer_is_seen_gone_by_its_lock_and_a_reused_pid_never_hides_it(state):
    """The lock says whether the writer runs, not its pid: after a reboot a new editor
    may get the pid of one killed before it, and neither hides nor overwrites its file."""
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=dict(os.environ),
    )
    try:
        theirs = Path(child.stdout.readline().strip())
        assert theirs.is_file() and theirs.with_suffix(".lock").is_file()
        assert recovery.left_behind() == [], "the writer runs: its lock is held"
        child.kill()
        child.wait(30)
    finally:
        if child.poll() is None:
            child.kill()
    assert recovery.left_behind() == [theirs], "killed: the system let go of its lock"
    # the same file as if written before a reboot by an editor that had this very pid
    ours_then = state / f"recovery-{os.getpid()}-00000000.json"
    theirs.rename(ours_then)
    theirs.with_suffix(".lock").rename(ours_then.with_suffix(".lock"))
    assert recovery.left_behind() == [ours_then], "the same pid, but its lock is free"
    mine = recovery.write(example_scenario("torus-compression"), title="now", path=None)
    assert mine != ours_then and recovery.read(ours_then).title == "child"
    assert recovery.left_behind() == [ours_then]
    recovery.remove(mine)


def test_a_damaged_recovery_file_is_one_clear_error(state):
    state.mkdir(parents=True)
    bad = state / "recovery-1.json"
    bad.write_text(json.dumps({"format": "isochor-recovery", "scenario": {"model": 3}}))
    with pytest.raises(IsochorError, match="cannot be recovered"):
        recovery.read(bad)
