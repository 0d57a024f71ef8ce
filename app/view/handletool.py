"""The view's surface handles: placing one with a click on the model (the Handle tool, or
Ctrl+click), selecting one with a click on its marker, and dragging its target in the view
plane at its depth (X/Y/Z lock an axis, as for node drags: the drag is the
:class:`~isochor.app.view.nodedrag.NodeDragger`'s). A part of
:class:`~isochor.app.view.viewport.Viewport`; the markers are
:class:`~isochor.app.view.overlays.HandleMarkers`. GUI thread only.

The view only says what the user did (signals); the window turns a hit on the model into the
model's rest point (:meth:`isochor.app.editor.handlerules.HandleRules.rest_point`) and the session
runs the drag like a node drag.
"""

from __future__ import annotations

from PySide6.QtCore import QObject, QPoint, QPointF, Qt, Signal

from .camera import CameraControl
from .gestures import HandlePress, ModelPress
from .nodedrag import NodeDragger
from .overlays import HandleMarkers
from .scene import Scene

#: The mouse must travel this many pixels before a press on a handle or the model drags.
HANDLE_DRAG = 3.0


class HandleTool(QObject):
    """The presses on handles and on the model, and the Handle tool's switch.

    Parameters
    ----------
    camera : the view's camera (its projection; what is under the cursor)
    scene : the model as drawn
    markers : the handles' markers (where their targets are drawn)
    dragger : runs the drag of a target

    Attributes
    ----------
    active : the Handle tool is on: a click on the model places a handle

    Signals
    -------
    selected(int) : a click on handle i's marker
    placed(int, object) : a click on the model placing a handle: full-mesh triangle,
                          (3,) barycentric weights of the point
    dragStarted(int, int, object) : a drag of handle i's target began (i, -1, None), or of
                                    a new handle's on the model (-1, triangle, weights)
    menuRequested(int, QPoint) : a right click on handle i's marker, global position
    """

    selected = Signal(int)
    placed = Signal(int, object)
    dragStarted = Signal(int, int, object)
    menuRequested = Signal(int, QPoint)

    def __init__(
        self,
        camera: CameraControl,
        scene: Scene,
        markers: HandleMarkers,
        dragger: NodeDragger,
        parent: QObject | None = None,
    ) -> None:
        super().__init__(parent)
        self.camera = camera
        self.scene = scene
        self.markers = markers
        self.dragger = dragger
        self.active = False

    def set_active(self, on: bool) -> None:
        """The Handle tool on (a click on the model places a handle) or off."""
        self.active = bool(on)

    def handle_at(self, pos: QPointF) -> int:
        """The user's handle whose marker is drawn under ``pos``, or -1."""
        return self.markers.at(self.camera.projection(), pos.x(), pos.y())

    def press(self, pos: QPointF) -> HandlePress | None:
        """A left press on a handle's marker, or None."""
        index = self.handle_at(pos)
        if index < 0:
            return None
        return HandlePress(index, QPointF(pos))

    def model_press(self, pos: QPointF) -> ModelPress | None:
        """A left press on the model that places a handle (Handle tool or Ctrl), or None."""
        if not self.scene.built:
            return None
        hit = self.camera.model_hit(pos)
        if hit is None:
            return None
        face, weights, point = hit
        return ModelPress(QPointF(pos), face, weights, point)

    def move(self, press: HandlePress | ModelPress, pos: QPointF) -> None:
        """A move during a press on a handle or on the model: a drag of the target once
        the mouse travels."""
        if not self.dragger.active:
            if (pos - press.pos).manhattanLength() < HANDLE_DRAG:
                return
            if isinstance(press, HandlePress):
                anchor = self.markers.targets[press.index].copy()
            else:
                anchor = press.point.copy()
            self.dragger.begin(press.pos, anchor, announce=False)
            if isinstance(press, HandlePress):
                self.dragStarted.emit(press.index, -1, None)
            else:
                self.dragStarted.emit(-1, press.face, press.weights)
        self.dragger.move(pos)

    def release(self, press: HandlePress | ModelPress, pos: QPointF) -> None:
        """The press ended: the drag's end, or a click (select the handle, place one)."""
        if self.dragger.active:
            self.dragger.end(pos)
        elif isinstance(press, HandlePress):
            self.selected.emit(press.index)
        else:
            self.placed.emit(press.face, press.weights)

    def context(self, pos: QPointF, global_pos: QPoint) -> bool:
        """A right click on a handle's marker opens its menu (True)."""
        index = self.handle_at(pos)
        if index < 0:
            return False
        self.menuRequested.emit(index, global_pos)
        return True

    def cursor(self, pos: QPointF) -> Qt.CursorShape:
        """The cursor over ``pos``: a hand over what can be dragged, a cross where a click
        places a handle."""
        if self.camera.node_at(pos, placing=self.active) >= 0 or self.handle_at(pos) >= 0:
            return Qt.CursorShape.OpenHandCursor
        if self.active:
            return Qt.CursorShape.CrossCursor
        return Qt.CursorShape.ArrowCursor
