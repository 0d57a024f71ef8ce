"""The 3D view: the deformed model, the lattice, node picking, dragging and box selection.

Mouse (left button)
-------------------
- on a node: select it (Shift: add or remove it); drag a selected node to move the whole
  selection in the view plane under the cursor. While dragging, X / Y / Z lock the move to
  that world axis, Shift+X / Y / Z to the plane across it (press again to unlock), and Esc
  cancels the drag back to where it started.
- on empty space: rotate the camera (the usual pyvista trackball); a click without moving
  clears the selection. Shift+drag on empty space (or any drag in box-select mode) draws a
  rubber band that selects the nodes inside it (Shift adds to the selection).
- middle button pans, the wheel zooms, right-drag zooms; a right click opens the context
  menu of the node under the cursor (or of the selection).

Picking is done here, not with VTK pickers: node positions are projected to the screen with
the renderer's camera matrix and the nearest within :data:`PICK_RADIUS` pixels wins. The
same projection turns a mouse position back into a world point at the grabbed node's depth.

Only the GUI thread calls into this module. Frames update the points of existing actors in
place (``poly.points[:] = ...``); actors are added only when a document or lattice changes.
"""

from __future__ import annotations

import time

import numpy as np
import pyvista as pv
from PySide6.QtCore import QPoint, QPointF, QRect, QSize, Qt, Signal
from PySide6.QtWidgets import QLabel, QRubberBand
from pyvistaqt import QtInteractor

from app import style

#: A click within this many pixels of a node's centre picks it.
PICK_RADIUS = 12.0
#: The mouse must travel this many pixels before a press becomes a drag.
DRAG_THRESHOLD = 3.0
NODE_SIZE = 15.0
SELECTED_SIZE = 22.0

AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]),
        "z": np.array([0.0, 0.0, 1.0])}


