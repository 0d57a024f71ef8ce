"""What the view draws over the scene: the translate gizmo at the selection's centre, drawn on
a renderer layered above the scene (sharing its camera) so the model never hides it.
GUI thread only.

The gizmo's three arrows are red (x), green (y) and blue (z) (:data:`style.AXIS_COLOURS`);
dragging one moves the selection along its world axis. Its length is a fraction of the
model's size. Its actors are built once per view; moving it only moves their points.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkRenderer

from ..editor.transform import AXES, unit
from . import picking, style
from .glyphs import GAP, HALO, glyph_actor, halo_actor

#: the gizmo's arrow length over the model's size
GIZMO_FRACTION = 0.2
#: a press within this many pixels of an arrow's shaft (its outer part) grabs it
GIZMO_PICK = 9.0
#: the part of an arrow that picks: from this fraction of its length to its tip
PICK_FROM = 0.3


def rgb01(color: str) -> tuple[float, float, float]:
    return tuple(c / 255 for c in style.hex_to_rgb(color))


class Overlay:
    """A renderer on layer 1 of the view's render window, with the scene's camera."""

    def __init__(self, plotter) -> None:
        self.plotter = plotter
        self.renderer = vtkRenderer()
        self.renderer.SetLayer(1)
        self.renderer.InteractiveOff()
        window = plotter.render_window
        window.SetNumberOfLayers(max(2, window.GetNumberOfLayers()))
        window.AddRenderer(self.renderer)
        self.sync()

    def sync(self) -> None:
        """Share the scene's camera and viewport (the plotter may have replaced its camera)."""
        main = self.plotter.renderer
        if self.renderer.GetActiveCamera() is not main.GetActiveCamera():
            self.renderer.SetActiveCamera(main.GetActiveCamera())
        self.renderer.SetViewport(main.GetViewport())

    def add(self, actor) -> None:
        self.renderer.AddActor(actor)


class Gizmo:
    """Three arrows at a point; :meth:`axis_at` says which arrow a press is on."""

    def __init__(self, overlay: Overlay) -> None:
        self.overlay = overlay
        self.length = 1.0
        self.centre = np.zeros(3)
        self.visible = False
        self._template: dict[str, np.ndarray] = {}
        self._polys: dict[str, pv.PolyData] = {}
        self.actors: dict[str, vtkActor] = {}
        for axis in AXES:
            arrow = pv.Arrow(
                start=(0, 0, 0),
                direction=unit(axis),
                tip_length=0.25,
                tip_radius=0.085,
                shaft_radius=0.032,
                scale=1.0,
            )
            self._template[axis] = np.array(arrow.points)
            self._polys[axis] = arrow
            mapper = vtkPolyDataMapper()
            mapper.SetInputData(arrow)
            actor = vtkActor()
            actor.SetMapper(mapper)
            actor.PickableOff()
            prop = actor.GetProperty()
            prop.SetColor(*rgb01(style.AXIS_COLOURS[axis]))
            prop.SetAmbient(0.45)
            prop.SetDiffuse(0.7)
            actor.SetVisibility(False)
            overlay.add(actor)
            self.actors[axis] = actor

    def set_length(self, length: float) -> None:
        self.length = float(length)
        self._place()

    def show_at(self, centre) -> None:
        """Draw the arrows from ``centre``."""
        self.centre = np.array(centre, dtype=np.float64).reshape(3)
        self.visible = True
        self._place()
        for actor in self.actors.values():
            actor.SetVisibility(True)

    def hide(self) -> None:
        self.visible = False
        for actor in self.actors.values():
            actor.SetVisibility(False)

    def _place(self) -> None:
        self.overlay.sync()
        for axis, poly in self._polys.items():
            poly.points[:] = self._template[axis] * self.length + self.centre
            poly.Modified()

    def tip(self, axis: str) -> np.ndarray:
        """(3,) world position of an arrow's tip."""
        return self.centre + self.length * unit(axis)

    def axis_at(self, proj: picking.Projection, x: float, y: float) -> str | None:
        """The arrow drawn under widget pixel (x, y) (the nearest within the pick distance),
        or None."""
        if not self.visible:
            return None
        best, best_d = None, GIZMO_PICK
        for axis in AXES:
            a = self.centre + PICK_FROM * self.length * unit(axis)
            d = picking.segment_distance(proj, a, self.tip(axis), x, y)
            if d <= best_d:
                best, best_d = axis, d
        return best


#: a handle's target marker: its diameter over the model's size
HANDLE_FRACTION = 0.06
#: a press within this many pixels of a handle's target picks it
HANDLE_PICK = 12.0


