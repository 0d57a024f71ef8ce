"""The 3D view: camera, overlays and the mouse and key gestures on nodes.

Mouse (left button)
-------------------
- on a node: select it (Shift: add or remove it); drag a selected node to move the whole
  selection in the view plane under the cursor. While dragging, X / Y / Z lock the move to
  that world axis, Shift+X / Y / Z to the plane across it (press again to unlock), and Esc
  cancels the drag back to where it started.
- on empty space: rotate the camera (the usual pyvista trackball); a click without moving
  clears the selection. Shift+drag on empty space (or any drag in box-select mode) draws a
  rubber band that selects the nodes inside it (Shift adds to the selection).
- on a gizmo arrow: drag the selection along that axis; on a handle's marker: select it,
  drag its target; on the model with the Handle tool (or Ctrl): place a handle, and drag
  it at once (:mod:`isochor.app.view.handleview`).
- middle button pans, the wheel zooms, right-drag zooms; a right click opens the context
  menu of the handle or node under the cursor (or of the selection).

Keys: G, R, S grab, rotate and scale the selection (:mod:`isochor.app.view.viewtools`).

The view holds no editing state: it asks for selections and reports drags by signals, and
draws what the window gives it (:class:`~isochor.app.view.scene.Scene` holds the actors). The
projection and picking maths are in :mod:`isochor.app.view.picking`. GUI thread only.
"""

from __future__ import annotations

import time
from contextlib import nullcontext

import numpy as np
from PySide6.QtCore import QPoint, QPointF, QRect, QSize, Qt, Signal
from PySide6.QtWidgets import QLabel, QRubberBand
from pyvistaqt import QtInteractor

from ...core.io.formats import is_model, is_scenario
from . import picking, style
from .camera import AXES, CameraMixin
from .gestures import (
    BoxPress,
    CameraPress,
    ContextPress,
    HandlePress,
    IgnorePress,
    ModelPress,
    NodeDrag,
    NodePress,
)
from .handleview import HandleViewMixin
from .modeldraw import ModelDrawMixin
from .overlays import Gizmo, HandleMarkers, Overlay
from .scene import Scene
from .viewtools import ToolsMixin

#: The mouse must travel this many pixels before a press becomes a drag.
DRAG_THRESHOLD = 3.0


