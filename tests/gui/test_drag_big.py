"""Issue 9 in the real window: a lattice node of the 346k-triangle armadillo dragged with live
solving on. While the lattice moves the window draws a proxy of the model (a pyramid level)
at every frame, the volume readout says it is an estimate, picking still works on the full
mesh; when the drag ends the full mesh is drawn, with the volume the solve measured, and the
nodes are the headless solve's. Behaviour only: no timing is asserted (the benchmark,
``benchmarks/window.py``, measures the rate and the stalls)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.gui.conftest import MODELS, open_window
from tests.gui.test_editor import pickable_node, point, screen_positions

ARMADILLO = MODELS / "armadillo_loop1_346k.ply"

pytestmark = pytest.mark.skipif(
    not ARMADILLO.exists(),
    reason=f"{ARMADILLO} is not there (the shared models folder ../shared is absent)",
)


def settled(win) -> bool:
    """No solve, no pending frame, and the full mesh on screen."""
    return (
        not win.is_solving()
        and not win.session.frame_pending
        and win.viewport.model_frames.showing_full()
    )


@pytest.fixture
def armadillo(qtbot, themed_app):
    """The window on the 346k armadillo, its caches prepared, nothing running."""
    from isochor.app.editor.document import Document

    doc = Document.open(ARMADILLO)
    doc.surface.prepare(doc.state.problem.options)
    win = open_window(qtbot, doc, size=(1360, 860))
    qtbot.waitUntil(lambda: win.viewport.paints > 0 and settled(win), timeout=60_000)
    yield win
    win.undo_stack.setClean()
    win.close()


def test_a_drag_of_the_big_armadillo_draws_a_proxy_and_ends_on_the_headless_solve(qtbot, armadillo):
    from PySide6.QtCore import QPointF, Qt
    from PySide6.QtTest import QTest

    from isochor.core.solve.generators import run_to_end
    from isochor.core.solve.multilevel import solve

    win = armadillo
    vp = win.viewport
    st = win.state
    surface = st.surface
    assert surface.full.n_faces > 300_000
    assert vp.model_frames.drawn_model().startswith("full mesh"), "nothing moves: the full mesh"
    win.action_set.live.setChecked(True)
    assert win.session.live, "live solving is on"

    row = pickable_node(win, want_free=True)
    frames = []  # what each frame drew: the dragged node, which mesh, the volume label
    previews = []
    picked = {}

    def drawn(_nodes, _record) -> None:  # runs after the window drew the frame
        frames.append(
            (vp.nodes[row].copy(), vp.model_frames.drawn_model(), win.readout.volume_label.text())
        )
        if not picked and len(frames) > 3 and win.doc.drag is not None:
            picked["points"] = np.array(vp.scene.model_points())
            picked["nodes"] = vp.nodes.copy()

    def done(_gen, _ok) -> None:
        result = win.session.last_result
        if win.doc.drag is not None and result is not None:
            previews.append(bool(result.preview))

    win.session.frameReady.connect(drawn)
    win.solveDone.connect(done)
    gen0 = win.worker.generation
    start = screen_positions(win)[0][row]
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
    QTest.mousePress(vp, left, none, point(start))
    steps = 14
    for i in range(1, steps + 1):
        QTest.mouseMove(vp, point(start + np.array([-7.0 * i, -3.0 * i])))
        qtbot.wait(70)
    during = list(frames)
    QTest.mouseRelease(vp, left, none, point(start + np.array([-7.0 * steps, -3.0 * steps])))
    released = len(frames)
    qtbot.waitUntil(lambda: settled(win), timeout=120_000)
    win.session.frameReady.disconnect(drawn)
    win.solveDone.disconnect(done)

    # progressive: many frames during the drag, at different node positions, all proxies
    assert len(during) >= 5, f"only {len(during)} frames while dragging"
    positions = np.unique(np.round([f[0] for f in during], 12), axis=0)
    assert len(positions) >= 4, "the dragged node was drawn at several positions"
    assert all(f[1].startswith("proxy") for f in during), {f[1] for f in during}
    assert all("≈" in f[2] and "preview" in f[2] for f in during), "the volume is an estimate"
    assert win.worker.generation - gen0 >= 3, "the preview solve restarted as the mouse moved"
    assert previews and all(previews), "the drag's solves were live previews"
    # frames of the release solve drew the proxy too, and the last the full mesh
    assert all(f[1].startswith("proxy") for f in frames[released:-1])
    assert vp.model_frames.drawn_model() == f"full mesh ({surface.full.n_faces} triangles)"

    # picking used the full mesh at the nodes drawn while the proxy was on screen
    assert picked, "a frame during the drag was recorded"
    assert picked["points"].shape == (surface.full.n_vertices, 3)
    full = surface.deform(picked["nodes"])
    assert np.allclose(picked["points"], full, atol=1e-12 * surface.size)

    # converged, drawn whole, the measured volume, and the headless solve's nodes
    st = win.state
    assert win.undo_stack.count() == 1 and st.moved[row]
    assert st.solved and st.converged, st.result.message
    assert np.array_equal(vp.nodes, st.nodes)
    assert np.allclose(vp.scene.model_points(), surface.deform(st.nodes), atol=1e-9)
    assert not vp.scene.volume_estimated and "≈" not in win.readout.volume_label.text()
    measured = surface.rest_volume * (st.goal.target_ratio + st.result.rel_volume_error)
    assert vp.model_volume == pytest.approx(measured, rel=1e-12)
    assert vp.model_volume / surface.rest_volume == pytest.approx(st.goal.target_ratio, abs=1e-3)
    nodes, fixed, goal = win.session.last_solve_input
    assert fixed[row].all()
    assert win.session.last_solve_near, "the solve on release starts near the last frame"
    headless = run_to_end(
        solve(
            surface,
            nodes,
            fixed,
            goal=goal,
            options=st.problem.options,
            handles=st.handles,
            near=True,
        )
    )
    assert headless.converged
    # The release solve starts from the preconditioner the live frames factored (shared
    # while the nodes stay near, by design); the headless one factors its own, so their
    # steps differ and each stops where the solver's criteria hold: the nodes within the
    # paper's epsilon (tol_nodes of the size) of the same minimum, the volume within its
    # tolerance. (Equal to 1e-7 of the size in practice; 1e-9 held only when no live frame
    # had run before the release.)
    tol = st.problem.scenario
    assert np.allclose(st.nodes, headless.nodes, rtol=0, atol=tol.tol_nodes * surface.size)
    assert abs(st.result.rel_volume_error - headless.rel_volume_error) <= 2 * tol.tol_volume

    # a click on the model places a handle on a full-mesh triangle
    hit = vp.camera_control.model_hit(QPointF(*screen_positions(win)[0][row]))
    centre = vp.camera_control.projection().project(st.surface.center)[0][0]
    hit = hit or vp.camera_control.model_hit(QPointF(*centre))
    assert hit is not None and 0 <= hit[0] < surface.full.n_faces