class HandleMarkers:
    """The surface handles: a large orange sphere at each target, a small white dot where
    the handle's point is now and a thin line between them; the selected handle ringed in
    the selection's yellow, mirror images (symmetry) dimmed. Drawn over the scene."""

    def __init__(self, overlay: Overlay) -> None:
        self.overlay = overlay
        self.targets = np.zeros((0, 3))
        self.points = np.zeros((0, 3))
        self.count = 0  #: the user's handles (the first ``count`` targets; then mirrors)
        self.selected: int | None = None
        self.size = 1.0
        self._targets = pv.PolyData(np.zeros((1, 3)))
        self._targets.point_data["rgb"] = np.zeros((1, 3), np.uint8)
        self._points = pv.PolyData(np.zeros((1, 3)))
        self._lines = pv.PolyData(np.zeros((2, 3)), lines=np.array([2, 0, 1]))
        self._selected = pv.PolyData(np.zeros((1, 3)))
        sphere = pv.Sphere(radius=0.5, theta_resolution=20, phi_resolution=14)
        self.actors = {
            "targets": glyph_actor(self._targets, [sphere], 1.0),
            "points": glyph_actor(self._points, [sphere], 1.0),
            "ring": halo_actor(self._selected, 1.0),
            "gap": halo_actor(self._selected, 1.0, ring=False),
        }
        m = self.actors["targets"].GetMapper()
        m.SetScalarModeToUsePointFieldData()
        m.SelectColorArray("rgb")
        m.SetColorModeToDirectScalars()
        m.ScalarVisibilityOn()
        self.actors["targets"].GetProperty().SetAmbient(0.35)
        self.actors["points"].GetMapper().ScalarVisibilityOff()
        self.actors["points"].GetProperty().SetColor(1.0, 1.0, 1.0)
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(self._lines)
        self.actors["lines"] = vtkActor()
        self.actors["lines"].SetMapper(mapper)
        prop = self.actors["lines"].GetProperty()
        prop.SetColor(*rgb01(style.HANDLE))
        prop.SetLineWidth(2.0)
        prop.LightingOff()
        for actor in self.actors.values():
            actor.PickableOff()
            actor.SetVisibility(False)
            overlay.add(actor)

    def set_size(self, model_size: float) -> None:
        self.size = HANDLE_FRACTION * float(model_size)
        self.actors["targets"].GetMapper().SetScaleFactor(self.size)
        self.actors["points"].GetMapper().SetScaleFactor(0.35 * self.size)
        self.actors["ring"].GetMapper().SetScaleFactor(HALO * self.size)
        self.actors["gap"].GetMapper().SetScaleFactor(GAP * self.size)

    def show(self, targets, points, count: int, selected: int | None = None) -> None:
        """Draw handles with these ``targets`` and current ``points`` ((h, 3) each); the
        first ``count`` are the user's, the rest mirror images; ``selected`` is one of
        the user's, or None."""
        self.targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
        self.points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self.count, self.selected = int(count), selected
        h = len(self.targets)
        ringed = selected is not None and 0 <= selected < self.count
        for name, actor in self.actors.items():
            actor.SetVisibility(h > 0 and (ringed or name not in ("ring", "gap")))
        if h == 0:
            return
        self.overlay.sync()
        rgb = np.tile(np.array(style.hex_to_rgb(style.HANDLE), np.uint8), (h, 1))
        rgb[self.count :] = (rgb[self.count :] * 0.55).astype(np.uint8)
        if ringed:
            self._set(self._selected, self.targets[selected : selected + 1])
            self._selected.Modified()
        self._set(self._targets, self.targets)
        self._targets.point_data["rgb"] = rgb
        self._set(self._points, self.points)
        lines = np.c_[np.full(h, 2), np.arange(h), np.arange(h) + h].ravel()
        self._lines.copy_from(pv.PolyData(np.vstack([self.targets, self.points]), lines=lines))
        for poly in (self._targets, self._points, self._lines):
            poly.Modified()

    @staticmethod
    def _set(poly: pv.PolyData, pts: np.ndarray) -> None:
        if poly.n_points == len(pts):
            poly.points[:] = pts
        else:
            poly.copy_from(pv.PolyData(pts))

    def target_colours(self) -> np.ndarray:
        """(h, 3) uint8: each target's colour as drawn."""
        return np.array(self._targets.point_data["rgb"])

    def at(self, proj: picking.Projection, x: float, y: float) -> int:
        """The user's handle whose target is drawn under widget pixel (x, y), or -1."""
        if self.count == 0:
            return -1
        return picking.nearest(proj, self.targets[: self.count], x, y, HANDLE_PICK)
