"""The view's surface handles: placing one with a click on the model (the Handle tool, or
Ctrl+click), selecting one with a click on its marker, and dragging its target in the view
plane at its depth (X/Y/Z lock an axis, as for node drags). A mixin of
:class:`~isochor.app.view.viewport.Viewport`; the markers are
:class:`~isochor.app.view.overlays.HandleMarkers`. GUI thread only.

The view only says what the user did (signals); the window turns a hit on the model into the
model's rest point (:func:`isochor.app.editor.handlerules.rest_point`) and the session
runs the drag like a node drag.
"""

from __future__ import annotations

from PySide6.QtCore import QPointF, Qt

from . import picking
from .gestures import HandlePress, ModelPress, NodeDrag

#: The mouse must travel this many pixels before a press on a handle or the model drags.
HANDLE_DRAG = 3.0


class HandleViewMixin:
    """Needs the viewport's ``scene``, ``handles`` (the markers), ``projection()``,
    ``_press``, ``_drag``, ``_update_drag`` and its signals."""

    handle_mode = False  #: the Handle tool: a click on the model places a handle

    def _handle_press(self, pos: QPointF) -> bool:
        """A left press on a handle's marker."""
        index = self.handles.at(self.projection(), pos.x(), pos.y())
        if index < 0:
            return False
        self._press = HandlePress(index, QPointF(pos))
        return True

    def _model_press(self, pos: QPointF) -> bool:
        """A left press on the model that places a handle (Handle tool or Ctrl)."""
        if not self.scene.built:
            return False
        hit = picking.surface_hit(
            self.projection(), self.scene.model_points(), self.scene.model_faces(), *pos.toTuple()
        )
        if hit is None:
            return False
        face, weights, point = hit
        self._press = ModelPress(QPointF(pos), face, weights, point)
        return True

    def model_hit(self, pos: QPointF):
        """``(face, weights, point)`` of the model drawn under ``pos``, or None."""
        return picking.surface_hit(
            self.projection(), self.scene.model_points(), self.scene.model_faces(), *pos.toTuple()
        )

    def _handle_move(self, press, pos: QPointF) -> None:
        """A move during a press on a handle or on the model: a drag of the target once
        the mouse travels."""
        if self._drag is None:
            if (pos - press.pos).manhattanLength() < HANDLE_DRAG:
                return
            if isinstance(press, HandlePress):
                anchor = self.handles.targets[press.index].copy()
            else:
                anchor = press.point.copy()
            _, depth, _ = self.projection().project(anchor)
            self._drag = NodeDrag(press.pos, anchor, float(depth[0]), press.pos)
            if isinstance(press, HandlePress):
                self.handleDragStarted.emit(press.index, -1, None)
            else:
                self.handleDragStarted.emit(-1, press.face, press.weights)
        self._update_drag(pos)

    def _handle_release(self, press, pos: QPointF) -> None:
        if self._drag is not None:
            self._update_drag(pos)
            self._end_drag()
        elif isinstance(press, HandlePress):
            self.handleSelected.emit(press.index)
        else:
            self.handlePlaced.emit(press.face, press.weights)

    def _handle_context(self, pos: QPointF) -> bool:
        """A right click on a handle's marker opens its menu."""
        index = self.handles.at(self.projection(), pos.x(), pos.y())
        if index < 0:
            return False
        self.handleMenuRequested.emit(index, self.mapToGlobal(pos.toPoint()))
        return True

    def _cursor(self, pos: QPointF) -> Qt.CursorShape:
        """The cursor over ``pos``: a hand over what can be dragged, a cross where a click
        places a handle."""
        if self.node_at(pos) >= 0 or self.handles.at(self.projection(), *pos.toTuple()) >= 0:
            return Qt.CursorShape.OpenHandCursor
        if self.handle_mode:
            return Qt.CursorShape.CrossCursor
        return Qt.CursorShape.ArrowCursor
