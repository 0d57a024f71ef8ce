"""The timeline in the window (issue 13), driven with real mouse and key events: keys set at
two frames with I, a node moved by a real drag in between; dragging the scrubber to a frame
between the keys shows that frame's solved pose, the nodes the headless
:func:`~isochor.core.scenario.sequence.solve_sequence` gives for it, with the volume kept; undo and
redo of a key take its marker away and back; going to a key loads its edit; playing; and a
scenario with poses saved and opened again in the window has the same keys.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from tests.gui.conftest import SPHERE, open_window, save_shot, wait_idle
from tests.gui.test_editor import pickable_node, point
from tests.gui.test_goal_window import activate, rgb, type_into, undo_key


def key(win, k, mods=None):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    QTest.keyClick(win.viewport, getattr(Qt.Key, k), mods or Qt.KeyboardModifier.NoModifier)


def scrub(qtbot, win, frm, to, steps=6):
    """Press the scrubber at frame ``frm``, drag to frame ``to``, release."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    bar = win.timeline.panel.scrubber
    y = bar.height() // 2
    x0, x1 = bar.x_of(frm), bar.x_of(to)
    none = Qt.KeyboardModifier.NoModifier
    QTest.mousePress(bar, Qt.MouseButton.LeftButton, none, point((x0, y)))
    for i in range(1, steps + 1):
        QTest.mouseMove(bar, point((x0 + (x1 - x0) * i / steps, y)))
        qtbot.wait(5)
    QTest.mouseRelease(bar, Qt.MouseButton.LeftButton, none, point((x1, y)))


def frames_solved(qtbot, win, timeout=30_000):
    qtbot.waitUntil(
        lambda: win.timeline.cache is not None and win.timeline.cache.complete, timeout=timeout
    )
    win.session.flush()


