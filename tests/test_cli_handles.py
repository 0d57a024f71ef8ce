"""The command-line contract of issue 12 (surface handles, symmetric editing), out of
process: the real ``isochor solve`` on version 3 scenarios, every run held to the contract
of :mod:`tests.test_cli_goals` (exit 0 is never a lie, one line for an error, no
traceback)."""

from __future__ import annotations

import numpy as np
import pytest

from isochor.core.api import Session
from isochor.core.goal.symmetry import Mirror
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build
from tests.test_cli_goals import SMALL_TORUS, cow, one_line, scenario, solve, solve_all


def _cow_points():
    """The cow's nose and tail (its vertices of largest and smallest x) and its size."""
    full = build(Scenario(cow(), lattice_nodes=(4, 3, 3))).surface.full
    v = full.vertices
    return v[np.argmax(v[:, 0])], v[np.argmin(v[:, 0])], full.size


def _handle(at, by) -> dict:
    return {"at": [float(a) for a in at], "to": [float(a) + float(b) for a, b in zip(at, by)]}


def test_two_handles_on_the_cow_are_met_by_the_command_line(tmp_path):
    nose, tail, size = _cow_points()
    handles = [_handle(nose, [0, 0.12 * size, 0]), _handle(tail, [-0.05 * size, 0, 0])]
    doc = scenario(cow(), nodes=(4, 3, 3), version=3, handles=handles)
    run = solve(tmp_path, doc, out="cow_out.obj")
    assert run.returncode == 0, run
    r = run.report
    assert r["handles_met"] is True and len(r["handles"]) == 2
    for h, want in zip(r["handles"], handles):
        assert h["to"] == want["to"]
        assert np.linalg.norm(np.subtract(h["reached"], want["to"])) <= 1e-3 * size
        assert h["miss"] <= 1e-3
    # the Python API on the same file solves to the same nodes
    session = Session(tmp_path / "s.json")
    assert session.handles and session.solve().converged
    assert np.allclose(session.nodes, r["nodes"], atol=1e-9 * size)


def test_symmetry_option_gives_a_mirror_symmetric_lattice(tmp_path):
    jobs = [
        {
            "name": f"sym_{axis}",
            "scenario": scenario(SMALL_TORUS, moves=[{"node": [0, 0, 0], "by": [0.3, 0.2, 0.1]}]),
            "args": ["--symmetry", axis],
        }
        for axis in "xyz"
    ]
    for axis, run in zip("xyz", solve_all(tmp_path, jobs)):
        assert run.returncode == 0, run
        r = run.report
        assert r["symmetry"] == axis and r["asymmetry"] < 1e-9
        lattice = build(Scenario.from_dict(jobs[0]["scenario"])).surface.lattice
        assert Mirror.of(lattice, axis).asymmetry(np.array(r["nodes"])) < 1e-9


def test_handles_pulled_apart_are_fitted_with_a_warning(tmp_path):
    nose, _, size = _cow_points()
    handles = [_handle(nose, [0, 0.1 * size, 0]), _handle(nose, [0, -0.1 * size, 0])]
    run = solve(tmp_path, scenario(cow(), nodes=(4, 3, 3), version=3, handles=handles))
    assert run.returncode == 0, run
    assert run.report["handles_met"] is False
    warning = [line for line in run.lines if "least squares" in line]
    assert len(warning) == 1 and warning[0].startswith("isochor: warning: 2 handles cannot")


@pytest.mark.parametrize(
    ("keys", "version", "names"),
    [
        ({"handles": [{"at": [0, 0, 0]}]}, 3, ["handles[0]", "'to'"]),
        ({"handles": [{"at": [0, 0], "to": [0, 0, 0]}]}, 3, ["handles[0].at"]),
        ({"handles": [{"at": [0, 0, 0], "to": [1e300, 0, 0]}]}, 3, ["handles[0].to"]),
        ({"handles": [{"at": [0, 0, 0], "to": [1e9, 0, 0]}]}, 3, ["handles[0]", "wrong unit"]),
        ({"symmetry": "w"}, 3, ["symmetry"]),
        ({"symmetry": "x"}, 2, ["symmetry", '"version": 3']),
        ({"handles": []}, 1, ["handles", '"version": 3']),
    ],
)
def test_bad_handles_and_symmetry_are_one_line(tmp_path, keys, version, names):
    run = solve(tmp_path, scenario(SMALL_TORUS, version=version, **keys))
    one_line(run, 1, *names)
    assert not (tmp_path / "s.r.json").exists()


def test_symmetry_on_a_tilted_frame_is_refused_in_one_line(tmp_path):
    doc = scenario(SMALL_TORUS, version=3, symmetry="x")
    doc["lattice"] = {
        "nodes": [3, 3, 3],
        "frame": {"origin": [-2, -2, -1], "axes": [[4, 1, 0], [-1, 4, 0], [0, 0, 2]]},
    }
    one_line(solve(tmp_path, doc), 1, "symmetry x", "not aligned")
