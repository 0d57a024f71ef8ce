"""The view's frames of the model: the proxy while something moves, the full mesh prepared in
steps when it stops (:mod:`isochor.app.view.modelview`). A mixin of
:class:`~isochor.app.view.viewport.Viewport`. GUI thread only.

A frame places the nodes and the model (:meth:`ModelDrawMixin.set_frame`; the window then
renders at once, so that what a frame costs is measured whole). When a big model stops
moving, a zero-interval timer prepares its full mesh one step per event-loop turn and
renders it when it is ready; ``modelDrawn`` says so. A press that may start a drag draws
the proxy already (:meth:`ModelDrawMixin.hold_proxy`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QTimer


class ModelDrawMixin:
    """Needs the viewport's ``scene``, ``update()``/``repaint()``, ``show_gizmo()``,
    ``_update_guide()``, ``dragging`` and its ``modelDrawn`` signal."""

    _model_timer: QTimer | None = None
    _held = False  # a press drew the proxy: its release draws the full mesh again
    #: the window says whether the lattice is on the move (set by the window)
    moving_hint: Callable[[], bool] = staticmethod(lambda: False)

    def set_frame(self, nodes: np.ndarray, moving: bool = False) -> None:
        """Place the lattice and the model at ``nodes`` (a big model as its proxy while
        ``moving``); the view renders at its next paint."""
        self.scene.set_frame(nodes, moving)
        if self.dragging:
            self._update_guide()
        self.show_gizmo()
        if self.scene.model.upgrading:
            if self._model_timer is None:
                self._model_timer = QTimer(self)
                self._model_timer.setInterval(0)
                self._model_timer.timeout.connect(self._model_step)
            self._model_timer.start()
        elif self._model_timer is not None:
            self._model_timer.stop()

    def hold_proxy(self) -> None:
        """A press that may start a drag: draw a big model's proxy from now on, so the
        repaints the press causes (the selection) are a proxy's, not the full mesh's."""
        if self.scene.built and self.scene.model.proxy is not None:
            self.scene.model.draw(self.nodes, moving=True)
            self._held = True

    def holding(self) -> bool:
        """A press that may start a drag is on (the window counts it as moving)."""
        return self._held

    def end_press(self, dragged: bool = False) -> None:
        """The press ended: when it ``dragged`` nothing, draw what the window draws when
        nothing is pressed (a drag's end brings its own frames)."""
        if self._held:
            self._held = False
            if not dragged and not self.dragging:
                self.set_frame(self.nodes, self.moving_hint())
                self.update()

    def _model_step(self) -> None:
        if self.scene.model.step():
            self._model_timer.stop()
            self.repaint()  # the full mesh is on screen when it says so
            self.modelDrawn.emit()

    def finish_model(self) -> None:
        """Draw the full mesh now if it is being prepared (before a screenshot)."""
        if self.scene.built and self.scene.model.upgrading:
            self.scene.model.finish()
            self._model_step()

    def showing_full(self) -> bool:
        """The full mesh is on screen (nothing is being prepared)."""
        return not self.scene.built or self.scene.model.showing_full

    def drawn_model(self) -> str:
        """Which mesh of the model is on screen: ``"full mesh (N triangles)"`` or
        ``"proxy (level k, N triangles)"``."""
        return self.scene.model.drawn() if self.scene.built else "nothing"