def test_keys_scrub_to_a_solved_in_between_frame_undo_and_redo(qtbot, sphere, tmp_path):
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from isochor.app.view import style
    from isochor.core.scenario.document import Scenario
    from isochor.core.scenario.problem import build
    from isochor.core.scenario.sequence import solve_sequence
    from isochor.core.solve.generators import run_to_end

    win = sphere
    tool, panel, vp = win.timeline, win.timeline.panel, win.viewport
    bar = panel.scrubber
    st = win.state
    size, rest_volume = st.surface.size, st.surface.rest_volume
    assert not win.timeline_dock.isVisible(), "no keys: the view has the room"
    win.timeline_dock.toggleViewAction().trigger()  # View > Timeline
    assert win.timeline_dock.isVisible() and tool.frame == 0
    assert "no keys yet" in panel.info.text()

    # the range 0-10, typed; key 0 at rest with I
    type_into(panel.end, "10")
    assert win.undo_stack.undoText() == "Frame range 0–10" and bar.end == 10
    key(win, "Key_I")
    assert win.undo_stack.undoText() == "Set key at frame 0"
    assert win.state.timeline.key_frames == (0,) and bar.keys == (0,)

    # frame 10 (typed), a real drag of a node, I keys it there
    type_into(panel.frame, "10")
    assert tool.frame == 10 and tool.showing, "after the last key: its pose is shown"
    assert "after the last key (0)" in panel.info.text()
    row = pickable_node(win)
    start = vp.camera_control.projection().project(vp.nodes[row])[0][0]
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start))
    for i in range(1, 7):
        QTest.mouseMove(vp, point(start + np.array([40, -50]) * i / 6))
        qtbot.wait(5)
    win.session.flush()
    assert not tool.showing, "a drag shows the working pose, which it moves"
    assert np.allclose(
        vp.camera_control.projection().project(vp.nodes[row])[0][0], start + (40, -50), atol=1
    )
    QTest.mouseRelease(
        vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, point(start + (40, -50))
    )
    assert win.undo_stack.undoText().startswith("Move 1 node")
    assert "showing the working pose, not keyed" in panel.info.text()
    wait_idle(qtbot, win)
    moved_to = np.array(win.state.nodes[row])
    assert np.linalg.norm(moved_to - st.nodes[row]) > 0.05 * size
    key(win, "Key_I")
    assert win.undo_stack.undoText() == "Set key at frame 10"
    assert bar.keys == (0, 10) and "key 10: this is its edit" in panel.info.text()

    # drag the scrubber from 10 to 5: frame 5's solved pose, the working edit unchanged
    count = win.undo_stack.count()
    scrub(qtbot, win, 10, 5)
    assert tool.frame == 5 and panel.frame.value() == 5 and bar.current == 5
    assert win.undo_stack.count() == count, "scrubbing between keys is no edit"
    frames_solved(qtbot, win)
    qtbot.waitUntil(lambda: tool.solved, timeout=5_000)
    win.session.flush()
    assert "between keys 0 and 10, solved" in panel.info.text()
    assert "An edit here starts from the working pose" in panel.info.text()
    assert panel.progress.text() == "11 frames solved"
    assert bar.solved == frozenset(range(11))

    # the same scenario solved headless: the drawn lattice is its frame 5
    path = tmp_path / "keys.json"
    assert win.files.save_to(path)
    problem = build(Scenario.read(path))
    # the window solves the frames from the rest lattice, not from the working edit
    problem = replace(problem, nodes=problem.surface.lattice.rest_nodes)
    seq = run_to_end(solve_sequence(problem))
    expected = np.array(seq.frames[5].result.nodes)
    assert seq.frames[5].frame == 5 and seq.converged
    assert np.allclose(vp.nodes, expected, atol=1e-9 * size, rtol=0)
    assert np.allclose(vp.scene.model_points(), st.surface.deform(expected), atol=1e-9 * size)
    assert not np.allclose(vp.nodes, win.state.nodes), "not the working pose"
    halfway = 0.5 * (st.nodes[row] + moved_to)
    assert np.allclose(vp.nodes[row], halfway, atol=1e-9 * size), "the node on its path"
    moved_colour = rgb(style.MOVED)
    assert (vp.scene.node_colours()[row] == moved_colour).all(), "moved in key 10: marked so"
    tol = st.problem.scenario.tol_volume
    assert abs(vp.model_volume / rest_volume - 1.0) <= tol, "the drawn model keeps its volume"
    save_shot(win, "timeline_between_keys")

    # undo removes key 10 and its marker; redo brings both back (its frames kept)
    undo_key(win)
    assert win.state.timeline.key_frames == (0,) and bar.keys == (0,)
    assert tool.frame == 5 and tool.showing
    undo_key(win, redo=True)
    assert win.state.timeline.key_frames == (0, 10) and bar.keys == (0, 10)
    assert tool.solved, "the frames solved for these keys are found again"
    win.session.flush()
    assert np.allclose(vp.nodes, expected, atol=1e-9 * size, rtol=0)

    # Down goes to the previous key and loads its edit, Up to the next: one undo step
    count = win.undo_stack.count()
    key(win, "Key_Down")
    assert tool.frame == 0 and not tool.showing
    assert win.undo_stack.undoText() == "Go to key 0" and not win.state.moved.any()
    assert win.state.solved, "the key's own solve from the frames"
    key(win, "Key_Up")
    assert tool.frame == 10 and win.state.moved[row] and win.state.solved
    assert win.undo_stack.count() == count, "back on the working edit of before: no step"
    win.session.flush()
    assert np.allclose(vp.nodes[row], moved_to)
    key(win, "Key_Down")
    win.undo_stack.undo()
    assert win.state.moved[row] and win.undo_stack.undoText() == "Set key at frame 10"
    tool.go_to(10)

    # Space plays the solved frames, looping; Space again stops
    key(win, "Key_Space")
    assert tool.playing and panel.buttons["play"].text() == "❚❚"
    seen = set()
    qtbot.waitUntil(lambda: seen.add(tool.frame) or len(seen) >= 4, timeout=5_000)
    key(win, "Key_Space")
    assert not tool.playing
    # Alt+I removes the key at the current frame (a key frame after stopping on it, or not)
    tool.go_to(10)
    key(win, "Key_I", mods=_alt())
    assert win.undo_stack.undoText() == "Remove key at frame 10" and bar.keys == (0,)


def _alt():
    from PySide6.QtCore import Qt

    return Qt.KeyboardModifier.AltModifier


