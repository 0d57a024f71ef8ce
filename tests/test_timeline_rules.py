"""The timeline's rules in the document (issue 13), headless: set, replace and remove keys,
go to a key, the range, rate and interpolation as undoable edits; the keys written to and
read from the scenario; what a frame shows (the solved frame or the interpolated start) and
the words for it; the frame caches by what the frames depend on."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from isochor.app.editor import goalrules, latticerules, noderules, timelinerules
from isochor.app.editor.document import Document
from isochor.app.editor.timeline import (
    FrameCache,
    FrameCaches,
    TimelineState,
    describe,
    frame_fixed,
    frame_nodes,
    frame_target,
    pose_of,
    same_pose,
    sequence_problem,
    sequence_signature,
)
from isochor.core.errors import IsochorError
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.poses import Pose
from isochor.core.scenario.problem import build
from isochor.core.scenario.sequence import solve_sequence
from isochor.core.solve.generators import run_to_end

SPHERE = {"model": {"builtin": "sphere", "n_levels": 3}, "lattice": {"nodes": [3, 3, 3]}}


@pytest.fixture(scope="module")
def problem():
    return build(Scenario.from_dict(SPHERE))


@pytest.fixture
def doc(problem):
    return Document(problem)


def commit(doc, edit):
    """What the session does with an edit: its state becomes current."""
    from isochor.app.editor.state import StateCell

    assert edit is not None
    doc.set_cell(StateCell(edit.state))
    return edit


def move_top(doc, dz=-0.4):
    """Move node (1, 1, 2) down by ``dz`` (typed, as the Inspector does)."""
    lat = doc.state.lattice
    row = lat.index(1, 1, 2)
    doc.selection.select([row])
    commit(doc, noderules.edit_position(doc.base(), 2, float(doc.state.nodes[row, 2] + dz)))
    return row


def test_set_replace_and_remove_keys_keep_the_working_edit(doc):
    st0 = doc.state
    assert st0.timeline == TimelineState() and st0.timeline.core() is None
    edit = commit(doc, timelinerules.edit_set_key(doc.base(), 0))
    assert edit.text == "Set key at frame 0"
    assert doc.state.timeline.key_frames == (0,)
    assert doc.state.solved == st0.solved, "keying leaves the working edit and its solve"
    assert timelinerules.edit_set_key(doc.base(), 0) is None, "the same edit again changes nothing"
    row = move_top(doc)
    edit = commit(doc, timelinerules.edit_set_key(doc.base(), 10))
    assert edit.text == "Set key at frame 10" and doc.state.timeline.key_frames == (0, 10)
    key = doc.state.timeline.key_at(10)
    assert key.target_ratio == 1.0 and [m.node for m in key.edit.moves] == [(1, 1, 2)]
    assert key.edit.moves[0].to == tuple(doc.state.nodes[row])
    # keying frame 0 again with this edit replaces the key there
    assert commit(doc, timelinerules.edit_set_key(doc.base(), 0)).text == "Replace key at frame 0"
    assert same_pose(doc.state.timeline.key_at(0), key, doc.state.lattice)
    assert commit(doc, timelinerules.edit_remove_key(doc.base(), 0)).text == "Remove key at frame 0"
    assert doc.state.timeline.key_frames == (10,)
    assert timelinerules.edit_remove_key(doc.base(), 3) is None


def test_go_to_key_loads_its_edit_solved_or_to_solve(doc):
    lat = doc.state.lattice
    commit(doc, timelinerules.edit_set_key(doc.base(), 0))
    row = move_top(doc)
    commit(doc, goalrules.edit_target(doc.base(), 95))
    commit(doc, timelinerules.edit_set_key(doc.base(), 12))
    assert timelinerules.edit_go_to_key(doc.base(), 12) is None, (
        "the working edit is key 12's already"
    )
    assert timelinerules.edit_go_to_key(doc.base(), 5) is None, "no key at 5"
    edit = commit(doc, timelinerules.edit_go_to_key(doc.base(), 0))
    assert edit.text == "Go to key 0"
    st = doc.state
    assert not st.moved.any() and st.goal.target_ratio == 1.0
    assert st.solved and np.array_equal(st.nodes, lat.rest_nodes), "at rest: nothing to solve"
    assert st.timeline.key_frames == (0, 12), "the keys stay"
    # with the key's solve known the state is solved with it; without, it is to be solved
    fake = run_to_end(solve_sequence(sequence_problem(doc.state))).keys[1].result
    solved = timelinerules.edit_go_to_key(doc.base(), 12, solved=fake).state
    assert solved.solved and np.array_equal(solved.nodes, fake.nodes)
    assert solved.moved[row] and solved.goal.target_ratio == 0.95
    unsolved = timelinerules.edit_go_to_key(doc.base(), 12).state
    assert not unsolved.solved and unsolved.moved[row]
    assert np.allclose(unsolved.nodes[row], doc.state.timeline.key_at(12).edit.moves[0].to)


def test_range_rate_and_interpolation_are_checked_edits(doc):
    assert (
        commit(doc, timelinerules.edit_frame_range(doc.base(), -5, 30)).text == "Frame range -5–30"
    )
    assert timelinerules.edit_frame_range(doc.base(), -5, 30) is None
    with pytest.raises(IsochorError, match="end"):
        timelinerules.edit_frame_range(doc.base(), 10, 2)
    assert (
        commit(doc, timelinerules.edit_timeline_setting(doc.base(), "rate", 30)).text
        == "Frame rate 30 fps"
    )
    with pytest.raises(IsochorError, match="rate"):
        timelinerules.edit_timeline_setting(doc.base(), "rate", 0)
    edit = commit(doc, timelinerules.edit_timeline_setting(doc.base(), "interpolation", "smooth"))
    assert edit.text == "Interpolation smooth"
    with pytest.raises(IsochorError, match="interpolation"):
        timelinerules.edit_timeline_setting(doc.base(), "interpolation", "cubic")
    tl = doc.state.timeline
    assert (tl.start, tl.end, tl.rate, tl.interpolation) == (-5, 30, 30.0, "smooth")
    assert tl.clamp(-9) == -5 and tl.clamp(99) == 30


def test_keys_are_saved_in_the_scenario_and_read_back(doc, tmp_path):
    commit(doc, timelinerules.edit_set_key(doc.base(), 0))
    move_top(doc)
    commit(doc, timelinerules.edit_set_key(doc.base(), 8))
    commit(doc, timelinerules.edit_timeline_setting(doc.base(), "interpolation", "smooth"))
    commit(doc, timelinerules.edit_frame_range(doc.base(), 0, 16))
    path = tmp_path / "poses.json"
    doc.save(path)
    sc = Scenario.read(path)
    assert sc.version == 3 and sc.timeline == doc.state.timeline.core()
    again = Document.open(path)
    assert again.state.timeline == doc.state.timeline
    # a pose without a target ratio takes the scenario's, so keys never follow the working one
    spec = {**SPHERE, "version": 3, "target_volume_ratio": 0.9, "poses": [{"frame": 4}]}
    opened = Document(build(Scenario.from_dict(spec)))
    assert opened.state.timeline.keys[0].target_ratio == 0.9
    # a new lattice drops the keys (they name nodes of the old one) and says so
    edit = latticerules.edit_lattice(doc.base(), (4, 3, 3))
    assert edit.text == "Rebuild lattice 4x3x3, 2 keys dropped"
    assert edit.state.timeline.keys == () and edit.state.timeline.end == 16


def test_a_frame_shows_its_solve_or_the_interpolated_start(doc):
    lat = doc.state.lattice
    commit(doc, timelinerules.edit_set_key(doc.base(), 0))
    row = move_top(doc, -0.4)
    commit(doc, timelinerules.edit_set_key(doc.base(), 10))
    commit(doc, timelinerules.edit_frame_range(doc.base(), 0, 10))
    st = doc.state
    tl = st.timeline
    rest = lat.rest_nodes
    # nothing solved: the keys' edits blended, the moved node on its straight path
    nodes, solved = frame_nodes(tl, lat, None, 5)
    assert not solved
    assert np.allclose(nodes[row], 0.5 * rest[row] + 0.5 * np.array(tl.keys[1].edit.moves[0].to))
    pins, moved = frame_fixed(tl, lat, 5)
    assert moved[row] and moved.sum() == 1 and pins.sum() == 0
    # solved: the cache's nodes, exactly the sequence's frame
    seq = run_to_end(solve_sequence(sequence_problem(st)))
    cache = FrameCache.for_state(st)
    for f in (*seq.keys, *seq.frames):
        cache.add(f)
    assert cache.complete and cache.progress() == "11 frames solved"
    nodes, solved = frame_nodes(tl, lat, cache, 5)
    assert solved and np.array_equal(nodes, seq.frames[5].result.nodes)
    # the words
    assert describe(tl, 5, True, True).startswith(
        "Frame 5 of 0–10 — between keys 0 and 10, solved."
    )
    assert "not solved yet" in describe(tl, 5, True, False)
    assert "key 10: this is its edit" in describe(tl, 10, False, False)
    assert "not keyed: press I" in describe(tl, 5, False, False)
    assert "no keys yet" in describe(TimelineState(), 3, False, False)


def test_frame_caches_follow_what_the_frames_depend_on(doc):
    caches = FrameCaches(kept=2)
    assert caches.get(doc.state) is None, "no keys, no frames"
    commit(doc, timelinerules.edit_set_key(doc.base(), 0))
    a = caches.get(doc.state)
    assert a is not None and a.progress() == "Solving keys 0/1"
    move_top(doc)
    assert caches.get(doc.state) is a, "the working edit is not what the frames depend on"
    commit(doc, timelinerules.edit_set_key(doc.base(), 6))
    b = caches.get(doc.state)
    assert b is not a
    commit(doc, timelinerules.edit_timeline_setting(doc.base(), "rate", 12))
    assert caches.get(doc.state) is b, "the rate changes no frame"
    commit(doc, goalrules.edit_keep_centroid(doc.base(), True))
    c = caches.get(doc.state)
    assert c is not b, "the goal does"
    st = replace(doc.state, goal=replace(doc.state.goal, keep_centroid=False))
    assert caches.get(st) is b, "a kept cache is found again (undo)"
    assert sequence_signature(st) != sequence_signature(doc.state)
    commit(doc, timelinerules.edit_timeline_setting(doc.base(), "interpolation", "smooth"))
    caches.get(doc.state)
    assert (
        caches.get(replace(doc.state, goal=replace(doc.state.goal, keep_centroid=False))) is not b
    )
    assert pose_of(doc.state, 3) == Pose(3, doc.state.timeline.keys[1].edit, 1.0)


def test_the_target_eases_between_keys_and_old_caches_go_by_size(doc):
    commit(doc, timelinerules.edit_set_key(doc.base(), 0))
    commit(doc, goalrules.edit_target(doc.base(), 90))
    commit(doc, timelinerules.edit_set_key(doc.base(), 10))
    tl = doc.state.timeline
    assert frame_target(tl, 5) == pytest.approx(0.95) and frame_target(tl, 20) == 0.9
    smooth = tl.changed(interpolation="smooth")
    assert frame_target(smooth, 2) == pytest.approx(1 - 0.1 * (3 * 0.04 - 2 * 0.008))
    # a budget of node positions: the current cache stays, the oldest go
    n = doc.state.lattice.n_nodes
    caches = FrameCaches(kept=8, nodes=15 * n)
    first = caches.get(doc.state)
    first.frames.update({f: np.zeros((n, 3)) for f in range(11)})
    commit(doc, timelinerules.edit_frame_range(doc.base(), 0, 12))
    second = caches.get(doc.state)
    assert second is not first and caches.get(replace(doc.state, timeline=tl)) is first
    second.frames.update({f: np.zeros((n, 3)) for f in range(13)})
    assert caches.get(doc.state) is second, "over the budget: the older one goes"
    assert caches.get(replace(doc.state, timeline=tl)) is not first
