"""The far side stays (issue 29 item 1): the whole top layer grabbed down, scaled or turned,
one corner or three corners pushed down, a handle dragged, on real models, through
``isochor.Session`` and the command line (out of process).

Each edit pins every rigid motion of the lattice but the handle's, so before the rule held
the far face only while rigid motions were free, the springs carried the whole model along
(the top layer down 0.5: everything down 0.5). Now the ground stays: its lattice nodes do
not move (well within 1 % of the model's size), the volume is kept, and the model's lowest
vertices stay within a few percent (the Bernstein basis lets every node move every point);
with ``anchor: none`` the same edits carry the model 20-28 % of its size.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import isochor
from isochor.core.defaults import TOL_VOLUME
from tests.models import model
from tests.test_cli_goals import solve_all

UP = 1  #: the models stand on y
CASES = ("grab", "scale", "rotate", "corner", "corners3", "handle")
#: the far face's nodes stay within this fraction of the model's size (the issue's 1 %)
FAR_NODES = 0.01
#: the model's lowest 5 % stays within this fraction: what holding the ground gives with
#: Bernstein weights (1-3 % measured on spot, kitten and fertility; a carried model: 20 %+)
FAR_VERTICES = 0.05


def layer(lattice, axis: int, index: int) -> list[int]:
    """The node rows of one lattice layer."""
    return [r for r in range(lattice.n_nodes) if lattice.ijk(r)[axis] == index]


def top_corners(lattice) -> list[int]:
    l, m, n = lattice.shape
    return [lattice.index(i, m - 1, k) for i, k in [(0, 0), (l - 1, 0), (0, n - 1), (l - 1, n - 1)]]


def turn_about_up(angle_deg: float) -> np.ndarray:
    t = np.radians(angle_deg)
    return np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])


def apply_case(s: isochor.Session, case: str) -> None:
    """Make edit ``case`` on session ``s`` (at rest)."""
    lat = s.lattice
    rest, h = lat.rest_nodes, lat.axes[UP, UP]
    top = layer(lat, UP, lat.shape[UP] - 1)
    c = rest[top].mean(axis=0)
    if case == "grab":
        for r in top:
            s.move(lat.ijk(r), by=(0, -0.25 * h, 0))
    elif case == "scale":
        for r in top:
            s.move(lat.ijk(r), to=c + 0.75 * (rest[r] - c))
    elif case == "rotate":
        for r in top:
            s.move(lat.ijk(r), to=c + (rest[r] - c) @ turn_about_up(25).T)
    elif case in ("corner", "corners3"):
        for r in top_corners(lat)[: 1 if case == "corner" else 3]:
            s.move(lat.ijk(r), by=(0, -0.25 * h, 0))
    else:  # a handle on the model's highest point dragged down
        v = s.problem.surface.full.vertices
        at = v[np.argmax(v[:, UP])]
        s.add_handle(at, to=at - [0, 0.2 * h, 0])


def far_side_shifts(lattice, rest_vertices, nodes, vertices) -> tuple[float, float]:
    """How far the ground's lattice nodes and the model's lowest 5 % moved, over the model's
    size."""
    size = float(np.ptp(rest_vertices, axis=0).max())
    ground = layer(lattice, UP, 0)
    node_shift = np.linalg.norm(np.asarray(nodes)[ground] - lattice.rest_nodes[ground], axis=1)
    y = rest_vertices[:, UP]
    low = y < y.min() + 0.05 * np.ptp(y)
    vertex_shift = np.linalg.norm(np.asarray(vertices)[low] - rest_vertices[low], axis=1)
    return float(node_shift.max()) / size, float(vertex_shift.max()) / size


def check_far_side(lattice, rest_vertices, nodes, vertices) -> None:
    nodes_moved, vertices_moved = far_side_shifts(lattice, rest_vertices, nodes, vertices)
    assert nodes_moved < FAR_NODES, f"the ground's nodes moved {nodes_moved:.1%} of the size"
    assert vertices_moved < FAR_VERTICES, f"the model's base moved {vertices_moved:.1%}"
    # squashed, not left alone: the top moved
    size = float(np.ptp(rest_vertices, axis=0).max())
    top = rest_vertices[:, UP] > rest_vertices[:, UP].max() - 0.05 * np.ptp(rest_vertices[:, UP])
    moved = np.linalg.norm(np.asarray(vertices)[top] - rest_vertices[top], axis=1).max()
    assert moved > 0.02 * size


@pytest.mark.parametrize(
    "name, cases",
    [
        ("spot_triangulated.obj", ("grab", "scale")),
        ("kitten.obj", ("rotate", "corner")),
        ("fertility.obj", ("corners3", "handle")),
    ],
)
def test_the_far_side_stays_through_the_session(name, cases):
    path = model(name)
    for case in cases:
        s = isochor.Session(path)
        apply_case(s, case)
        r = s.solve()
        assert r.converged, (case, r.message)
        assert r.held_face == "y min", case
        assert abs(r.rel_volume_error) <= TOL_VOLUME
        check_far_side(s.lattice, s.problem.surface.full.vertices, r.nodes, s.deformed_vertices())


def test_anchor_none_carries_the_model_as_the_paper_does():
    s = isochor.Session(model("spot_triangulated.obj"), anchor="none")
    apply_case(s, "grab")
    r = s.solve()
    assert r.converged and r.held_face == ""
    nodes_moved, vertices_moved = far_side_shifts(
        s.lattice, s.problem.surface.full.vertices, r.nodes, s.deformed_vertices()
    )
    assert nodes_moved > 0.1 and vertices_moved > 0.1  # carried down with the top


def test_the_far_side_stays_through_the_command_line(tmp_path):
    """The six edits saved as scenarios and solved by ``isochor solve`` out of process, a
    few at a time."""
    path = model("spot_triangulated.obj")
    jobs, sessions = [], {}
    for case in CASES:
        s = isochor.Session(path)
        apply_case(s, case)
        s.save(tmp_path / f"{case}.json")
        doc = json.loads((tmp_path / f"{case}.json").read_text())
        jobs.append({"scenario": doc, "name": case, "out": f"{case}.obj"})
        sessions[case] = s
    for case, run in zip(CASES, solve_all(tmp_path, jobs)):
        assert run.returncode == 0, run
        assert run.report["held"]["face"] == "y min" and run.report["converged"], case
        assert abs(run.report["relative_volume_error"]) <= TOL_VOLUME
        s = sessions[case]
        out = isochor.Session(tmp_path / f"{case}.obj").problem.surface.full.vertices
        check_far_side(s.lattice, s.problem.surface.full.vertices, run.report["nodes"], out)


def test_removing_the_only_handle_returns_the_model_to_rest():
    s = isochor.Session(model("kitten.obj"))
    apply_case(s, "handle")
    r = s.solve()
    assert r.converged and r.held_face == "y min"
    s.remove_handle(0)
    back = s.solve()
    assert back.converged and s.handles == []
    size = s.lattice.size
    assert np.abs(np.asarray(back.nodes) - s.lattice.rest_nodes).max() < 1e-9 * size
