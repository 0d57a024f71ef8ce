"""The view's grab, rotate and scale gestures on the node selection (G, R, S). A part of
:class:`~isochor.app.view.viewport.Viewport`; the gesture's maths are
:mod:`isochor.app.editor.transform`'s. GUI thread only.

A gesture is modal: it starts at the mouse position, the mouse moves it (no button held),
X/Y/Z lock it to a world axis (Shift: the plane across it), typed digits override the mouse,
Enter or a left click confirms (one undo step), Esc or a right click cancels. During a
gesture every key goes to the view, not to the window's shortcuts (``1`` is a digit then,
not the front view).
"""

from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QObject, QPointF, Qt, Signal

from ..editor.transform import VERBS, Transform, unit
from . import picking
from .camera import CameraControl
from .scene import Scene

#: keys -> the text a gesture types
TYPED_KEYS = {getattr(Qt.Key, f"Key_{d}"): str(d) for d in range(10)} | {
    Qt.Key.Key_Period: ".",
    Qt.Key.Key_Comma: ".",
    Qt.Key.Key_Minus: "-",
    Qt.Key.Key_Backspace: "\b",
}
AXIS_KEYS = {Qt.Key.Key_X: "x", Qt.Key.Key_Y: "y", Qt.Key.Key_Z: "z"}
MODE_KEYS = {Qt.Key.Key_G: "grab", Qt.Key.Key_R: "rotate", Qt.Key.Key_S: "scale"}
#: a scale gesture that starts nearer the centre than this many pixels measures from here
SCALE_RADIUS = 24.0


