"""Keyframed poses (issue 13) in the core and the Python API: what holds between keys, and
a solved sequence that keeps the volume at every frame and passes through its keys."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from isochor.core.api import Session
from isochor.core.errors import IsochorError
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.edits import Edit, Move
from isochor.core.scenario.poses import Pose, Timeline
from isochor.core.scenario.sequence import frame_path


def test_the_timeline_eases_between_keys_and_holds_outside_them():
    keys = (Pose(0), Pose(10), Pose(20))
    linear = Timeline(keys, -5, 25)
    assert linear.segment(5) == (0, 1, 0.5)
    assert linear.segment(-5) == (0, 0, 0.0) and linear.segment(25) == (2, 2, 0.0)
    assert linear.segment(10) == (1, 2, 0.0)  # a key frame is exactly its key
    smooth = Timeline(keys, 0, 20, interpolation="smooth")
    assert smooth.segment(2.5)[2] == pytest.approx(3 * 0.25**2 - 2 * 0.25**3)
    assert len(smooth.frames) == 21


def test_frame_paths_are_zero_padded_where_the_hashes_are():
    assert frame_path("out/f_####.obj", 12) == "out/f_0012.obj"
    assert frame_path("f#.ply", 7) == "f7.ply" and frame_path("f##.ply", 123) == "f123.ply"
    with pytest.raises(IsochorError, match="####"):
        frame_path("f.obj", 1)


def test_poses_round_trip_through_the_scenario(tmp_path):
    doc = {
        "version": 3,
        "model": {"builtin": "torus"},
        "lattice": {"nodes": [3, 2, 2]},
        "poses": [
            {"frame": 8, "moves": [{"node": [2, 0, 0], "by": [0.2, 0, 0]}]},
            {"frame": 0, "target_volume_ratio": 0.9},
        ],
        "timeline": {"rate": 30, "interpolation": "smooth"},
    }
    sc = Scenario.from_dict(doc)
    assert [p.frame for p in sc.timeline.poses] == [0, 8]  # sorted by frame
    assert (sc.timeline.start, sc.timeline.end, sc.timeline.rate) == (0, 8, 30.0)
    assert sc.timeline.poses[1].edit == Edit(moves=(Move((2, 0, 0), by=(0.2, 0.0, 0.0)),))
    sc.write(tmp_path / "s.json")
    assert Scenario.read(tmp_path / "s.json").timeline == sc.timeline
    with pytest.raises(IsochorError, match="timeline: there are no poses"):
        Scenario.from_dict({**doc, "poses": []})


def test_a_session_keys_poses_and_solves_every_frame():
    ball = trimesh.creation.icosphere(subdivisions=3)
    s = Session(ball, lattice=(3, 3, 3))
    s.pin(*[(i, j, 0) for i in range(3) for j in range(3)])
    s.key(0)
    s.move((1, 1, 2), by=(0.0, 0.0, -0.4))
    s.key(6)
    s.move((1, 1, 2), by=(0.0, 0.0, 0.6))
    s.key(12, target=1.1)
    seq = s.frames(interpolation="smooth")
    assert [f.frame for f in seq.frames] == list(range(13)) and seq.converged
    for f in seq.frames:
        ratio = f.result.volume_target / f.result.volume_original
        assert abs(f.result.target_error) <= 5e-4
        assert 1.0 - 1e-12 <= ratio <= 1.1 + 1e-12
    # each key frame is its key's solve
    for key in seq.keys:
        frame = seq.frames[key.frame]
        assert np.allclose(frame.result.nodes, key.result.nodes, atol=1e-3 * s.lattice.size)
    assert s.scenario().timeline.poses == tuple(s.poses)
