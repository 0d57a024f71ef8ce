"""The editing session (isochor.app.session) driven headless: an EditorSession on a
document, with pytest-qt's ``qtbot`` for the event loop and no window.

An edit committed starts a solve whose records arrive and whose result lands in the edit's
undo cell, the volume kept within the scenario's tolerance; undo and redo land on solved
states without solving again; a live drag shows previews and its release solves near its
last frame; records of a stale generation are dropped. The drag part
(:class:`~isochor.app.session.drag.SessionDrag`) is also driven alone, through a host made
of plain functions: its interface to the session is all it needs.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from isochor.app.editor import noderules
from isochor.app.editor.document import Document
from isochor.app.session.controller import EditorSession
from isochor.app.session.drag import DragHost, SessionDrag
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build
from isochor.core.volume import face_volumes, signed_volume

SPHERE = {"model": {"builtin": "sphere", "n_levels": 3}, "lattice": {"nodes": [3, 3, 3]}}
EPS = np.finfo(np.float64).eps
SOLVE_MS = 60_000


@pytest.fixture(scope="module")
def problem():
    """A built-in sphere in a 3x3x3 lattice, at rest (nothing to solve)."""
    return build(Scenario.from_dict(SPHERE))


@pytest.fixture
def session(qtbot, problem):
    s = EditorSession(Document(problem))
    s.view_ready()  # no window: nothing waits for a first frame
    yield s
    s.shutdown()


class Seen:
    """What the session said: solves started (their generation), records, ends, frames."""

    def __init__(self, session: EditorSession) -> None:
        self.started: list[int] = []
        self.records: list = []
        self.done: list[tuple[int, bool]] = []
        self.frames: list[np.ndarray] = []
        self.failed: list[str] = []
        session.solveStarted.connect(lambda: self.started.append(session.worker.generation))
        session.recordAccepted.connect(self.records.append)
        session.solveDone.connect(lambda gen, ok: self.done.append((gen, ok)))
        session.frameReady.connect(lambda nodes, _record: self.frames.append(np.array(nodes)))
        session.failed.connect(self.failed.append)


def top_node(doc: Document) -> int:
    return doc.state.lattice.index(1, 1, 2)


def volume_error(doc: Document, nodes: np.ndarray) -> tuple[float, float]:
    """|V/V0 - target| of the full mesh deformed by ``nodes``, and the rounding bound of
    that number: each volume is a sum of f tetrahedra, so its error is at most
    f eps sum|v_i| (relative to V0, for both sums)."""
    s = doc.surface
    faces = s.full.faces
    points = s.deform(nodes)
    rel = signed_volume(points, faces) / s.rest_volume - doc.state.goal.target_ratio
    terms = (
        np.abs(face_volumes(points, faces)).sum()
        + np.abs(face_volumes(s.full.vertices, faces)).sum()
    )
    return abs(rel), len(faces) * EPS * terms / abs(s.rest_volume)


def assert_volume_kept(doc: Document, nodes: np.ndarray) -> None:
    tol = doc.problem.scenario.tol_volume
    err, rounding = volume_error(doc, nodes)
    assert err <= tol + rounding, f"|dV|/V0 = {err:.3e} > {tol:.1e}"


def edit_and_solve(qtbot, session: EditorSession, dz: float = -0.2):
    """Type the top node's z ``dz`` of the model's size lower; wait for its solve."""
    doc = session.document
    top = top_node(doc)
    doc.selection.select([top])
    z = float(doc.state.nodes[top, 2])
    edit = noderules.edit_position(doc.base(), 2, z + dz * doc.surface.size)
    assert session.commit(edit)
    cell = doc.cell
    qtbot.waitUntil(lambda: cell.state.solved, timeout=SOLVE_MS)
    return cell, edit


def test_a_committed_edit_is_solved_into_its_undo_cell(qtbot, session):
    doc = session.document
    seen = Seen(session)
    at_rest = doc.cell
    assert at_rest.state.solved and not session.busy(), "at rest: nothing to solve"
    top = top_node(doc)
    doc.selection.select([top])
    z = float(doc.state.nodes[top, 2])
    edit = noderules.edit_position(doc.base(), 2, z - 0.2 * doc.surface.size)
    assert session.commit(edit)
    cell = doc.cell
    assert cell is not at_rest and cell.state is edit.state and not cell.state.solved
    assert session.undo_stack.count() == 1 and session.undo_stack.undoText() == "Move 1 node"
    gen = session.worker.generation
    assert seen.started == [gen], "the commit started one solve"
    assert session.busy() and session.status()[0] == "Solving…"

    qtbot.waitUntil(lambda: bool(seen.done), timeout=SOLVE_MS)
    assert seen.done == [(gen, True)] and seen.failed == []
    log = list(session.accepted_log)
    assert log == [(gen, "progress")] * len(seen.records) + [(gen, "finished")]
    assert len(seen.records) >= 1, "records arrived while it solved"
    st = cell.state
    assert doc.cell is cell and st.solved and st.converged
    assert session.status()[0] == "Converged"
    np.testing.assert_array_equal(st.nodes, session.last_result.nodes)
    np.testing.assert_array_equal(st.nodes[top], edit.state.nodes[top])  # a moved node stays
    free = np.flatnonzero(~st.fixed)
    assert np.abs(st.nodes[free] - edit.state.nodes[free]).max() > 1e-3 * doc.surface.size
    assert abs(st.result.rel_volume_error) <= doc.problem.scenario.tol_volume
    assert_volume_kept(doc, st.nodes)
    # the window is handed the solved nodes
    qtbot.waitUntil(lambda: not session.frame_pending, timeout=5_000)
    np.testing.assert_array_equal(seen.frames[-1], st.nodes)


def test_undo_and_redo_land_on_solved_states_without_solving_again(qtbot, session):
    doc = session.document
    at_rest = doc.cell
    rest_nodes = np.array(at_rest.state.nodes)
    cell, _ = edit_and_solve(qtbot, session)
    solved = np.array(cell.state.nodes)
    gen = session.worker.generation
    seen = Seen(session)

    session.undo_stack.undo()
    assert doc.cell is at_rest and doc.state.solved and not session.busy()
    np.testing.assert_array_equal(doc.state.nodes, rest_nodes)
    session.undo_stack.redo()
    assert doc.cell is cell and doc.state.solved and not session.busy()
    np.testing.assert_array_equal(doc.state.nodes, solved)
    qtbot.waitUntil(lambda: not session.frame_pending, timeout=5_000)
    qtbot.wait(3 * 16)  # a few frames: nothing starts late either
    assert seen.started == [] and seen.records == [] and session.worker.generation == gen
    np.testing.assert_array_equal(seen.frames[-1], solved)
    assert session.status()[0] == "Converged"


def test_a_live_drag_previews_and_its_release_is_solved(qtbot, session):
    doc = session.document
    seen = Seen(session)
    session.live = True
    top = top_node(doc)
    doc.selection.select([top])
    before = doc.cell
    base = doc.base_nodes()
    assert session.begin_drag()
    assert session.status()[0] == "Dragging"
    assert session.drag_text("z axis").startswith("Moving 1 node — locked to the z axis")
    delta = np.array([0.0, 0.0, -0.15 * doc.surface.size])
    for k in range(1, 6):
        session.drag_to(delta * k / 5)
        qtbot.wait(50)  # the preview timer (LIVE_MS) fires meanwhile
    qtbot.waitUntil(
        lambda: len(seen.done) >= 1 and session.document.live_nodes is not None, timeout=SOLVE_MS
    )
    qtbot.waitUntil(lambda: not session.frame_pending, timeout=5_000)
    previews = list(seen.done)
    assert all(ok for _, ok in previews) and session.last_result.preview
    assert doc.cell is before and session.undo_stack.count() == 0, "a preview keeps no state"
    np.testing.assert_array_equal(before.state.nodes, base)
    shown = seen.frames[-1]
    np.testing.assert_array_equal(shown[top], base[top] + delta)  # under the cursor
    free = np.flatnonzero(~before.state.fixed)
    free = free[free != top]
    assert np.abs(shown[free] - base[free]).max() > 1e-4 * doc.surface.size, "previewed"

    session.finish_drag()
    assert session.undo_stack.count() == 1 and session.undo_stack.undoText() == "Move 1 node"
    assert session.last_solve_near, "the release starts near the last preview"
    cell = doc.cell
    qtbot.waitUntil(lambda: cell.state.solved, timeout=SOLVE_MS)
    st = cell.state
    assert st.converged and st.moved[top]
    np.testing.assert_array_equal(st.nodes[top], base[top] + delta)
    assert_volume_kept(doc, st.nodes)
    assert seen.failed == []


def test_a_cancelled_drag_restores_the_state_before_it(qtbot, session):
    doc = session.document
    doc.selection.select([top_node(doc)])
    before = doc.cell
    assert session.begin_drag("Scale")
    session.drag_transform(np.diag([2.0, 2.0, 2.0, 1.0]))
    session.cancel_drag()
    assert doc.cell is before and doc.drag is None and session.undo_stack.count() == 0
    assert session.drag_text() == "" and session.status()[0] == "At rest"


def test_records_of_a_stale_generation_are_dropped(qtbot, session):
    doc = session.document
    seen = Seen(session)
    top = top_node(doc)
    doc.selection.select([top])
    z = float(doc.state.nodes[top, 2])
    size = doc.surface.size
    session.commit(noderules.edit_position(doc.base(), 2, z - 0.1 * size))
    first, first_gen = doc.cell, session.worker.generation
    # a second edit before any event is handled: the first solve's records are all stale
    session.commit(noderules.edit_position(doc.base(), 2, z - 0.2 * size))
    second, second_gen = doc.cell, session.worker.generation
    assert second_gen == first_gen + 1 and seen.started == [first_gen, second_gen]

    dropped = session.dropped
    bogus = np.zeros((doc.state.lattice.n_nodes, 3))
    session.worker.progress.emit(first_gen, SimpleNamespace(nodes=bogus))
    session.worker.finished.emit(first_gen, SimpleNamespace(nodes=bogus, converged=True))
    session.worker.failed.emit(first_gen, "a stale failure")
    assert session.dropped == dropped + 3
    assert doc.live_nodes is None and seen.records == [] and seen.failed == []
    assert not first.state.solved and not second.state.solved

    qtbot.waitUntil(lambda: second.state.solved, timeout=SOLVE_MS)
    assert not first.state.solved, "the first solve's result never landed"
    assert {gen for gen, _ in session.accepted_log} == {second_gen}
    assert seen.done == [(second_gen, True)]
    assert_volume_kept(doc, second.state.nodes)


def test_the_drag_part_reaches_the_session_through_its_host_only(qtbot, problem):
    doc = Document(problem)
    calls: list = []
    host = DragHost(
        document=lambda: doc,
        stop=lambda: calls.append("stop"),
        show=lambda nodes: calls.append(("show", np.array(nodes))),
        preview=lambda *args: calls.append(("preview", args)),
        commit=lambda edit: calls.append(("commit", edit)) or edit is not None,
        activity=lambda what: calls.append(("activity", what)),
        told=lambda: calls.append("told"),
    )
    drags = SessionDrag(host)
    assert not drags.begin(), "nothing selected: no drag"
    assert calls == ["stop"]

    top = top_node(doc)
    doc.selection.select([top])
    base = doc.base_nodes()
    calls.clear()
    assert drags.begin("Scale")
    assert [c if isinstance(c, str) else c[0] for c in calls] == [
        "stop",
        "activity",
        "show",
        "told",
    ]
    assert calls[1] == ("activity", "dragging")
    np.testing.assert_array_equal(calls[2][1], base)
    delta = np.array([0.1, 0.0, 0.0])
    calls.clear()
    drags.move(delta)
    assert len(calls) == 1 and calls[0][0] == "show"
    np.testing.assert_array_equal(calls[0][1][top], base[top] + delta)
    assert not drags.timer.isActive(), "live is off: no preview"
    calls.clear()
    drags.finish()
    assert calls[:2] == ["stop", ("activity", "idle")]
    edit = calls[2][1]
    assert edit.text == "Scale 1 node" and edit.state.moved[top]
    assert drags.take_near() is False

    # live: the timer starts a preview of the drag as it is now
    drags.set_live(True)
    before = doc.cell
    assert drags.begin()
    drags.move(delta)
    assert drags.timer.isActive()
    qtbot.waitUntil(lambda: any(c[0] == "preview" for c in calls if isinstance(c, tuple)))
    st, nodes, fixed, handles = next(c[1] for c in calls if c[0] == "preview")
    assert st is before.state and handles == ()
    np.testing.assert_array_equal(nodes[top], base[top] + delta)
    assert fixed[top].all()
    calls.clear()
    drags.cancel()
    assert calls == ["stop"] and doc.cell is before and doc.drag is None
