"""The view's frames of the model: the proxy while something moves, the full mesh prepared in
steps when it stops (:mod:`isochor.app.view.modelview`). A part of
:class:`~isochor.app.view.viewport.Viewport`. GUI thread only.

A frame places the nodes and the model (:meth:`ModelFrames.place`; the window then renders
at once, so that what a frame costs is measured whole). When a big model stops moving, its
result is drawn at the proxy at once, and the full mesh waits until the view has been left
alone for :data:`IDLE_MS` (a press, a move or the wheel over the view starts the wait
again: :meth:`ModelFrames.touched`); then a zero-interval timer prepares it one step per
event-loop turn, draws it in passes (:mod:`isochor.app.view.composer`: one render of the
346k armadillo's full mesh is 45-80 ms in software OpenGL, a pass 5-16 ms) and shows it
when it is ready; ``drawn`` says so. It is put where the user is least likely to press:
after a pause, not right after the release, when the next drag often follows; a press
between two steps draws the proxy at once and the passes start again after the next pause.
A press that may start a drag draws the proxy already (:meth:`ModelFrames.hold_proxy`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal

from .scene import Scene

#: the full mesh is prepared once the view has been left alone this long, ms
IDLE_MS = 250


class ModelFrames(QObject):
    """What the model's frames draw, and the full mesh's preparation after a move.

    Parameters
    ----------
    scene : the actors (the model as full mesh or proxy, the lattice)
    repaint : paints the view now (the full mesh's frame, drawn in passes, is on screen when
              ``drawn`` says so)

    Signals
    -------
    drawn() : a big model's full mesh is on screen again after its proxy
    """

    drawn = Signal()

    def __init__(
        self, scene: Scene, repaint: Callable[[], None], parent: QObject | None = None
    ) -> None:
        super().__init__(parent)
        self.scene = scene
        self.repaint = repaint
        self.held = False  #: a press drew the proxy: its release draws the full mesh again
        self._moving: Callable[[], bool] = lambda: False
        self._timer = QTimer(self)
        self._timer.setInterval(0)
        self._timer.timeout.connect(self._step)
        self._idle = QTimer(self)  # the pause before the full mesh is prepared
        self._idle.setSingleShot(True)
        self._idle.setInterval(IDLE_MS)
        self._idle.timeout.connect(self._timer.start)

    def follow_motion(self, moving: Callable[[], bool]) -> None:
        """``moving()`` says whether the lattice is on the move (the window knows)."""
        self._moving = moving

    def moving(self) -> bool:
        """The lattice is on the move, as the window says."""
        return self._moving()

    def place(self, nodes: np.ndarray, moving: bool = False) -> None:
        """Place the lattice and the model at ``nodes`` (a big model as its proxy while
        ``moving``); the view renders at its next paint."""
        self.scene.set_frame(nodes, moving)
        self._timer.stop()
        if self.scene.model.upgrading:
            self._idle.start()
        else:
            self._idle.stop()

    def touched(self) -> None:
        """The user acts on the view (a press, a move, the wheel): the full mesh waits for
        another pause of :data:`IDLE_MS` (steps already prepared are kept)."""
        if self._timer.isActive() or self._idle.isActive():
            self._timer.stop()
            self._idle.start()

    def hold_proxy(self) -> None:
        """A press that may start a drag: draw a big model's proxy from now on, so the
        repaints the press causes (the selection) are a proxy's, not the full mesh's."""
        if self.scene.built and self.scene.model.proxy is not None:
            self.scene.model.draw(self.scene.nodes, moving=True)
            self.held = True
            self._timer.stop()
            self._idle.stop()

    def lower(self) -> None:
        """The camera moves (a turn, a pan, the wheel): a big model is drawn as its proxy
        until the view has been left alone for :data:`IDLE_MS`; every render of the move is
        a proxy's (2.5-5x shorter than the full mesh's on the 346k armadillo, software OpenGL)."""
        if self.held or self.moving():  # (the proxy is drawn already, and stays)
            return
        if self.scene.built and self.scene.model.proxy is not None:
            self.scene.model.lower()
            self._timer.stop()
            self._idle.start()

    def release(self) -> bool:
        """The press ended: True when it held the proxy (the full mesh is due again)."""
        held, self.held = self.held, False
        return held

    def _step(self) -> None:
        if self.scene.model.step():
            self._timer.stop()
            self.repaint()  # the full mesh is on screen when it says so
            self.drawn.emit()

    def finish(self) -> None:
        """Draw the full mesh now if it is being prepared (before a screenshot)."""
        self._idle.stop()
        if self.scene.built and self.scene.model.upgrading:
            self.scene.model.finish()
            self._step()

    def showing_full(self) -> bool:
        """The full mesh is on screen (nothing is being prepared)."""
        return not self.scene.built or self.scene.model.showing_full

    def drawn_model(self) -> str:
        """Which mesh of the model is on screen: ``"full mesh (N triangles)"`` or
        ``"proxy (level k, N triangles)"``."""
        return self.scene.model.drawn() if self.scene.built else "nothing"
