"""The window's frames: what the session hands out is drawn here, a big model as its proxy
while the lattice moves (:mod:`isochor.app.view.modelview`), and the convergence plot follows
the solve. A mixin of :class:`~isochor.app.window.mainwindow.MainWindow`. GUI thread only."""

from __future__ import annotations

import time

import numpy as np

from . import handletools


class FramesMixin:
    """Needs the window's ``session``, ``doc``, ``state``, ``viewport``, ``readout``,
    ``timeline``, ``plot``, ``redraws``, ``_show_selection``, ``_frame_after_solve`` and
    its ``solveDone`` signal."""

    def moving(self) -> bool:
        """The lattice is on the move (a drag or a press that may start one, a solve, the
        timeline playing): a big model is drawn as its proxy (:mod:`isochor.app.view.modelview`)."""
        return (
            self.doc.drag is not None
            or self.session.busy()
            or self.timeline.playing
            or self.viewport.holding()
        )

    def _draw(self, nodes: np.ndarray, record=None) -> None:
        """One frame: the nodes and the model placed and rendered, the labels; its whole
        cost is the session's ``frame_cost`` (the frame timer leaves the solver time)."""
        t0 = time.perf_counter()
        if self.timeline.shown is not None:  # a frame of the timeline, not the working edit
            nodes, record = self.timeline.shown, None
        moving = self.moving()
        self.viewport.set_frame(nodes, moving)
        if not moving:
            self.readout.know_volume(nodes)
        self.redraws += 1
        self.readout.frame(record)
        self.timeline.drawn()  # (a frame's own target volume)
        if record is not None:
            self.plot.update()
        self.plot.refresh()
        self._show_selection()  # (the scene moved the selection markers with the nodes)
        handletools.redraw(self, render=False)  # the handle markers follow the model
        self.viewport.repaint()  # the one render of the frame, now: part of its cost
        self.session.frame_cost = time.perf_counter() - t0

    def _solve_started(self) -> None:
        st = self.state
        self.plot.reset(
            st.surface.size, st.problem.scenario.tol_volume, st.problem.scenario.tol_nodes
        )

    def _record(self, record) -> None:
        self.plot.add(
            record.elapsed, record.nodes, record.rel_volume_error, record.level, record.level_done
        )

    def _solve_done(self, gen: int, ok: bool) -> None:
        result = self.session.last_result
        if result is not None:
            self.plot.finish(result.nodes)
        if self._frame_after_solve and self.doc.drag is None:
            self._frame_after_solve = False
            self.session.flush()
            self.viewport.frame()
        self.solveDone.emit(gen, ok)

    def _view_busy(self) -> bool:
        """The view is still drawing the last frame: a big model's full mesh is being
        prepared. A proxy left on screen with nothing on the move (a solve stopped) is
        replaced by the full mesh."""
        vp = self.viewport
        if vp.showing_full():
            return False
        if not vp.scene.model.upgrading and not self.moving():
            self.session.redraw()
        return True
