"""A running drag in the 3D view: of the selected nodes (from a node or a gizmo arrow) or of
a surface handle's target. The mouse moves the grabbed point in the view plane at its
depth; X / Y / Z lock the move to that world axis, Shift+X / Y / Z to the plane across it
(the same key again unlocks), and Esc cancels. A part of
:class:`~isochor.app.view.viewport.Viewport`; the maths are
:func:`isochor.app.view.picking.drag_delta`. GUI thread only.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject, QPointF, Signal

from . import picking
from .camera import AXES, CameraControl
from .gestures import NodeDrag


class NodeDragger(QObject):
    """The drag that runs, if any, and what it moved.

    Parameters
    ----------
    camera : the view's camera (its projection turns the mouse into a world move)

    Signals
    -------
    started() : a drag of the selected nodes began (a handle's drag is announced by
                :class:`~isochor.app.view.handletool.HandleTool`)
    moved(object) : (3,) world displacement of the grabbed point from the drag start
    finished() : the drag ended where the mouse was released
    canceled() : Esc: the drag goes back
    lockChanged(str) : the axis lock ("" when free)
    guideChanged() : the locked axis changed (or the drag ended): redraw the guide line
    """

    started = Signal()
    moved = Signal(object)
    finished = Signal()
    canceled = Signal()
    lockChanged = Signal(str)
    guideChanged = Signal()

    def __init__(self, camera: CameraControl, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.camera = camera
        self.drag: NodeDrag | None = None  #: the running drag

    @property
    def active(self) -> bool:
        return self.drag is not None

    def begin(
        self, press: QPointF, anchor: np.ndarray, axis: str | None = None, announce: bool = True
    ) -> None:
        """Start a drag of the world point ``anchor`` from the mouse at ``press``
        (``axis``: locked to that world axis from the start); ``announce``: say so
        (``started``; a handle's drag is announced by its tool)."""
        _, depth, _ = self.camera.projection().project(anchor)
        self.drag = NodeDrag(press, anchor, float(depth[0]), press, axis=axis)
        if announce:
            self.started.emit()
        if axis is not None:
            self.guideChanged.emit()
            self.lockChanged.emit(self.drag.lock_text())

    def drop(self) -> None:
        """Forget the drag without a word (a new scene)."""
        self.drag = None

    def move(self, pos: QPointF) -> None:
        """The mouse at ``pos``: the move of the grabbed point (``moved``)."""
        drag = self.drag
        if drag is None:
            return
        drag.pos = pos
        axis = AXES[drag.axis] if drag.axis is not None else None
        delta = picking.drag_delta(
            self.camera.projection(),
            (drag.press.x(), drag.press.y()),
            (pos.x(), pos.y()),
            drag.anchor,
            drag.depth,
            axis,
            drag.plane,
        )
        if delta is not None:
            drag.delta = delta
        self.moved.emit(drag.delta.copy())

    def set_lock(self, axis: str | None, plane: bool = False) -> None:
        """Lock the move to ``axis`` (``plane``: to the plane across it); the same lock
        again unlocks."""
        drag = self.drag
        if drag is None:
            return
        if drag.axis == axis and drag.plane == plane:
            axis, plane = None, False  # the same key again unlocks
        drag.axis, drag.plane = axis, plane
        self.move(drag.pos)
        self.guideChanged.emit()
        self.lockChanged.emit(drag.lock_text())

    def end(self, pos: QPointF) -> None:
        """The button was released at ``pos``: the last move, then ``finished``."""
        self.move(pos)
        self.drag = None
        self.guideChanged.emit()
        self.finished.emit()

    def cancel(self) -> None:
        """Esc: the drag goes back (``canceled``)."""
        if self.drag is None:
            return
        self.drag = None
        self.guideChanged.emit()
        self.canceled.emit()

    def guide(self) -> tuple[str, np.ndarray] | None:
        """The locked axis and the point on it the guide line goes through (the grabbed
        point as moved), or None (no drag, free or locked to a plane)."""
        drag = self.drag
        if drag is None or drag.axis is None or drag.plane:
            return None
        return drag.axis, drag.anchor + drag.delta

    def plane_guide(self) -> tuple[str, np.ndarray] | None:
        """The axis across whose plane the move is locked and the grabbed point as moved,
        or None (no drag, free or locked to an axis)."""
        drag = self.drag
        if drag is None or drag.axis is None or not drag.plane:
            return None
        return drag.axis, drag.anchor + drag.delta
