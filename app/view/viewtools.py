"""The view's tools on the node selection: the grab, rotate and scale gestures (G, R, S), the
translate gizmo, framing the selection, the orthographic camera, and box selection of the
nodes the model does not hide. A mixin of :class:`~isochor.app.view.viewport.Viewport`; the
gesture's maths are :mod:`isochor.app.editor.transform`'s. GUI thread only.

A gesture is modal: it starts at the mouse position, the mouse moves it (no button held),
X/Y/Z lock it to a world axis (Shift: the plane across it), typed digits override the mouse,
Enter or a left click confirms (one undo step), Esc or a right click cancels. During a
gesture every key goes to the view, not to the window's shortcuts (``1`` is a digit then,
not the front view).
"""

from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QEvent, QPointF, Qt

from ..editor.transform import VERBS, Transform, unit
from . import picking, style
from .gestures import IgnorePress, NodeDrag
from .overlays import GIZMO_FRACTION

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


class ToolsMixin:
    """Needs the viewport's ``scene``, ``gizmo``, ``nodes``, ``selection``, ``projection()``,
    ``_drag``, ``_press``, ``_size`` and its signals."""

    _transform: Transform | None = None

    # -- the gesture -------------------------------------------------------------------------
    @property
    def transforming(self) -> bool:
        return self._transform is not None

    def _view_vector(self, at: np.ndarray) -> np.ndarray:
        """(3,) unit vector from ``at`` towards the viewer."""
        cam = self.renderer.GetActiveCamera()
        if cam.GetParallelProjection():
            v = -np.array(cam.GetDirectionOfProjection())
        else:
            v = np.array(cam.GetPosition()) - at
        n = np.linalg.norm(v)
        return v / n if n > 0 else unit("z")

    def start_transform(self, mode: str) -> bool:
        """Start a grab, rotate or scale of the selection at the mouse (False: nothing
        selected, the lattice hidden, or a drag runs)."""
        if self._drag is not None or len(self.selection) == 0 or not self.scene.show_lattice:
            return False
        if self._transform is not None:  # G, R or S again: the same gesture, another mode
            self._transform.set_mode(mode)
            self._turned, self._last_angle = 0.0, self._screen_angle(self._gesture_start)
            self.transformStarted.emit(VERBS[mode])
            self._transform_mouse(self._gesture_pos)
            return True
        centre = self.nodes[self.selection].mean(axis=0)
        xy, depth, _ = self.projection().project(centre)
        self._centre_xy, self._centre_depth = xy[0], float(depth[0])
        mouse = self._mouse
        inside = mouse is not None and self.rect().contains(mouse.toPoint())
        start = mouse if inside else QPointF(*(self._centre_xy + (90.0, -60.0)))
        self._transform = Transform(mode, centre, self._view_vector(centre))
        self._gesture_start = QPointF(start)
        self._gesture_pos = QPointF(start)
        self._turned = 0.0
        self._last_angle = self._screen_angle(start)
        self._press = IgnorePress()
        self.setFocus(Qt.FocusReason.OtherFocusReason)
        self.gizmo.hide()
        self.transformStarted.emit(VERBS[mode])
        self._transform_changed()
        return True

    def _screen_angle(self, pos: QPointF) -> float:
        c = self._centre_xy
        return math.atan2(-(pos.y() - c[1]), pos.x() - c[0])

    def _transform_mouse(self, pos: QPointF) -> None:
        """What the mouse at ``pos`` says for the running gesture."""
        t = self._transform
        self._gesture_pos = QPointF(pos)
        start = self._gesture_start
        if t.mode == "grab":
            axis = unit(t.axis) if t.axis is not None else None
            delta = picking.drag_delta(
                self.projection(),
                (start.x(), start.y()),
                (pos.x(), pos.y()),
                t.centre,
                self._centre_depth,
                axis,
                t.plane,
            )
            if delta is not None:
                t.mouse = delta
        elif t.mode == "rotate":
            angle = self._screen_angle(pos)
            step = (angle - self._last_angle + math.pi) % (2 * math.pi) - math.pi
            self._last_angle = angle
            self._turned += step
            towards = float(t.rotation_axis() @ t.view)
            t.mouse = self._turned * (-1.0 if towards < 0 else 1.0)
        else:
            c = self._centre_xy
            r0 = math.hypot(start.x() - c[0], start.y() - c[1])
            r = math.hypot(pos.x() - c[0], pos.y() - c[1])
            t.mouse = max(0.0, 1.0 + (r - r0) / max(r0, SCALE_RADIUS))
        self._transform_changed()

    def _transform_changed(self) -> None:
        t = self._transform
        self.transformMoved.emit(t.matrix())
        self._update_guide()
        self.hintChanged.emit(t.text())

    def finish_transform(self) -> None:
        """Confirm the gesture: its edit is committed (one undo step)."""
        if self._transform is None:
            return
        self._transform = None
        self._update_guide()
        self.hintChanged.emit("")
        self.dragFinished.emit()
        self.show_gizmo()

    def cancel_transform(self) -> None:
        """Cancel the gesture: the selection goes back."""
        if self._transform is None:
            return
        self._transform = None
        self._update_guide()
        self.hintChanged.emit("")
        self.dragCanceled.emit()
        self.show_gizmo()

    def _transform_key(self, ev) -> bool:
        """A key during a gesture; True when it was the gesture's."""
        t = self._transform
        key = ev.key()
        if key in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
            self.finish_transform()
        elif key == Qt.Key.Key_Escape:
            self.cancel_transform()
        elif key in AXIS_KEYS:
            shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            t.lock(AXIS_KEYS[key], shift)
            self._transform_mouse(self._gesture_pos)
        elif key in MODE_KEYS:
            self.start_transform(MODE_KEYS[key])
        elif key in TYPED_KEYS and t.type_key(TYPED_KEYS[key]):
            self._transform_changed()
        else:
            return False
        return True

    def _transform_press(self, ev) -> None:
        if ev.button() == Qt.MouseButton.LeftButton:
            if not self._transform.typing:
                self._transform_mouse(ev.position())
            self.finish_transform()
        elif ev.button() == Qt.MouseButton.RightButton:
            self.cancel_transform()
        self._press = IgnorePress()

    # -- the gizmo ---------------------------------------------------------------------------
    def show_gizmo(self) -> None:
        """The gizmo at the centre of the selection as drawn (hidden without one, with the
        lattice hidden, and during a gesture)."""
        if not hasattr(self, "gizmo"):
            return
        rows = self.selection[self.selection < len(self.nodes)]
        if len(rows) == 0 or not self.scene.show_lattice or self._transform is not None:
            self.gizmo.hide()
            return
        self.gizmo.show_at(self.nodes[rows].mean(axis=0))

    def set_gizmo_size(self, size: float) -> None:
        self.gizmo.set_length(GIZMO_FRACTION * size)

    def _gizmo_press(self, pos: QPointF) -> bool:
        """A press on a gizmo arrow starts a drag of the selection along its axis."""
        axis = self.gizmo.axis_at(self.projection(), pos.x(), pos.y())
        if axis is None:
            return False
        centre = self.gizmo.centre.copy()
        _, depth, _ = self.projection().project(centre)
        self._press = IgnorePress()
        self._drag = NodeDrag(pos, centre, float(depth[0]), pos, axis=axis)
        self._gizmo_drag = True
        self.dragStarted.emit()
        self._update_guide()
        self.lockChanged.emit(self._drag.lock_text())
        return True

    # -- the guide line ----------------------------------------------------------------------
    def _update_guide(self) -> None:
        """The guide line of a locked axis through the dragged point, in the axis's colour."""
        drag, t = self._drag, self._transform
        axis, c = None, None
        if drag is not None and drag.axis is not None and not drag.plane:
            axis, c = drag.axis, drag.anchor + drag.delta
        elif t is not None and t.guide_axis() is not None:
            axis = t.guide_axis()
            m = t.matrix()
            c = m[:3, :3] @ t.centre + m[:3, 3]
        if axis is None:
            self.scene.set_guide(None)
            return
        a = unit(axis) * 3 * self._size
        self.scene.set_guide(np.array([c - a, c + a]), style.AXIS_COLOURS[axis])

    # -- camera ------------------------------------------------------------------------------
    def frame_selection(self) -> None:
        """Fit the selected nodes in the view (the whole model when nothing is selected)."""
        rows = self.selection[self.selection < len(self.nodes)]
        if len(rows) == 0 or not self.scene.built:
            self.frame()
            return
        pts = self.nodes[rows]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = max(0.12 * self._size - (hi - lo).max() / 2, 0.0) + 0.05 * self._size
        lo, hi = lo - pad, hi + pad
        corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T
        self.reset_camera(render=False, bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        self._fit(corners)
        self.renderer.ResetCameraClippingRange(*self._clip_bounds())
        self.update()

    def _clip_bounds(self) -> tuple:
        """The scene's bounds (the clipping range must hold all of it, not only what is
        framed)."""
        pts = self._framed_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])

    def set_orthographic(self, on: bool) -> None:
        """Parallel projection (on) or perspective, keeping what is in view about the same
        size."""
        cam = self.renderer.GetActiveCamera()
        if bool(cam.GetParallelProjection()) == bool(on):
            return
        distance = cam.GetDistance()
        if on:
            cam.SetParallelScale(distance * math.tan(math.radians(cam.GetViewAngle()) / 2))
        cam.SetParallelProjection(bool(on))
        self.renderer.ResetCameraClippingRange(*self._clip_bounds())
        self.update()

    @property
    def orthographic(self) -> bool:
        return bool(self.renderer.GetActiveCamera().GetParallelProjection())

    # -- box selection of what is seen ---------------------------------------------------------
    def visible_rows(self, rows) -> np.ndarray:
        """The given node rows the model does not hide (the deformed model as drawn)."""
        rows = np.asarray(rows, dtype=int)
        if len(rows) == 0 or not self.scene.built:
            return rows
        verts, faces = self.scene.model_points(), self.scene.model_faces()
        hidden = picking.occluded(self.projection(), self.nodes[rows], verts, faces)
        return rows[~hidden]

    # -- events ------------------------------------------------------------------------------
    def event(self, ev) -> bool:
        # during a gesture or drag every key is the view's: not "1" for the front view
        if ev.type() == QEvent.Type.ShortcutOverride and (
            self._transform is not None or self._drag is not None
        ):
            ev.accept()
            return True
        return super().event(ev)