def test_a_scenario_with_poses_round_trips_through_the_window(qtbot, themed_app, tmp_path):
    from isochor.app.editor.document import Document

    spec = {
        **SPHERE,
        "version": 3,
        "poses": [
            {"frame": 0},
            {"frame": 6, "moves": [{"node": [1, 1, 2], "by": [0, 0, -0.3]}]},
            {
                "frame": 12,
                "moves": [{"node": [1, 1, 2], "by": [0.2, 0, 0.1]}],
                "target_volume_ratio": 0.95,
            },
        ],
        "timeline": {"start": 0, "end": 12, "rate": 30, "interpolation": "smooth"},
    }
    src = tmp_path / "poses.json"
    src.write_text(json.dumps(spec))
    win = open_window(qtbot, Document.open(src))
    wait_idle(qtbot, win)
    activate(qtbot, win)
    panel, bar = win.timeline.panel, win.timeline.panel.scrubber
    assert bar.keys == (0, 6, 12), "a window opened on poses shows its keys"
    assert (panel.start.value(), panel.end.value()) == (0, 12)
    assert panel.rate.value() == 30 and panel.interpolation.currentData() == "smooth"
    frames_solved(qtbot, win)
    assert panel.progress.text() == "13 frames solved"
    save_shot(win, "timeline_opened")
    # frame 9, half way from key 6 to key 12 (smooth): the target half way, 97.5 %
    scrub(qtbot, win, 0, 9)
    assert win.timeline.solved and win.timeline.frame == 9
    win.session.flush()
    volume = win.viewport.model_volume / win.state.surface.rest_volume
    assert volume == pytest.approx(0.975, abs=win.state.problem.scenario.tol_volume)
    assert "(target 97.5 % at frame 9)" in win.readout.volume_label.text()
    assert win.timeline.label.text() == "Frame 9 · solved"

    out = tmp_path / "saved.json"
    assert win.files.save_to(out)
    saved = json.loads(out.read_text())
    assert [p["frame"] for p in saved["poses"]] == [0, 6, 12]
    assert saved["timeline"] == {"start": 0, "end": 12, "rate": 30.0, "interpolation": "smooth"}
    assert saved["poses"][2]["target_volume_ratio"] == 0.95
    keys = win.state.timeline
    win.undo_stack.setClean()
    assert win.files.open_path(out)
    assert win.state.timeline == keys and bar.keys == (0, 6, 12)
    assert win.timeline.frame == 0
    win.undo_stack.setClean()
    win.close()


def test_the_scrubber_shows_each_frames_state_at_a_glance(qtbot, themed_app, tmp_path, monkeypatch):
    """Converged frames green, a frame that did not converge red (and taller), frames not
    solved yet dim: read back from the scrubber's pixels (issue 29 item 5)."""
    import dataclasses
    import time

    from PySide6.QtGui import QColor

    from isochor.app.editor.document import Document
    from isochor.app.session import framesolver
    from isochor.app.window import timelinebar

    solve = framesolver.solve_sequence

    def marked(problem):
        """The real sequence solve, slowed down, with frame 3's result marked unconverged."""
        records = solve(problem)
        try:
            while True:
                try:
                    item = next(records)
                except StopIteration as stop:
                    return stop.value
                if getattr(item, "frame", None) == 3 and not getattr(item, "key", True):
                    result = dataclasses.replace(item.result, converged=False)
                    item = dataclasses.replace(item, result=result)
                time.sleep(0.05)
                yield item
        finally:
            records.close()

    monkeypatch.setattr(framesolver, "solve_sequence", marked)
    spec = {
        **SPHERE,
        "version": 3,
        "poses": [{"frame": 0}, {"frame": 8, "moves": [{"node": [1, 1, 2], "by": [0, 0, -0.3]}]}],
        "timeline": {"start": 0, "end": 8},
    }
    src = tmp_path / "states.json"
    src.write_text(json.dumps(spec))
    win = open_window(qtbot, Document.open(src))
    bar = win.timeline.panel.scrubber

    def band(frame) -> str:
        """The colour of the band under ``frame``, as painted."""
        img = bar.grab().toImage()
        return QColor(img.pixel(int(bar.x_of(frame)), bar.height() - 4)).name()

    qtbot.waitUntil(lambda: "pending" in {bar.state_of(f) for f in range(9)}, timeout=10_000)
    pending = max(f for f in range(9) if bar.state_of(f) == "pending")  # not 0, the current
    assert band(pending) == QColor(timelinebar.PENDING).name()
    frames_solved(qtbot, win)
    win.timeline.panel.scrubber.update()
    assert bar.state_of(3) == "not converged"
    assert [bar.state_of(f) for f in (0, 2, 4, 8)] == ["converged"] * 4
    assert band(3) == QColor(timelinebar.UNCONVERGED).name()
    assert band(2) == band(4) == QColor(timelinebar.SOLVED).name()
    save_shot(win, "timeline_states")
    win.undo_stack.setClean()
    win.close()