class TransformTool(QObject):
    """The gesture that runs, if any, and where the mouse has taken it.

    Parameters
    ----------
    camera : the view's camera (projection, the direction towards the viewer)
    scene : the nodes and the selection as drawn

    Signals
    -------
    started(str, bool) : a gesture began (True) or changed mode (False); its undo verb
    moved(object) : (4, 4) affine map of the selection from the gesture's start
    hintChanged(str) : what the gesture does, for the status line ("" when it ended)
    finished() : confirmed (one undo step)
    canceled() : cancelled: the selection goes back
    guideChanged() : the locked axis or the map changed (or the gesture ended): redraw
                     the guide line
    """

    started = Signal(str, bool)
    moved = Signal(object)
    hintChanged = Signal(str)
    finished = Signal()
    canceled = Signal()
    guideChanged = Signal()

    def __init__(self, camera: CameraControl, scene: Scene, parent: QObject | None = None):
        super().__init__(parent)
        self.camera = camera
        self.scene = scene
        self.transform: Transform | None = None  #: the running gesture
        self._centre_xy = np.zeros(2)  # the selection's centre on screen, and its depth
        self._centre_depth = 0.0
        self._start = QPointF()  # where the mouse started the gesture, and is now
        self._pos = QPointF()
        self._turned = 0.0  # a rotation's angle so far, and the mouse's last angle
        self._last_angle = 0.0

    @property
    def running(self) -> bool:
        return self.transform is not None

    def start(self, mode: str, mouse: QPointF | None) -> bool:
        """Start a grab, rotate or scale of the selection from the mouse at ``mouse``
        (None: the mouse is not over the view; the gesture starts beside the selection's
        centre). During a gesture, the same gesture in another mode. False: nothing
        selected, or the lattice hidden."""
        if len(self.scene.selection) == 0 or not self.scene.show_lattice:
            return False
        if self.transform is not None:  # G, R or S again: the same gesture, another mode
            self.transform.set_mode(mode)
            self._turned, self._last_angle = 0.0, self._screen_angle(self._start)
            self.started.emit(VERBS[mode], False)
            self.mouse(self._pos)
            return True
        centre = self.scene.nodes[self.scene.selection].mean(axis=0)
        xy, depth, _ = self.camera.projection().project(centre)
        self._centre_xy, self._centre_depth = xy[0], float(depth[0])
        start = mouse if mouse is not None else QPointF(*(self._centre_xy + (90.0, -60.0)))
        self.transform = Transform(mode, centre, self.camera.view_vector(centre))
        self._start = QPointF(start)
        self._pos = QPointF(start)
        self._turned = 0.0
        self._last_angle = self._screen_angle(start)
        self.started.emit(VERBS[mode], True)
        self._changed()
        return True

    def drop(self) -> None:
        """Forget the gesture without a word (a new scene)."""
        self.transform = None

    def _screen_angle(self, pos: QPointF) -> float:
        c = self._centre_xy
        return math.atan2(-(pos.y() - c[1]), pos.x() - c[0])

    def mouse(self, pos: QPointF) -> None:
        """What the mouse at ``pos`` says for the running gesture."""
        t = self.transform
        if t is None:
            return
        self._pos = QPointF(pos)
        start = self._start
        if t.mode == "grab":
            axis = unit(t.axis) if t.axis is not None else None
            delta = picking.drag_delta(
                self.camera.projection(),
                (start.x(), start.y()),
                (pos.x(), pos.y()),
                t.centre,
                self._centre_depth,
                axis,
                t.plane,
            )
            if delta is not None:
                t.follow(delta)
        elif t.mode == "rotate":
            angle = self._screen_angle(pos)
            step = (angle - self._last_angle + math.pi) % (2 * math.pi) - math.pi
            self._last_angle = angle
            self._turned += step
            towards = float(t.rotation_axis() @ t.view)
            t.follow(self._turned * (-1.0 if towards < 0 else 1.0))
        else:
            c = self._centre_xy
            r0 = math.hypot(start.x() - c[0], start.y() - c[1])
            r = math.hypot(pos.x() - c[0], pos.y() - c[1])
            t.follow(max(0.0, 1.0 + (r - r0) / max(r0, SCALE_RADIUS)))
        self._changed()

    def _changed(self) -> None:
        t = self.transform
        assert t is not None
        self.moved.emit(t.matrix())
        self.guideChanged.emit()
        self.hintChanged.emit(t.text())

    def finish(self) -> None:
        """Confirm the gesture: its edit is committed (one undo step)."""
        if self.transform is None:
            return
        self.transform = None
        self.guideChanged.emit()
        self.hintChanged.emit("")
        self.finished.emit()

    def cancel(self) -> None:
        """Cancel the gesture: the selection goes back."""
        if self.transform is None:
            return
        self.transform = None
        self.guideChanged.emit()
        self.hintChanged.emit("")
        self.canceled.emit()

    def key(self, ev) -> bool:
        """A key during a gesture; True when it was the gesture's."""
        t = self.transform
        if t is None:
            return False
        key = ev.key()
        if key in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
            self.finish()
        elif key == Qt.Key.Key_Escape:
            self.cancel()
        elif key in AXIS_KEYS:
            shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            t.lock(AXIS_KEYS[key], shift)
            self.mouse(self._pos)
        elif key in MODE_KEYS:
            self.start(MODE_KEYS[key], None)
        elif key in TYPED_KEYS and t.type_key(TYPED_KEYS[key]):
            self._changed()
        else:
            return False
        return True

    def press(self, button: Qt.MouseButton, pos: QPointF) -> None:
        """A mouse press during the gesture: the left button confirms it (where the mouse
        is, unless a value was typed), the right one cancels it."""
        t = self.transform
        if t is None:
            return
        if button == Qt.MouseButton.LeftButton:
            if not t.typing:
                self.mouse(pos)
            self.finish()
        elif button == Qt.MouseButton.RightButton:
            self.cancel()

    def guide(self) -> tuple[str, np.ndarray] | None:
        """The locked axis and the point on it the guide line goes through (the
        selection's centre as mapped), or None."""
        t = self.transform
        axis = t.guide_axis() if t is not None else None
        if t is None or axis is None:
            return None
        m = t.matrix()
        return axis, m[:3, :3] @ t.centre + m[:3, 3]

    def plane_guide(self) -> tuple[str, np.ndarray] | None:
        """The axis across whose plane the gesture is locked and the selection's centre as
        mapped, or None."""
        t = self.transform
        if t is None or t.axis is None or not t.plane:
            return None
        m = t.matrix()
        return t.axis, m[:3, :3] @ t.centre + m[:3, 3]
