"""The recovery file (issue 29 item 2), headless: written atomically into the state folder,
read back to the same scenario, offered only when its process is gone."""

from __future__ import annotations

import json
import os
import subprocess
import sys

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
    assert mine == state / f"recovery-{os.getpid()}.json" and mine.is_file()
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
    dead = recovery.own_file(int(done.stdout))
    dead.write_text(mine.read_text())
    assert recovery.left_behind() == [dead]
    recovery.remove(dead)
    recovery.remove(dead)  # twice: nothing to remove
    assert recovery.left_behind() == []


def test_a_damaged_recovery_file_is_one_clear_error(state):
    state.mkdir(parents=True)
    bad = state / "recovery-1.json"
    bad.write_text(json.dumps({"format": "isochor-recovery", "scenario": {"model": 3}}))
    with pytest.raises(IsochorError, match="cannot be recovered"):
        recovery.read(bad)
