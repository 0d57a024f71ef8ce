"""The view's camera: standard views around the model's up axis, framing that fills the
view, and the projection of world points to the widget (what picking uses). A mixin of
:class:`~isochor.app.view.viewport.Viewport` (a pyvista plotter with a scene).
"""

from __future__ import annotations

import numpy as np
import pyvista as pv
from PySide6.QtCore import QPoint, QPointF, QRect

from . import picking

AXES = {
    "x": np.array([1.0, 0.0, 0.0]),
    "y": np.array([0.0, 1.0, 0.0]),
    "z": np.array([0.0, 0.0, 1.0]),
}


class CameraMixin:
    """Needs ``self.scene``, ``self.nodes``, ``self._up`` (a unit axis) and the plotter's
    renderer and camera."""

    # -- projection --------------------------------------------------------------------------
    def projection(self) -> picking.Projection:
        """The current world-to-widget projection (camera and window size)."""
        ren = self.renderer
        # The render window's size follows the widget only when VTK renders or resizes;
        # take the widget's own size, as Qt lays it out now.
        dpr = self.devicePixelRatioF()
        w, h = self.width() * dpr, self.height() * dpr
        aspect = w / h if h > 0 else 1.0
        m = ren.camera.GetCompositeProjectionTransformMatrix(aspect, -1, 1)
        vx0, vy0, vx1, vy1 = ren.GetViewport()
        box = (vx0 * w, vy0 * h, (vx1 - vx0) * w, (vy1 - vy0) * h)
        return picking.Projection(pv.array_from_vtkmatrix(m), box, self.height(), dpr)

    def node_at(self, pos: QPointF | QPoint) -> int:
        """Row of the node drawn under ``pos`` (the nearest within the pick radius), or -1."""
        if not self.scene.show_lattice:
            return -1
        return picking.nearest(self.projection(), self.nodes, pos.x(), pos.y())

    def nodes_in_rect(self, rect: QRect) -> np.ndarray:
        return picking.in_rect(
            self.projection(), self.nodes, rect.left(), rect.top(), rect.right(), rect.bottom()
        )

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
        self.camera_position = [
            tuple(focal + np.asarray(direction, float)),
            tuple(focal),
            tuple(up),
        ]
        self.frame()

    def _framed_points(self) -> np.ndarray:
        if not self.scene.built:
            return np.zeros((1, 3))
        return np.vstack([self.nodes, self.scene.bounds()])

    def frame(self) -> None:
        """Fit the model and the lattice in the view, keeping the direction."""
        if not self.scene.built:
            self.reset_camera(render=False)
            self.update()
            return
        pts = self._framed_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self.reset_camera(render=False, bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        self._fit(pts)
        self.update()

    def _fit(self, pts: np.ndarray, fill: float = 0.86) -> None:
        """Zoom so that ``pts`` fill ``fill`` of the view (a bounding sphere wastes room)."""
        w, h = self.width(), self.height()
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
            self.camera.zoom(factor)
