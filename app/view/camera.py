"""The view's camera: standard views around the model's up axis, framing that fills the
view (all of it, or the selection), the orthographic projection, and the projection of
world points to the widget with what it picks there (a node, nodes in a box, the model,
the nodes the model does not hide). A part of :class:`~isochor.app.view.viewport.Viewport`.
GUI thread only.
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv
from PySide6.QtCore import QPoint, QPointF, QRect

from ..editor.transform import unit
from . import picking
from .scene import Scene

AXES = {
    "x": np.array([1.0, 0.0, 0.0]),
    "y": np.array([0.0, 1.0, 0.0]),
    "z": np.array([0.0, 0.0, 1.0]),
}


class CameraControl:
    """Where the view looks, and what is under a point of the widget.

    Parameters
    ----------
    plotter : the pyvista Qt plotter (the widget: its renderer, camera and size)
    scene : the actors it frames and picks (the nodes and the model as drawn)

    Attributes
    ----------
    up : (3,) the model's up axis: the standard views turn around it
    home_pending : frame the home view again once the widget has its final size
    """

    def __init__(self, plotter, scene: Scene) -> None:
        self.plotter = plotter
        self.scene = scene
        self.up = AXES["z"]
        self.home_pending = False

    # -- projection --------------------------------------------------------------------------
    def projection(self) -> picking.Projection:
        """The current world-to-widget projection (camera and window size)."""
        p = self.plotter
        ren = p.renderer
        # The render window's size follows the widget only when VTK renders or resizes;
        # take the widget's own size, as Qt lays it out now.
        dpr = p.devicePixelRatioF()
        w, h = p.width() * dpr, p.height() * dpr
        aspect = w / h if h > 0 else 1.0
        m = ren.camera.GetCompositeProjectionTransformMatrix(aspect, -1, 1)
        vx0, vy0, vx1, vy1 = ren.GetViewport()
        box = (vx0 * w, vy0 * h, (vx1 - vx0) * w, (vy1 - vy0) * h)
        return picking.Projection(pv.array_from_vtkmatrix(m), box, p.height(), dpr)

    def view_vector(self, at: np.ndarray) -> np.ndarray:
        """(3,) unit vector from ``at`` towards the viewer."""
        cam = self.plotter.renderer.GetActiveCamera()
        if cam.GetParallelProjection():
            v = -np.array(cam.GetDirectionOfProjection())
        else:
            v = np.array(cam.GetPosition()) - at
        n = np.linalg.norm(v)
        return v / n if n > 0 else unit("z")

    # -- what is under the cursor ------------------------------------------------------------
    def node_at(self, pos: QPointF | QPoint, *, prefer_visible: bool = False, placing=False) -> int:
        """Row of the node drawn under ``pos`` (the nearest within the pick radius), or -1.

        ``prefer_visible``: a node the model does not hide wins over hidden ones near the
        cursor; ``placing`` (a click that places a handle): a node the model hides is not
        picked at all, the click is on the surface in front of it."""
        if not self.scene.show_lattice:
            return -1
        proj = self.projection()
        hidden = None
        if (prefer_visible or placing) and self.scene.built:
            verts, faces = self.scene.model_points(), self.scene.model_faces()

            def hidden(points):
                return picking.occluded(proj, points, verts, faces)

        return picking.nearest(
            proj, self.scene.nodes, pos.x(), pos.y(), hidden=hidden, skip_hidden=placing
        )

    def nodes_in_rect(self, rect: QRect) -> np.ndarray:
        return picking.in_rect(
            self.projection(),
            self.scene.nodes,
            rect.left(),
            rect.top(),
            rect.right(),
            rect.bottom(),
        )

    def model_hit(self, pos: QPointF):
        """``(face, weights, point)`` of the model drawn under ``pos``, or None."""
        return picking.surface_hit(
            self.projection(), self.scene.model_points(), self.scene.model_faces(), *pos.toTuple()
        )

    def visible_rows(self, rows) -> np.ndarray:
        """The given node rows the model does not hide (the deformed model as drawn)."""
        rows = np.asarray(rows, dtype=int)
        if len(rows) == 0 or not self.scene.built:
            return rows
        verts, faces = self.scene.model_points(), self.scene.model_faces()
        hidden = picking.occluded(self.projection(), self.scene.nodes[rows], verts, faces)
        return rows[~hidden]

    # -- standard views ----------------------------------------------------------------------
    def _basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(forward-ish, side, up) world directions for the model's up axis."""
        up = self.up
        if up[2] == 1:
            return np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0]), up
        return np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), up  # y up: look down -z

    def set_up(self, up: np.ndarray) -> None:
        """The model's up axis ((3,) unit vector): the standard views turn around it."""
        self.up = up

    def home_view(self, again_when_sized: bool = False) -> None:
        """The view from the front, a little to the side and above; ``again_when_sized``:
        once more when the widget has its final size (:meth:`home_when_sized`)."""
        front, side, up = self._basis()
        self._view(1.0 * front + 0.6 * side + 0.45 * up, up)
        if again_when_sized:
            self.home_pending = True

    def home_when_sized(self) -> None:
        """Frame the home view again if it is pending and the widget has its size (until
        then its aspect ratio is not known)."""
        if self.home_pending and self.plotter.width() > 10:
            self.home_pending = False
            self.home_view()

    def standard_view(self, name: str) -> None:
        if name == "home":
            self.home_view()
            return
        front, side, up = self._basis()
        views = {
            "front": (front, up),
            "back": (-front, up),
            "right": (side, up),
            "left": (-side, up),
            "top": (up, -front),
            "bottom": (-up, front),
        }
        self._view(*views[name])

    def _view(self, direction, up) -> None:
        pts = self._framed_points()
        focal = (pts.min(axis=0) + pts.max(axis=0)) / 2
        self.plotter.camera_position = [
            tuple(focal + np.asarray(direction, float)),
            tuple(focal),
            tuple(up),
        ]
        self.frame()

    # -- framing -----------------------------------------------------------------------------
    def _framed_points(self) -> np.ndarray:
        if not self.scene.built:
            return np.zeros((1, 3))
        return np.vstack([self.scene.nodes, self.scene.bounds()])

    def frame(self) -> None:
        """Fit the model and the lattice in the view, keeping the direction. (The renderer's
        ``reset_camera``, not the plotter's: pyvista's renders at once whatever ``render``
        says, a whole extra render of the model, 0.1-0.2 s for the 346k armadillo in
        software OpenGL; the view's next paint draws it.)"""
        p = self.plotter
        if not self.scene.built:
            p.renderer.reset_camera(render=False)
            p.update()
            return
        pts = self._framed_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        p.renderer.reset_camera(render=False, bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        self._fit(pts)
        p.update()

    def frame_selection(self) -> None:
        """Fit the selected nodes in the view (the whole model when nothing is selected)."""
        scene, p = self.scene, self.plotter
        rows = scene.selection[scene.selection < len(scene.nodes)]
        if len(rows) == 0 or not scene.built:
            self.frame()
            return
        size = scene.size
        pts = scene.nodes[rows]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = max(0.12 * size - (hi - lo).max() / 2, 0.0) + 0.05 * size
        lo, hi = lo - pad, hi + pad
        corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T
        p.renderer.reset_camera(render=False, bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        self._fit(corners)
        p.renderer.ResetCameraClippingRange(*self._clip_bounds())
        p.update()

    def _fit(self, pts: np.ndarray, fill: float = 0.86) -> None:
        """Zoom so that ``pts`` fill ``fill`` of the view (a bounding sphere wastes room)."""
        w, h = self.plotter.width(), self.plotter.height()
        if w < 10 or h < 10:
            return
        for _ in range(4):
            xy, _, visible = self.projection().project(pts)
            if not visible.all():
                return
            extent = max(
                np.abs(xy[:, 0] - w / 2).max() / (w / 2), np.abs(xy[:, 1] - h / 2).max() / (h / 2)
            )
            if extent <= 0:
                return
            factor = fill / extent
            if abs(factor - 1) < 0.02:
                return
            self.plotter.camera.zoom(factor)

    def _clip_bounds(self) -> tuple:
        """The scene's bounds (the clipping range must hold all of it, not only what is
        framed)."""
        pts = self._framed_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])

    # -- projection kind ---------------------------------------------------------------------
    def set_orthographic(self, on: bool) -> None:
        """Parallel projection (on) or perspective, keeping what is in view about the same
        size."""
        cam = self.plotter.renderer.GetActiveCamera()
        if bool(cam.GetParallelProjection()) == bool(on):
            return
        distance = cam.GetDistance()
        if on:
            cam.SetParallelScale(distance * math.tan(math.radians(cam.GetViewAngle()) / 2))
        cam.SetParallelProjection(bool(on))
        self.plotter.renderer.ResetCameraClippingRange(*self._clip_bounds())
        self.plotter.update()

    @property
    def orthographic(self) -> bool:
        return bool(self.plotter.renderer.GetActiveCamera().GetParallelProjection())
