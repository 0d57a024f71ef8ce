"""The window's frames: what the session hands out is drawn here, a big model as its proxy
while the lattice moves (:mod:`isochor.app.view.modelview`), and the convergence plot follows
the solve. Framing the view when a solve ends (the opening one) is asked for here too.
GUI thread only."""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtCore import QObject, Signal


class FrameDrawer(QObject):
    """The frames of one window: the view, the labels, the plot and the handle markers at
    the nodes the session hands out.

    Attributes
    ----------
    redraws : frames drawn (the tests and the benchmarks read it)

    Signals
    -------
    solveDone(int, bool) : a solve the session accepted ended (generation, success), after
                           its result was drawn
    """

    solveDone = Signal(int, bool)

    def __init__(self, win) -> None:
        super().__init__(win)
        self.win = win
        self.redraws = 0
        self._frame_after_solve = False  # fit the view when the running solve ends

    # -- framing after a solve -----------------------------------------------------------------
    def frame_after_solve(self) -> None:
        """Fit the model in the view once the solve that runs now ends (a document opened:
        the opening solve may change its shape)."""
        self._frame_after_solve = True

    def keep_camera(self) -> None:
        """The user acts on the model: the view stays where it is when the solve ends."""
        self._frame_after_solve = False

    # -- frames --------------------------------------------------------------------------------
    def moving(self) -> bool:
        """The lattice is on the move (a drag or a press that may start one, a solve, the
        timeline playing): a big model is drawn as its proxy (:mod:`isochor.app.view.modelview`)."""
        win = self.win
        return (
            win.doc.drag is not None
            or win.session.busy()
            or win.timeline.playing
            or win.viewport.model_frames.held
        )

    def draw(self, nodes: np.ndarray, record=None) -> None:
        """One frame: the nodes and the model placed and rendered, the labels; its whole
        cost is the session's ``frame_cost`` (the frame timer leaves the solver time)."""
        win = self.win
        t0 = time.perf_counter()
        timeline = win.timeline
        if timeline.shown is not None:  # a frame of the timeline, not the working edit
            nodes, record = timeline.shown, None
        moving = self.moving()
        win.viewport.set_frame(nodes, moving)
        if not moving:
            win.readout.know_volume(nodes)
        self.redraws += 1
        win.readout.frame(record)
        timeline.drawn()  # (a frame's own target volume)
        if record is not None:
            win.plot.update()
        win.plot.refresh()
        win.show_selection()  # (the scene moved the selection markers with the nodes)
        win.handle_tools.redraw(render=False)  # the handle markers follow the model
        win.viewport.repaint()  # the one render of the frame, now: part of its cost
        win.session.frame_drawn(time.perf_counter() - t0)

    def solve_started(self) -> None:
        st = self.win.state
        self.win.plot.reset(
            st.surface.size, st.problem.scenario.tol_volume, st.problem.scenario.tol_nodes
        )

    def record(self, record) -> None:
        self.win.plot.add(
            record.elapsed, record.nodes, record.rel_volume_error, record.level, record.level_done
        )

    def solve_done(self, gen: int, ok: bool) -> None:
        win = self.win
        result = win.session.last_result
        if result is not None:
            win.plot.finish(result.nodes)
        if self._frame_after_solve and win.doc.drag is None:
            self._frame_after_solve = False
            win.session.flush()
            win.viewport.camera_control.frame()
        self.solveDone.emit(gen, ok)

    def view_busy(self) -> bool:
        """The view is still drawing the last frame: a big model's full mesh is being
        prepared. A proxy left on screen with nothing on the move (a solve stopped) is
        replaced by the full mesh."""
        vp = self.win.viewport
        if vp.model_frames.showing_full():
            return False
        if not vp.scene.model.upgrading and not self.moving():
            self.win.session.redraw()
        return True