class Shading:
    """Vertex normals and enclosed volume of a deforming mesh with a fixed face list.

    Both come from one pass over the faces (the face normal ``(b - a) x (c - a)`` also gives
    the signed tetrahedron volume ``a . n / 6``), and the normals are gathered to the
    vertices by a sparse incidence matrix built once: a frame costs a few milliseconds even
    for a few hundred thousand triangles.
    """

    def __init__(self, faces: np.ndarray, n_vertices: int, center: np.ndarray) -> None:
        import scipy.sparse as sp  # noqa: PLC0415

        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        f = len(self.faces)
        self.center = np.asarray(center, dtype=np.float64)
        self._gather = sp.csr_matrix(
            (np.ones(3 * f), (self.faces.ravel(), np.repeat(np.arange(f), 3))),
            shape=(n_vertices, f))

    def __call__(self, points: np.ndarray, normals: bool = True):
        """(normals (m, 3) or None, signed volume) of the mesh at ``points``."""
        p = points - self.center
        a, b, c = p[self.faces[:, 0]], p[self.faces[:, 1]], p[self.faces[:, 2]]
        u, v = b - a, c - a
        n = np.empty_like(u)
        n[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
        n[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
        n[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
        volume = float(np.einsum("ij,ij->", a, n)) / 6.0
        if not normals:
            return None, volume
        vn = self._gather @ n
        norm = np.sqrt(np.einsum("ij,ij->i", vn, vn))[:, None]
        norm[norm == 0] = 1.0
        return vn / norm, volume


def _faces_vtk(faces: np.ndarray) -> np.ndarray:
    return np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()


def _lines_vtk(edges: np.ndarray) -> np.ndarray:
    return np.hstack([np.full((len(edges), 1), 2, dtype=np.int64), edges]).ravel()


def _rgb(color: str) -> np.ndarray:
    return np.array(style.hex_to_rgb(color), dtype=np.uint8)


class _Drag:
    """An active node drag: where it started and what constrains it."""

    def __init__(self, press: QPointF, anchor: np.ndarray, depth: float) -> None:
        self.press = press
        self.anchor = anchor  # world position of the grabbed node at the start
        self.depth = depth  # its normalised device depth
        self.pos = press
        self.axis: str | None = None
        self.plane = False  # True: move in the plane across ``axis``
        self.delta = np.zeros(3)


class Viewport(QtInteractor):
    """The pyvistaqt view with Isochor's actors and node interaction.

    Signals
    -------
    selectionChanged() : the selected node rows changed
    dragStarted() : a node drag began (the selection is about to move)
    dragMoved(object) : (3,) world displacement of the selection from the drag start
    dragFinished() : the button was released after a drag
    dragCanceled() : Esc during a drag: the selection goes back
    lockChanged(str) : the axis lock during a drag ("" when free)
    contextMenuRequested(int, QPoint) : a right click on node row (-1: none), global pos
    fileDropped(str) : a model or scenario file was dropped on the view
    """

    selectionChanged = Signal()
    dragStarted = Signal()
    dragMoved = Signal(object)
    dragFinished = Signal()
    dragCanceled = Signal()
    lockChanged = Signal(str)
    contextMenuRequested = Signal(int, QPoint)
    fileDropped = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent, auto_update=False, multi_samples=0)
        self.set_background(style.BACKGROUND_BOTTOM, top=style.BACKGROUND_TOP)
        self.setContextMenuPolicy(Qt.ContextMenuPolicy.PreventContextMenu)
        self.setMinimumSize(QSize(320, 240))
        self.box_mode = False
        self.selection = np.zeros(0, dtype=int)
        self.nodes = np.zeros((0, 3))
        self.show_lattice = True
        self.show_diagonals = True
        self.smooth = True
        self._faces: np.ndarray | None = None
        self._size = 1.0
        self._up = np.array([0.0, 0.0, 1.0])
        self._press: dict | None = None
        self._needs_home = True
        self.volume = 0.0  #: signed volume of the model as drawn
        self.paint_seconds = 0.0  #: how long the last repaint took
        self.paints = 0
        self._drag: _Drag | None = None
        self._actors: dict[str, object] = {}
        self._band = QRubberBand(QRubberBand.Shape.Rectangle, self)
        self._legend = QLabel(self, objectName="overlay")
        self._legend.setTextFormat(Qt.TextFormat.RichText)
        self._legend.setText(self._legend_html())
        self._legend.move(12, 12)
        self._legend.adjustSize()
        self._legend.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self._info = QLabel(self, objectName="hint")
        self._info.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self._info.hide()

    # -- overlays ----------------------------------------------------------------------------
    @staticmethod
    def _legend_html() -> str:
        def dot(color, label, big=False):
            size = "15px" if big else "13px"
            return (f'<span style="color:{color}; font-size:{size}">&#9679;</span>'
                    f'&nbsp;{label}')

        rows = [dot(style.FREE, "free"), dot(style.PINNED, "pinned"),
                dot(style.MOVED, "moved (fixed)"), dot(style.SELECTED, "selected", True)]
        return "&nbsp;&nbsp;&nbsp;".join(rows)

    def show_info(self, text: str) -> None:
        """A one-line note at the bottom left of the view (empty hides it)."""
        if not text:
            self._info.hide()
            return
        self._info.setText(text)
        self._info.adjustSize()
        self._info.move(12, self.height() - self._info.height() - 12)
        self._info.show()

    def paintGL(self) -> None:  # noqa: N802
        t0 = time.perf_counter()
        super().paintGL()
        self.paint_seconds = time.perf_counter() - t0
        self.paints += 1

    def resizeEvent(self, ev) -> None:  # noqa: N802
        super().resizeEvent(ev)
        if self._needs_home and self.isVisible():
            self._needs_home = False
            self.home_view()
        if self._info.isVisible():
            self._info.move(12, self.height() - self._info.height() - 12)

    # -- scene -------------------------------------------------------------------------------
    def set_scene(self, surface, nodes: np.ndarray, pinned, moved, *, up: str = "z",
                  reset_camera: bool = True) -> None:
        """Replace every actor for a new model or lattice (not called per frame).

        ``reset_camera`` False keeps the view (a new lattice around the same model)."""
        for actor in self._actors.values():
            self.remove_actor(actor, render=False)
        self._actors.clear()
        full = surface.full
        self._faces = np.asarray(full.faces)
        self._size = float(surface.size)
        self._up = AXES[up]
        self.nodes = np.array(nodes, dtype=np.float64)
        self.selection = np.zeros(0, dtype=int)

        ghost = pv.PolyData(np.array(full.vertices), _faces_vtk(self._faces))
        self._ghost = ghost
        self._actors["ghost"] = self.add_mesh(
            ghost, color=style.GHOST, opacity=0.28, show_scalar_bar=False, render=False,
            pickable=False, name="ghost")
        self._actors["ghost"].SetVisibility(False)

        points = surface.deform(self.nodes)
        self._shading = Shading(self._faces, len(points), surface.center)
        normals, self.volume = self._shading(points)
        model = pv.PolyData(points, _faces_vtk(self._faces))
        model.point_data["Normals"] = normals
        model.point_data.active_normals_name = "Normals"
        self._model = model
        self._actors["model"] = self.add_mesh(
            model, color=style.MODEL, smooth_shading=False, specular=0.25, specular_power=20,
            diffuse=0.85, ambient=0.12, show_scalar_bar=False, render=False, name="model")

        edges = np.asarray(surface.springs.edges)
        lattice = surface.lattice
        ijk = np.array([lattice.ijk(r) for r in range(lattice.n_nodes)])
        axis_edge = np.abs(ijk[edges[:, 0]] - ijk[edges[:, 1]]).sum(axis=1) == 1
        self._springs_axis = pv.PolyData(self.nodes.copy(), lines=_lines_vtk(edges[axis_edge]))
        self._springs_diag = pv.PolyData(self.nodes.copy(), lines=_lines_vtk(edges[~axis_edge]))
        self._actors["diag"] = self.add_mesh(
            self._springs_diag, color=style.SPRING_DIAGONAL, line_width=1.0, lighting=False,
            render=False, pickable=False, name="diag")
        self._actors["axis"] = self.add_mesh(
            self._springs_axis, color=style.SPRING_AXIS, line_width=2.0, lighting=False,
            render=False, pickable=False, name="axis")

        self._nodes_poly = pv.PolyData(self.nodes.copy())
        self._nodes_poly.point_data["rgb"] = np.zeros((len(self.nodes), 3), dtype=np.uint8)
        self._actors["nodes"] = self.add_mesh(
            self._nodes_poly, scalars="rgb", rgb=True, render_points_as_spheres=True,
            point_size=NODE_SIZE, show_scalar_bar=False, render=False, pickable=False,
            name="nodes")
        self._sel_poly = pv.PolyData(np.zeros((1, 3)))
        self._actors["selected"] = self.add_mesh(
            self._sel_poly, color=style.SELECTED, render_points_as_spheres=True,
            point_size=SELECTED_SIZE, render=False, pickable=False, name="selected")
        self._actors["selected"].SetVisibility(False)
        self._guide = pv.Line((0, 0, 0), (1, 0, 0))
        self._actors["guide"] = self.add_mesh(
            self._guide, color=style.GUIDE, line_width=2.5, lighting=False, render=False,
            pickable=False, name="guide")
        self._actors["guide"].SetVisibility(False)

        self.set_flags(pinned, moved)
        self._apply_visibility()
        if reset_camera:
            self.home_view()
            # Before the first show the view's aspect ratio is not known: frame again then.
            self._needs_home = not self.isVisible()

    def set_frame(self, nodes: np.ndarray, points: np.ndarray | None) -> None:
        """Move the lattice (and the model, if ``points`` is given) to new positions."""
        self.nodes = np.array(nodes, dtype=np.float64)
        self._nodes_poly.points[:] = self.nodes
        self._springs_axis.points[:] = self.nodes
        self._springs_diag.points[:] = self.nodes
        if points is not None:
            normals, self.volume = self._shading(points, self.smooth)
            self._model.points[:] = points
            if self.smooth:
                self._model.point_data["Normals"][:] = normals
        self._update_selection_actor()
        if self._drag is not None and self._drag.axis is not None:
            self._update_guide()

    def set_flags(self, pinned: np.ndarray, moved: np.ndarray) -> None:
        rgb = np.empty((len(pinned), 3), dtype=np.uint8)
        rgb[:] = _rgb(style.FREE)
        rgb[np.asarray(pinned, bool)] = _rgb(style.PINNED)
        rgb[np.asarray(moved, bool)] = _rgb(style.MOVED)
        self._nodes_poly.point_data["rgb"][:] = rgb

    def set_ghost(self, on: bool) -> None:
        self._actors["ghost"].SetVisibility(bool(on))

    def set_smooth(self, on: bool) -> None:
        self.smooth = bool(on)
        model = self._model
        if on:
            model.point_data["Normals"] = self._shading(np.asarray(model.points))[0]
            model.point_data.active_normals_name = "Normals"
        else:
            model.GetPointData().SetNormals(None)
        model.Modified()

    def set_lattice_visible(self, on: bool, diagonals: bool | None = None) -> None:
        self.show_lattice = bool(on)
        if diagonals is not None:
            self.show_diagonals = bool(diagonals)
        self._apply_visibility()

    def _apply_visibility(self) -> None:
        self._actors["nodes"].SetVisibility(self.show_lattice)
        self._actors["axis"].SetVisibility(self.show_lattice)
        self._actors["diag"].SetVisibility(self.show_lattice and self.show_diagonals)
        self._update_selection_actor()

    # -- selection ---------------------------------------------------------------------------
    def set_selection(self, rows, *, emit: bool = True) -> None:
        rows = np.unique(np.asarray(list(rows), dtype=int))
        if np.array_equal(rows, self.selection):
            return
        self.selection = rows
        self._update_selection_actor()
        self.update()
        if emit:
            self.selectionChanged.emit()

    def _update_selection_actor(self) -> None:
        actor = self._actors.get("selected")
        if actor is None:
            return
        rows = self.selection
        if len(rows) == 0 or not self.show_lattice:
            actor.SetVisibility(False)
            return
        pts = self.nodes[rows]
        if self._sel_poly.n_points == len(pts):
            self._sel_poly.points[:] = pts
        else:
            self._sel_poly.copy_from(pv.PolyData(pts))
        actor.SetVisibility(True)

    # -- camera ------------------------------------------------------------------------------
    def _view(self, direction, up) -> None:
        focal = self._scene_center()
        self.camera_position = [tuple(focal + np.asarray(direction, float)), tuple(focal),
                                tuple(up)]
        self.frame()

    def _scene_center(self) -> np.ndarray:
        pts = self.nodes if len(self.nodes) else np.zeros((1, 3))
        return (pts.min(axis=0) + pts.max(axis=0)) / 2

    def _basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(forward-ish, side, up) world directions for the model's up axis."""
        up = self._up
        if up[2] == 1:
            return np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0]), up
        return np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), up  # y up: look down -z

    def home_view(self) -> None:
        front, side, up = self._basis()
        self._view(1.0 * front + 0.6 * side + 0.45 * up, up)

    def standard_view(self, name: str) -> None:
        front, side, up = self._basis()
        views = {"front": (front, up), "back": (-front, up), "right": (side, up),
                 "left": (-side, up), "top": (up, -front), "bottom": (-up, front),
                 "home": None}
        if name == "home":
            self.home_view()
            return
        direction, vup = views[name]
        self._view(direction, vup)

    def frame(self) -> None:
        """Fit the model and the lattice in the view, keeping the direction."""
        pts = np.vstack([self.nodes, np.asarray(self._model.bounds).reshape(3, 2).T]) \
            if len(self.nodes) else None
        if pts is None:
            self.reset_camera(render=False)
        else:
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            self.reset_camera(render=False, bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
            self._fit(pts)
        self.update()

    def _fit(self, pts: np.ndarray, fill: float = 0.86) -> None:
        """Zoom so that ``pts`` fill ``fill`` of the view (a bounding sphere wastes room)."""
        w, h = self.width(), self.height()
        if w < 10 or h < 10:
            return
        for _ in range(3):
            xy, _, visible = self.project(pts)
            if not visible.all():
                return
            dx = np.abs(xy[:, 0] - w / 2).max() / (w / 2)
            dy = np.abs(xy[:, 1] - h / 2).max() / (h / 2)
            extent = max(dx, dy)
            if extent <= 0:
                return
            factor = fill / extent
            if abs(factor - 1) < 0.02:
                return
            self.camera.zoom(factor)

    # -- projection --------------------------------------------------------------------------
    def _matrix(self) -> np.ndarray:
        ren = self.renderer
        aspect = ren.GetTiledAspectRatio()
        m = ren.camera.GetCompositeProjectionTransformMatrix(aspect, -1, 1)
        return pv.array_from_vtkmatrix(m)

    def _display_box(self) -> tuple[float, float, float, float, float]:
        """(x0, y0, width, height) of the renderer in device pixels, and the pixel ratio."""
        w, h = self.ren_win.GetSize()
        vx0, vy0, vx1, vy1 = self.renderer.GetViewport()
        return vx0 * w, vy0 * h, (vx1 - vx0) * w, (vy1 - vy0) * h, self.devicePixelRatioF()

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Screen positions of world ``points``.

        Returns (xy (p, 2) widget pixels with y down, depth (p,) normalised device z,
        visible (p,) bool: in front of the camera)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        clip = np.c_[pts, np.ones(len(pts))] @ self._matrix().T
        w = clip[:, 3]
        visible = w > 1e-12
        safe = np.where(visible, w, 1.0)
        ndc = clip[:, :3] / safe[:, None]
        x0, y0, vw, vh, dpr = self._display_box()
        dx = x0 + (ndc[:, 0] + 1) / 2 * vw
        dy = y0 + (ndc[:, 1] + 1) / 2 * vh
        xy = np.c_[dx / dpr, self.height() - 1 - dy / dpr]
        return xy, ndc[:, 2], visible

    def unproject(self, x: float, y: float, depth: float) -> np.ndarray:
        """World point under widget pixel (x, y) at normalised device depth ``depth``."""
        x0, y0, vw, vh, dpr = self._display_box()
        dx, dy = x * dpr, (self.height() - 1 - y) * dpr
        ndc = np.array([2 * (dx - x0) / vw - 1, 2 * (dy - y0) / vh - 1, depth, 1.0])
        p = np.linalg.solve(self._matrix(), ndc)
        return p[:3] / p[3]

    def ray(self, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
        near, far = self.unproject(x, y, -1.0), self.unproject(x, y, 1.0)
        d = far - near
        return near, d / np.linalg.norm(d)

    def node_at(self, pos: QPointF | QPoint, radius: float = PICK_RADIUS) -> int:
        """Row of the node drawn under ``pos`` (the nearest within ``radius``), or -1."""
        if not self.show_lattice or len(self.nodes) == 0:
            return -1
        xy, depth, visible = self.project(self.nodes)
        d = np.hypot(xy[:, 0] - pos.x(), xy[:, 1] - pos.y())
        d[~visible] = np.inf
        near = np.flatnonzero(d <= radius)
        if len(near) == 0:
            return -1
        best = d[near].min()
        # Among nodes about equally near the cursor, the one in front wins.
        close = near[d[near] <= best + 2.0]
        return int(close[np.argmin(depth[close])])

    def nodes_in_rect(self, rect: QRect) -> np.ndarray:
        xy, _, visible = self.project(self.nodes)
        inside = ((xy[:, 0] >= rect.left()) & (xy[:, 0] <= rect.right())
                  & (xy[:, 1] >= rect.top()) & (xy[:, 1] <= rect.bottom()) & visible)
        return np.flatnonzero(inside)

    # -- dragging ----------------------------------------------------------------------------
    @property
    def dragging(self) -> bool:
        return self._drag is not None

    def _drag_delta(self, pos: QPointF) -> np.ndarray:
        drag = self._drag
        if drag.axis is None:
            a = self.unproject(drag.press.x(), drag.press.y(), drag.depth)
            b = self.unproject(pos.x(), pos.y(), drag.depth)
            return b - a
        axis = AXES[drag.axis]
        if drag.plane:  # the plane through the anchor across the axis
            def hit(p):
                o, d = self.ray(p.x(), p.y())
                den = d @ axis
                if abs(den) < 1e-6:
                    return None
                return o + ((drag.anchor - o) @ axis / den) * d

            a, b = hit(drag.press), hit(pos)
            if a is None or b is None:
                return drag.delta
            return b - a

        def along(p):  # parameter of the axis line point closest to the mouse ray
            o, d = self.ray(p.x(), p.y())
            w0 = drag.anchor - o
            b_ = axis @ d
            den = 1 - b_ * b_
            if den < 1e-6:
                return None
            return (b_ * (d @ w0) - (axis @ w0)) / den

        ta, tb = along(drag.press), along(pos)
        if ta is None or tb is None:
            return drag.delta
        return (tb - ta) * axis

    def _update_drag(self, pos: QPointF) -> None:
        drag = self._drag
        drag.pos = pos
        drag.delta = self._drag_delta(pos)
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
        text = "" if axis is None else (f"plane across {axis.upper()}" if plane
                                          else f"{axis.upper()} axis")
        self.lockChanged.emit(text)

    def _update_guide(self) -> None:
        drag = self._drag
        actor = self._actors.get("guide")
        if actor is None:
            return
        if drag is None or drag.axis is None or drag.plane:
            actor.SetVisibility(False)
            return
        c = drag.anchor + drag.delta
        a = AXES[drag.axis] * 3 * self._size
        self._guide.points[:] = np.array([c - a, c + a])
        actor.SetVisibility(True)

    def cancel_drag(self) -> None:
        if self._drag is None:
            return
        self._drag = None
        self._press = {"kind": "ignore"}
        self._update_guide()
        self.dragCanceled.emit()

    def _end_drag(self) -> None:
        self._drag = None
        self._update_guide()
        self.dragFinished.emit()

    # -- Qt events ---------------------------------------------------------------------------
    def mousePressEvent(self, ev) -> None:  # noqa: N802
        pos = ev.position()
        shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
        self.setFocus(Qt.FocusReason.MouseFocusReason)
        if self._drag is not None:  # another button during a drag: ignore it
            return
        if ev.button() == Qt.MouseButton.LeftButton:
            row = self.node_at(pos)
            if row >= 0:
                if shift:
                    sel = set(self.selection.tolist()) ^ {row}
                    self.set_selection(sel)
                    self._press = {"kind": "ignore"}
                    return
                if row not in self.selection:
                    self.set_selection([row])
                self._press = {"kind": "node", "row": row, "pos": pos}
                return
            if shift or self.box_mode:
                self._press = {"kind": "box", "pos": pos, "add": shift}
                self._band.setGeometry(QRect(pos.toPoint(), QSize()))
                self._band.show()
                return
            self._press = {"kind": "camera", "pos": pos}
        elif ev.button() == Qt.MouseButton.RightButton:
            self._press = {"kind": "context", "pos": pos}
        else:
            self._press = {"kind": "camera", "pos": pos}
        super().mousePressEvent(ev)

    def mouseMoveEvent(self, ev) -> None:  # noqa: N802
        pos = ev.position()
        press = self._press
        if press is None:
            self._hover(pos)
            super().mouseMoveEvent(ev)
            return
        kind = press["kind"]
        if kind == "node":
            if self._drag is None:
                if (pos - press["pos"]).manhattanLength() < DRAG_THRESHOLD:
                    return
                row = press["row"]
                xy, depth, _ = self.project(self.nodes[row])
                self._drag = _Drag(press["pos"], self.nodes[row].copy(), float(depth[0]))
                self.dragStarted.emit()
            self._update_drag(pos)
        elif kind == "box":
            self._band.setGeometry(QRect(press["pos"].toPoint(), pos.toPoint()).normalized())
        elif kind == "ignore":
            pass
        else:
            super().mouseMoveEvent(ev)

    def mouseReleaseEvent(self, ev) -> None:  # noqa: N802
        pos = ev.position()
        press, self._press = self._press, None
        if press is None:
            super().mouseReleaseEvent(ev)
            return
        kind = press["kind"]
        moved = (pos - press["pos"]).manhattanLength() >= DRAG_THRESHOLD if "pos" in press \
            else True
        if kind == "node":
            if self._drag is not None:
                self._update_drag(pos)
                self._end_drag()
            elif len(self.selection) > 1:
                self.set_selection([press["row"]])
        elif kind == "box":
            self._band.hide()
            rect = QRect(press["pos"].toPoint(), pos.toPoint()).normalized()
            rows = self.nodes_in_rect(rect)
            if press["add"]:
                rows = np.union1d(self.selection, rows)
            self.set_selection(rows)
        elif kind == "camera":
            super().mouseReleaseEvent(ev)
            if not moved and ev.button() == Qt.MouseButton.LeftButton:
                self.set_selection([])
        elif kind == "context":
            super().mouseReleaseEvent(ev)
            if not moved:
                self.contextMenuRequested.emit(self.node_at(pos),
                                               self.mapToGlobal(pos.toPoint()))
        self._hover(pos)

    def _hover(self, pos: QPointF) -> None:
        over = self.node_at(pos) >= 0
        self.setCursor(Qt.CursorShape.OpenHandCursor if over else Qt.CursorShape.ArrowCursor)

    # -- files dropped on the view (pyvistaqt would add them as extra actors) ----------------
    @staticmethod
    def _dropped_file(ev) -> str | None:
        from app.document import MODEL_SUFFIXES, SCENARIO_SUFFIXES  # noqa: PLC0415

        urls = ev.mimeData().urls() if ev.mimeData() is not None else []
        for url in urls:
            path = url.toLocalFile()
            if path.lower().endswith(MODEL_SUFFIXES + SCENARIO_SUFFIXES):
                return path
        return None

    def dragEnterEvent(self, ev) -> None:  # noqa: N802
        if self._dropped_file(ev):
            ev.acceptProposedAction()
        else:
            ev.ignore()

    def dropEvent(self, ev) -> None:  # noqa: N802
        path = self._dropped_file(ev)
        if path:
            ev.acceptProposedAction()
            self.fileDropped.emit(path)

    def keyPressEvent(self, ev) -> None:  # noqa: N802
        key = ev.key()
        if self._drag is not None and not ev.isAutoRepeat():
            axis = {Qt.Key.Key_X: "x", Qt.Key.Key_Y: "y", Qt.Key.Key_Z: "z"}.get(key)
            if axis is not None:
                self.set_lock(axis, bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier))
                return
        if key == Qt.Key.Key_Escape:
            if self._drag is not None:
                self.cancel_drag()
            elif self._press is not None and self._press["kind"] == "box":
                self._band.hide()
                self._press = {"kind": "ignore"}
            else:
                self.set_selection([])
            return
        # Every other key goes to the window's actions, never to the VTK interactor style
        # (whose single-letter keys would switch to wireframe, stereo, or quit).
        ev.ignore()

    def keyReleaseEvent(self, ev) -> None:  # noqa: N802
        ev.ignore()