class Viewport(ToolsMixin, HandleViewMixin, ModelDrawMixin, CameraMixin, QtInteractor):
    """The pyvistaqt view with Isochor's actors and node interaction.

    Signals
    -------
    selectRequested(object, str) : select these rows; mode "replace", "add" or "toggle"
    dragStarted() : a node drag began (the selection is about to move)
    dragMoved(object) : (3,) world displacement of the selection from the drag start
    dragFinished() : the button was released after a drag
    dragCanceled() : Esc during a drag: the selection goes back
    lockChanged(str) : the axis lock during a drag ("" when free)
    contextMenuRequested(int, QPoint) : a right click on node row (-1: none), global pos
    fileDropped(str) : a model or scenario file was dropped on the view
    firstPainted() : the view was drawn for the first time
    transformStarted(str) : a grab, rotate or scale began (or changed mode): the undo verb
    transformMoved(object) : (4, 4) affine map of the selection from the gesture's start
    hintChanged(str) : what the running gesture does, for the status line ("" when over)
    handleSelected(int) : a click on handle i's marker
    handlePlaced(int, object) : a click on the model placing a handle: full-mesh triangle,
                                (3,) barycentric weights of the point
    handleDragStarted(int, int, object) : a drag of handle i's target began (i, -1, None),
                                or of a new handle's on the model (-1, triangle, weights);
                                its moves are ``dragMoved``'s, its end ``dragFinished``'s
    handleMenuRequested(int, QPoint) : a right click on handle i's marker, global pos
    modelDrawn() : a big model's full mesh is on screen again after its proxy
    """

    selectRequested = Signal(object, str)
    dragStarted = Signal()
    dragMoved = Signal(object)
    dragFinished = Signal()
    dragCanceled = Signal()
    lockChanged = Signal(str)
    contextMenuRequested = Signal(int, QPoint)
    fileDropped = Signal(str)
    firstPainted = Signal()
    transformStarted = Signal(str)
    transformMoved = Signal(object)
    hintChanged = Signal(str)
    handleSelected = Signal(int)
    handlePlaced = Signal(int, object)
    handleDragStarted = Signal(int, int, object)
    handleMenuRequested = Signal(int, QPoint)
    modelDrawn = Signal()

    def __init__(self, parent=None) -> None:
        super().__init__(parent, auto_update=False, multi_samples=0)
        self.set_background(style.BACKGROUND_BOTTOM, top=style.BACKGROUND_TOP)
        self.setContextMenuPolicy(Qt.ContextMenuPolicy.PreventContextMenu)
        self.setMinimumSize(QSize(320, 240))
        self.scene = Scene(self)
        self.overlay = Overlay(self)
        self.gizmo = Gizmo(self.overlay)
        self.handles = HandleMarkers(self.overlay)
        self.box_mode = False
        self.visible_only = False  #: box selection skips the nodes the model hides
        self.paint_hold = nullcontext  #: around every paint (the window: its solver held)
        self._mouse: QPointF | None = None  # the last mouse position seen
        self._size = 1.0
        self._up = AXES["z"]
        self._press = None
        self._drag: NodeDrag | None = None
        self._needs_home = False
        self.paint_seconds = 0.0  #: how long the last repaint took
        self.paints = 0
        self._band = QRubberBand(QRubberBand.Shape.Rectangle, self)
        self._legend = QLabel(self, objectName="overlay")
        self._legend.setTextFormat(Qt.TextFormat.RichText)
        self._legend.setText(style.legend_html())
        self._legend.move(12, 12)
        self._legend.adjustSize()
        self._legend.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self._info = QLabel(self, objectName="hint")
        self._info.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self._info.hide()

    # -- what is drawn -----------------------------------------------------------------------
    @property
    def nodes(self) -> np.ndarray:
        return self.scene.nodes

    @property
    def selection(self) -> np.ndarray:
        return self.scene.selection

    @property
    def model_volume(self) -> float:
        """Signed volume of the model at the nodes drawn (while a big model's proxy is on
        screen, an estimate: ``scene.volume_estimated``)."""
        return self.scene.volume

    def set_scene(
        self, surface, nodes, pin_axes, moved, *, up: str = "z", reset_camera: bool = True
    ) -> None:
        """Build the actors of a model in a lattice; ``reset_camera`` frames it."""
        self._size = float(surface.size)
        self._up = AXES[up]
        self._drag = None
        self._transform = None
        self.scene.build(surface, nodes, pin_axes, moved)
        self.set_gizmo_size(self._size)
        self.handles.set_size(self._size)
        self.show_gizmo()
        if reset_camera:
            self.home_view()
            # Until the view has its final size its aspect ratio is not known: frame again
            # on the next resize (the first show, a window resized before it is shown).
            self._needs_home = True

    def set_selection(self, rows, repaint: bool = True) -> None:
        """Mark the selected nodes; ``repaint`` False: a frame that follows draws them."""
        self.scene.set_selection(rows)
        self.show_gizmo()
        if repaint:
            self.update()

    def show_info(self, text: str) -> None:
        """A one-line note at the bottom left of the view (empty hides it)."""
        if not text:
            self._info.hide()
            return
        self._info.setText(text)
        self._info.adjustSize()
        self._info.move(12, self.height() - self._info.height() - 12)
        self._info.show()

    def paintGL(self) -> None:
        t0 = time.perf_counter()
        with self.paint_hold():  # the solver starts no step while the renderer has the cores
            super().paintGL()
        self.paint_seconds = time.perf_counter() - t0
        self.paints += 1
        if self.paints == 1:
            self.firstPainted.emit()

    def resizeEvent(self, ev) -> None:
        super().resizeEvent(ev)
        if self._needs_home and self.isVisible() and self.width() > 10:
            self._needs_home = False
            self.home_view()
        if self._info.isVisible():
            self._info.move(12, self.height() - self._info.height() - 12)

    def showEvent(self, ev) -> None:
        super().showEvent(ev)
        if self._needs_home and self.width() > 10:
            self._needs_home = False
            self.home_view()

    # -- dragging ----------------------------------------------------------------------------
    @property
    def dragging(self) -> bool:
        """A node drag, a gizmo drag or a grab, rotate or scale gesture runs."""
        return self._drag is not None or self._transform is not None

    def _update_drag(self, pos: QPointF) -> None:
        drag = self._drag
        drag.pos = pos
        axis = AXES[drag.axis] if drag.axis is not None else None
        delta = picking.drag_delta(
            self.projection(),
            (drag.press.x(), drag.press.y()),
            (pos.x(), pos.y()),
            drag.anchor,
            drag.depth,
            axis,
            drag.plane,
        )
        if delta is not None:
            drag.delta = delta
        self.dragMoved.emit(drag.delta.copy())

    def set_lock(self, axis: str | None, plane: bool = False) -> None:
        drag = self._drag
        if drag is None:
            return
        if drag.axis == axis and drag.plane == plane:
            axis, plane = None, False  # the same key again unlocks
        drag.axis, drag.plane = axis, plane
        self._update_drag(drag.pos)
        self._update_guide()
        self.lockChanged.emit(drag.lock_text())

    def cancel_drag(self) -> None:
        if self._drag is None:
            return
        self._drag = None
        self._press = IgnorePress()
        self._update_guide()
        self.dragCanceled.emit()

    def _end_drag(self) -> None:
        self._drag = None
        self._update_guide()
        self.dragFinished.emit()

    # -- Qt events ---------------------------------------------------------------------------
    def mousePressEvent(self, ev) -> None:
        pos = ev.position()
        self._mouse = QPointF(pos)
        shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
        self.setFocus(Qt.FocusReason.MouseFocusReason)
        if self._transform is not None:  # a click confirms or cancels the gesture
            self._transform_press(ev)
            return
        if self._drag is not None:  # another button during a drag: ignore it
            return
        if ev.button() == Qt.MouseButton.LeftButton:
            row = self.node_at(pos)
            if (row < 0 or row in self.selection) and not shift and self._gizmo_press(pos):
                return
            if not shift and self._handle_press(pos):
                self.hold_proxy()
                return
            if row >= 0:
                if shift:
                    self.selectRequested.emit([row], "toggle")
                    self._press = IgnorePress()
                    return
                self.hold_proxy()  # a drag may follow: what the press redraws is the proxy
                if row not in self.selection:
                    self.selectRequested.emit([row], "replace")
                self._press = NodePress(row, pos)
                return
            ctrl = bool(ev.modifiers() & Qt.KeyboardModifier.ControlModifier)
            if (self.handle_mode or ctrl) and not shift and self._model_press(pos):
                self.hold_proxy()
                return
            if shift or self.box_mode:
                self._press = BoxPress(pos, shift)
                self._band.setGeometry(QRect(pos.toPoint(), QSize()))
                self._band.show()
                return
            self._press = CameraPress(pos)
        elif ev.button() == Qt.MouseButton.RightButton:
            self._press = ContextPress(pos)
        else:
            self._press = CameraPress(pos)
        super().mousePressEvent(ev)

    def mouseMoveEvent(self, ev) -> None:
        pos = ev.position()
        self._mouse = QPointF(pos)
        press = self._press
        if self._transform is not None:
            self._transform_mouse(pos)
            return
        if self._drag is not None and isinstance(press, IgnorePress):  # a gizmo arrow
            self._update_drag(pos)
            return
        if press is None:
            self._hover(pos)
            super().mouseMoveEvent(ev)
        elif isinstance(press, NodePress):
            if self._drag is None:
                if (pos - press.pos).manhattanLength() < DRAG_THRESHOLD:
                    return
                anchor = self.nodes[press.row].copy()
                _, depth, _ = self.projection().project(anchor)
                self._drag = NodeDrag(press.pos, anchor, float(depth[0]), press.pos)
                self.dragStarted.emit()
            self._update_drag(pos)
        elif isinstance(press, (HandlePress, ModelPress)):
            self._handle_move(press, pos)
        elif isinstance(press, BoxPress):
            self._band.setGeometry(QRect(press.pos.toPoint(), pos.toPoint()).normalized())
        elif not isinstance(press, IgnorePress):
            super().mouseMoveEvent(ev)

    def mouseReleaseEvent(self, ev) -> None:
        dragged = self._drag is not None
        self._release(ev)
        self.end_press(dragged)

    def _release(self, ev) -> None:
        pos = ev.position()
        press, self._press = self._press, None
        if self._drag is not None and isinstance(press, IgnorePress):  # a gizmo arrow
            self._update_drag(pos)
            self._end_drag()
            return
        if press is None or isinstance(press, IgnorePress):
            if press is None:
                super().mouseReleaseEvent(ev)
            self._hover(pos)
            return
        moved = (pos - press.pos).manhattanLength() >= DRAG_THRESHOLD
        if isinstance(press, NodePress):
            if self._drag is not None:
                self._update_drag(pos)
                self._end_drag()
            elif len(self.selection) > 1:
                self.selectRequested.emit([press.row], "replace")
        elif isinstance(press, (HandlePress, ModelPress)):
            self._handle_release(press, pos)
        elif isinstance(press, BoxPress):
            self._band.hide()
            rows = self.nodes_in_rect(QRect(press.pos.toPoint(), pos.toPoint()).normalized())
            if self.visible_only:
                rows = self.visible_rows(rows)
            self.selectRequested.emit(rows, "add" if press.add else "replace")
        elif isinstance(press, CameraPress):
            super().mouseReleaseEvent(ev)
            if not moved and ev.button() == Qt.MouseButton.LeftButton:
                self.selectRequested.emit([], "replace")
        elif isinstance(press, ContextPress):
            super().mouseReleaseEvent(ev)
            if not moved and not self._handle_context(pos):
                self.contextMenuRequested.emit(self.node_at(pos), self.mapToGlobal(pos.toPoint()))
        self._hover(pos)

    def _hover(self, pos: QPointF) -> None:
        self.setCursor(self._cursor(pos))

    # -- files dropped on the view (pyvistaqt would add them as extra actors) ----------------
    @staticmethod
    def _dropped_file(ev) -> str | None:
        urls = ev.mimeData().urls() if ev.mimeData() is not None else []
        for url in urls:
            path = url.toLocalFile()
            if is_model(path) or is_scenario(path):
                return path
        return None

    def dragEnterEvent(self, ev) -> None:
        if self._dropped_file(ev):
            ev.acceptProposedAction()
        else:
            ev.ignore()

    def dropEvent(self, ev) -> None:
        path = self._dropped_file(ev)
        if path:
            ev.acceptProposedAction()
            self.fileDropped.emit(path)

    def keyPressEvent(self, ev) -> None:
        key = ev.key()
        if self._transform is not None and self._transform_key(ev):
            return
        if self._drag is not None and not ev.isAutoRepeat():
            axis = {Qt.Key.Key_X: "x", Qt.Key.Key_Y: "y", Qt.Key.Key_Z: "z"}.get(key)
            if axis is not None:
                self.set_lock(axis, bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier))
                return
        if key == Qt.Key.Key_Escape:
            if self._drag is not None:
                self.cancel_drag()
            elif isinstance(self._press, BoxPress):
                self._band.hide()
                self._press = IgnorePress()
            else:
                self.selectRequested.emit([], "replace")
            return
        # Every other key goes to the window's actions, never to the VTK interactor style
        # (whose single-letter keys would switch to wireframe, stereo, or quit).
        ev.ignore()

    def keyReleaseEvent(self, ev) -> None:
        ev.ignore()
