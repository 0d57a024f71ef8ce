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
  it at once (:mod:`isochor.app.view.handletool`).
- middle button pans, the wheel zooms, right-drag zooms; a right click opens the context
  menu of the handle or node under the cursor (or of the selection).

Keys: G, R, S grab, rotate and scale the selection (:mod:`isochor.app.view.transformtool`).

The view holds no editing state: it asks for selections and reports drags by signals, and
draws what the window gives it. It is composed of parts that own their state, and its Qt
event handlers dispatch to them: the actors (:class:`~isochor.app.view.scene.Scene`), the
camera (:class:`~isochor.app.view.camera.CameraControl`), the running drag
(:class:`~isochor.app.view.nodedrag.NodeDragger`), the G/R/S gestures
(:class:`~isochor.app.view.transformtool.TransformTool`), the handle gestures
(:class:`~isochor.app.view.handletool.HandleTool`), the model's frames
(:class:`~isochor.app.view.modeldraw.ModelFrames`) and the overlays (the gizmo, the handle
markers). The projection and picking maths are in :mod:`isochor.app.view.picking`. GUI
thread only.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext

import numpy as np
from PySide6.QtCore import QEvent, QPoint, QPointF, QRect, QSize, Qt, Signal
from PySide6.QtWidgets import QLabel, QRubberBand
from pyvistaqt import QtInteractor

from ...core.io.formats import is_model, is_scenario
from ..editor.transform import unit
from . import style
from .camera import AXES, CameraControl
from .gestures import (
    BoxPress,
    CameraPress,
    ContextPress,
    HandlePress,
    IgnorePress,
    ModelPress,
    NodePress,
    Press,
)
from .handletool import HandleTool
from .modeldraw import ModelFrames
from .nodedrag import NodeDragger
from .overlays import GIZMO_FRACTION, Gizmo, HandleMarkers, Overlay
from .scene import Scene
from .transformtool import TransformTool

#: The mouse must travel this many pixels before a press becomes a drag.
DRAG_THRESHOLD = 3.0


class Viewport(QtInteractor):
    """The pyvistaqt view with Isochor's actors and node interaction.

    Parameters
    ----------
    parent : the parent widget
    paint_hold : the context every paint runs in (the window's: its solver held, so that
                 the solver starts no step while the renderer has the cores)

    Attributes
    ----------
    scene : :class:`~isochor.app.view.scene.Scene`, the actors
    camera_control : :class:`~isochor.app.view.camera.CameraControl`, where the view looks
                     and what is under a point of it
    node_drag : :class:`~isochor.app.view.nodedrag.NodeDragger`, the running drag
    transform_tool : :class:`~isochor.app.view.transformtool.TransformTool`, G / R / S
    handle_tool : :class:`~isochor.app.view.handletool.HandleTool`, the handle gestures
    model_frames : :class:`~isochor.app.view.modeldraw.ModelFrames`, the model's frames
    gizmo, handles : the overlays (:mod:`isochor.app.view.overlays`)
    colour_legend : the colour legend at the top left
    box_mode : any drag on empty space draws a selection box
    visible_only : box selection skips the nodes the model hides
    paints, paint_seconds : how many times the view was drawn, and how long the last took

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

    def __init__(
        self,
        parent=None,
        paint_hold: Callable[[], AbstractContextManager] = nullcontext,
    ) -> None:
        super().__init__(parent, auto_update=False, multi_samples=0)
        self.set_background(style.BACKGROUND_BOTTOM, top=style.BACKGROUND_TOP)
        self.setContextMenuPolicy(Qt.ContextMenuPolicy.PreventContextMenu)
        self.setMinimumSize(QSize(320, 240))
        self.scene = Scene(self)
        self.overlay = Overlay(self)
        self.gizmo = Gizmo(self.overlay)
        self.handles = HandleMarkers(self.overlay)
        self.camera_control = CameraControl(self, self.scene)
        self.node_drag = NodeDragger(self.camera_control, self)
        self.transform_tool = TransformTool(self.camera_control, self.scene, self)
        self.handle_tool = HandleTool(
            self.camera_control, self.scene, self.handles, self.node_drag, self
        )
        self.model_frames = ModelFrames(self.scene, self.repaint, self)
        self.box_mode = False
        self.visible_only = False
        self.paint_seconds = 0.0
        self.paints = 0
        self._paint_hold = paint_hold
        self._mouse: QPointF | None = None  # the last mouse position seen
        self._press: Press | None = None  # what the running mouse press started
        self._band = QRubberBand(QRubberBand.Shape.Rectangle, self)
        self.colour_legend = QLabel(self, objectName="overlay")
        self.colour_legend.setTextFormat(Qt.TextFormat.RichText)
        self.colour_legend.setText(style.legend_html())
        self.colour_legend.move(12, 12)
        self.colour_legend.adjustSize()
        self.colour_legend.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self._info = QLabel(self, objectName="hint")
        self._info.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self._info.hide()
        self._connect_parts()

    def _connect_parts(self) -> None:
        """The parts' signals are the view's (and redraw what they change)."""
        d = self.node_drag
        d.started.connect(self.dragStarted)
        d.moved.connect(self.dragMoved)
        d.finished.connect(self.dragFinished)
        d.canceled.connect(self.dragCanceled)
        d.lockChanged.connect(self.lockChanged)
        d.guideChanged.connect(self._update_guide)
        t = self.transform_tool
        t.started.connect(self._transform_started)
        t.moved.connect(self.transformMoved)
        t.guideChanged.connect(self._update_guide)
        t.hintChanged.connect(self.hintChanged)
        t.finished.connect(self.dragFinished)
        t.finished.connect(self.show_gizmo)
        t.canceled.connect(self.dragCanceled)
        t.canceled.connect(self.show_gizmo)
        h = self.handle_tool
        h.selected.connect(self.handleSelected)
        h.placed.connect(self.handlePlaced)
        h.dragStarted.connect(self.handleDragStarted)
        h.menuRequested.connect(self.handleMenuRequested)
        self.model_frames.drawn.connect(self.modelDrawn)

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
        size = float(surface.size)
        self.camera_control.set_up(AXES[up])
        self.node_drag.drop()
        self.transform_tool.drop()
        self.scene.build(surface, nodes, pin_axes, moved)
        self.gizmo.set_length(GIZMO_FRACTION * size)
        self.handles.set_size(size)
        self.show_gizmo()
        if reset_camera:
            # Until the view has its final size its aspect ratio is not known: frame again
            # on the next resize (the first show, a window resized before it is shown).
            self.camera_control.home_view(again_when_sized=True)

    def set_selection(self, rows, repaint: bool = True) -> None:
        """Mark the selected nodes; ``repaint`` False: a frame that follows draws them."""
        self.scene.set_selection(rows)
        self.show_gizmo()
        if repaint:
            self.update()

    def set_frame(self, nodes: np.ndarray, moving: bool = False) -> None:
        """Place the lattice and the model at ``nodes`` (a big model as its proxy while
        ``moving``); the view renders at its next paint."""
        self.model_frames.place(nodes, moving)
        if self.dragging:
            self._update_guide()
        self.show_gizmo()

    def show_gizmo(self) -> None:
        """The gizmo at the centre of the selection as drawn (hidden without one, with the
        lattice hidden, and during a gesture)."""
        rows = self.scene.selected_rows()
        if len(rows) == 0 or not self.scene.show_lattice or self.transform_tool.running:
            self.gizmo.hide()
            return
        self.gizmo.show_at(self.nodes[rows].mean(axis=0))

    def _update_guide(self) -> None:
        """The guide line of a locked axis through the dragged point, in the axis's colour
        (a drag's, or a grab, rotate or scale's)."""
        line = self.node_drag.guide() or self.transform_tool.guide()
        plane = self.node_drag.plane_guide() or self.transform_tool.plane_guide()
        reach = 3 * self.scene.size
        if line is not None:
            axis, c = line
            a = unit(axis) * reach
            self.scene.set_guide(np.array([c - a, c + a]), style.AXIS_COLOURS[axis])
        elif plane is not None:  # a cross of the plane's two axes, in the guide's colour
            axis, c = plane
            u, v = (unit(o) * reach for o in "xyz" if o != axis)
            self.scene.set_guide(np.array([c - u, c + u, c - v, c + v]), style.GUIDE)
        else:
            self.scene.set_guide(None)

    def show_info(self, text: str) -> None:
        """A one-line note at the bottom left of the view (empty hides it)."""
        if not text:
            self._info.hide()
            return
        self._info.setText(text)
        self._info.adjustSize()
        self._info.move(12, self.height() - self._info.height() - 12)
        self._info.show()

    def set_box_mode(self, on: bool) -> None:
        """Any drag on empty space draws a selection box (on), or turns the camera."""
        self.box_mode = bool(on)

    def set_visible_only(self, on: bool) -> None:
        """Box selection skips the nodes the model hides (on)."""
        self.visible_only = bool(on)

    def paintGL(self) -> None:
        t0 = time.perf_counter()
        # (the solver starts no step while the renderer has the cores; a frame composed in
        # passes is shown by drawing only what they did not: modelview.ModelView.composer)
        with self._paint_hold(), self.scene.model.composer.showing():
            super().paintGL()
        self.paint_seconds = time.perf_counter() - t0
        if self.scene.built:  # (the proxy's size follows what its paints cost)
            self.scene.model.proxy_painted(self.paint_seconds)
        self.paints += 1
        if self.paints == 1:
            self.firstPainted.emit()

    def resizeEvent(self, ev) -> None:
        super().resizeEvent(ev)
        if self.isVisible():
            self.camera_control.home_when_sized()
        if self._info.isVisible():
            self._info.move(12, self.height() - self._info.height() - 12)

    def showEvent(self, ev) -> None:
        super().showEvent(ev)
        self.camera_control.home_when_sized()

    # -- gestures ----------------------------------------------------------------------------
    @property
    def dragging(self) -> bool:
        """A node drag, a gizmo drag or a grab, rotate or scale gesture runs."""
        return self.node_drag.active or self.transform_tool.running

    def start_transform(self, mode: str) -> bool:
        """Start a grab, rotate or scale of the selection at the mouse (False: nothing
        selected, the lattice hidden, or a drag runs)."""
        if self.node_drag.active:
            return False
        mouse = self._mouse
        inside = mouse is not None and self.rect().contains(mouse.toPoint())
        return self.transform_tool.start(mode, mouse if inside else None)

    def _transform_started(self, verb: str, new: bool) -> None:
        if new:  # the rest of the press is the gesture's, and the keys
            self._press = IgnorePress()
            self.setFocus(Qt.FocusReason.OtherFocusReason)
            self.gizmo.hide()
        self.transformStarted.emit(verb)

    def cancel_drag(self) -> None:
        """Esc during a drag: the selection goes back."""
        if not self.node_drag.active:
            return
        self._press = IgnorePress()
        self.node_drag.cancel()

    def _gizmo_press(self, pos: QPointF) -> bool:
        """A press on a gizmo arrow starts a drag of the selection along its axis."""
        axis = self.gizmo.axis_at(self.camera_control.projection(), pos.x(), pos.y())
        if axis is None:
            return False
        self._press = IgnorePress()
        self.node_drag.begin(pos, self.gizmo.centre.copy(), axis=axis)
        return True

    # -- Qt events ---------------------------------------------------------------------------
    def event(self, ev) -> bool:
        # during a gesture or drag every key is the view's: not "1" for the front view
        if ev.type() == QEvent.Type.ShortcutOverride and self.dragging:
            ev.accept()
            return True
        return super().event(ev)

    def wheelEvent(self, ev) -> None:
        self.model_frames.lower()  # the zoom's renders are a proxy's
        super().wheelEvent(ev)

    def mousePressEvent(self, ev) -> None:
        pos = ev.position()
        self._mouse = QPointF(pos)
        self.model_frames.touched()
        shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
        self.setFocus(Qt.FocusReason.MouseFocusReason)
        if self.transform_tool.running:  # a click confirms or cancels the gesture
            self.transform_tool.press(ev.button(), pos)
            self._press = IgnorePress()
            return
        if self.node_drag.active:  # another button during a drag: ignore it
            return
        if ev.button() == Qt.MouseButton.LeftButton:
            ctrl = bool(ev.modifiers() & Qt.KeyboardModifier.ControlModifier)
            placing = (self.handle_tool.active or ctrl) and not shift
            row = self.camera_control.node_at(pos, prefer_visible=True, placing=placing)
            if (row < 0 or row in self.selection) and not shift and self._gizmo_press(pos):
                return
            handle = None if shift else self.handle_tool.press(pos)
            if handle is not None:
                self._press = handle
                self.model_frames.hold_proxy()
                return
            if row >= 0:
                if shift:
                    self.selectRequested.emit([row], "toggle")
                    self._press = IgnorePress()
                    return
                self.model_frames.hold_proxy()  # a drag may follow: the press draws a proxy
                if row not in self.selection:
                    self.selectRequested.emit([row], "replace")
                self._press = NodePress(row, pos)
                return
            if placing:
                press = self.handle_tool.model_press(pos)
                if press is not None:
                    self._press = press
                    self.model_frames.hold_proxy()
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
        if isinstance(self._press, CameraPress):
            self.model_frames.lower()  # the camera's renders are a proxy's
        super().mousePressEvent(ev)

    def mouseMoveEvent(self, ev) -> None:
        pos = ev.position()
        self._mouse = QPointF(pos)
        self.model_frames.touched()
        press = self._press
        if self.transform_tool.running:
            self.transform_tool.mouse(pos)
            return
        if self.node_drag.active and isinstance(press, IgnorePress):  # a gizmo arrow
            self.node_drag.move(pos)
            return
        if press is None:
            self._hover(pos)
            super().mouseMoveEvent(ev)
        elif isinstance(press, NodePress):
            if not self.node_drag.active:
                if (pos - press.pos).manhattanLength() < DRAG_THRESHOLD:
                    return
                self.node_drag.begin(press.pos, self.nodes[press.row].copy())
            self.node_drag.move(pos)
        elif isinstance(press, (HandlePress, ModelPress)):
            self.handle_tool.move(press, pos)
        elif isinstance(press, BoxPress):
            self._band.setGeometry(QRect(press.pos.toPoint(), pos.toPoint()).normalized())
        elif not isinstance(press, IgnorePress):
            super().mouseMoveEvent(ev)

    def mouseReleaseEvent(self, ev) -> None:
        dragged = self.node_drag.active
        self._release(ev)
        # a press that drew the proxy and dragged nothing: draw what the window draws when
        # nothing is pressed (a drag's end brings its own frames)
        if self.model_frames.release() and not dragged and not self.dragging:
            self.set_frame(self.nodes, self.model_frames.moving())
            self.update()

    def _release(self, ev) -> None:
        pos = ev.position()
        press, self._press = self._press, None
        if self.node_drag.active and isinstance(press, IgnorePress):  # a gizmo arrow
            self.node_drag.end(pos)
            return
        if press is None or isinstance(press, IgnorePress):
            if press is None:
                super().mouseReleaseEvent(ev)
            self._hover(pos)
            return
        moved = (pos - press.pos).manhattanLength() >= DRAG_THRESHOLD
        if isinstance(press, NodePress):
            if self.node_drag.active:
                self.node_drag.end(pos)
            elif len(self.selection) > 1:
                self.selectRequested.emit([press.row], "replace")
        elif isinstance(press, (HandlePress, ModelPress)):
            self.handle_tool.release(press, pos)
        elif isinstance(press, BoxPress):
            self._band.hide()
            rect = QRect(press.pos.toPoint(), pos.toPoint()).normalized()
            rows = self.camera_control.nodes_in_rect(rect)
            if self.visible_only:
                rows = self.camera_control.visible_rows(rows)
            self.selectRequested.emit(rows, "add" if press.add else "replace")
        elif isinstance(press, CameraPress):
            super().mouseReleaseEvent(ev)
            if not moved and ev.button() == Qt.MouseButton.LeftButton:
                self.selectRequested.emit([], "replace")
        elif isinstance(press, ContextPress):
            super().mouseReleaseEvent(ev)
            at = self.mapToGlobal(pos.toPoint())
            if not moved and not self.handle_tool.context(pos, at):
                self.contextMenuRequested.emit(
                    self.camera_control.node_at(pos, prefer_visible=True), at
                )
        self._hover(pos)

    def _hover(self, pos: QPointF) -> None:
        self.setCursor(self.handle_tool.cursor(pos))

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
        if self.transform_tool.running and self.transform_tool.key(ev):
            return
        if self.node_drag.active and not ev.isAutoRepeat():
            axis = {Qt.Key.Key_X: "x", Qt.Key.Key_Y: "y", Qt.Key.Key_Z: "z"}.get(key)
            if axis is not None:
                shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
                self.node_drag.set_lock(axis, shift)
                return
        if key == Qt.Key.Key_Escape:
            if self.node_drag.active:
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
