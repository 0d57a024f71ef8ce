"""The model as the view draws it: the full mesh, or a proxy while something moves. GUI
thread only.

A big model's frame costs what its triangles cost: deforming them, their vertex normals
(smooth shading) and, above all, rendering them. Measured on the 346k-triangle armadillo in
the 1360x860 window, software OpenGL (llvmpipe) on 2 cores: one render costs about 18 ms
without the model, 27 ms with its 21.6k-triangle pyramid level, 60 ms with the 86k one and
150 ms with the full mesh; the normals cost 4, 21 and 60-140 ms. So while the lattice
moves (a drag, a solve running) a model of more than :data:`PROXY_TRIANGLES` triangles is
drawn as a *proxy*: the finest level of its pyramid with at most that many triangles,
deformed by the same nodes, with the same colour and shading. When nothing moves any more
the full mesh is drawn again: it is deformed and shaded in steps of :data:`STEP_FACES`
triangles, one step per event-loop turn (:meth:`ModelView.step`, driven by the view), with
the proxy on screen meanwhile, and then drawn in passes of as many triangles, one per turn
too (:attr:`MeshView.pieces`, :class:`~isochor.app.view.composer.Composer`), and shown in
place of the proxy.

The volume comes with the normals (the same cross products): the proxy's, scaled by the
full mesh's rest volume over the proxy's, is an *estimate* (:attr:`ModelView.estimated`);
the full mesh's is measured, or given by a solve's result (:meth:`ModelView.know_volume`).
Picking always uses the full mesh at the nodes drawn (:meth:`ModelView.points`), so a
surface point is a full-mesh triangle whatever is on screen.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator

import numpy as np
import pyvista as pv
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

from . import style
from .composer import Composer
from .meshprep import (  # noqa: F401 (draw_order, cells, capped_last: the view's names too)
    AT_ONCE_FACES,
    PROXY_TRIANGLES,
    STEP_FACES,
    DisplayPrep,
    MeshPrep,
    Shading,
    capped_last,
    cells,
    draw_order,
    ghost_mesh,
    proxy_level,
)

#: a moving frame's paint (the proxy's) should take at most this, seconds: software OpenGL
#: draws every triangle, so when the median of the last :data:`PROXY_SAMPLES` paints of the
#: proxy is over it, the next coarser pyramid level becomes the proxy (for the rest of the
#: process: the machine is as slow for the next model)
PROXY_BUDGET = 0.025
PROXY_SAMPLES = 5
#: the proxy never gets coarser than a level of this many triangles (a rougher stand-in
#: shows its facets while it moves)
PROXY_FLOOR = 2000

#: how the model is lit (the same for the full mesh and the proxy)
LOOK = {"specular": 0.25, "specular_power": 20, "diffuse": 0.85, "ambient": 0.12}


def rgb(color: str) -> np.ndarray:
    return np.array(style.hex_to_rgb(color), dtype=np.uint8)


class MeshView:
    """One drawn mesh of the model: its polydata, actor and shading."""

    def __init__(self, plotter, prep: MeshPrep, name: str, smooth: bool, cull: bool = True):
        self.faces = prep.faces
        self.n_faces = len(prep.faces)
        self.shading = prep.shading
        self.closed = prep.closed  #: closed and consistently wound: back faces can be culled
        points = prep.points
        self.poly = pv.PolyData(np.array(points), prep.cells)
        self.caps = None if prep.cap_cells is None else Caps(plotter, points, prep.cap_cells, name)
        self.poly.point_data["colors"] = np.tile(rgb(style.MODEL), (len(points), 1))
        self.volume = prep.volume
        self.actor = plotter.add_mesh(
            self.poly,
            scalars="colors",
            rgb=True,
            smooth_shading=False,
            show_scalar_bar=False,
            render=False,
            name=name,
            **LOOK,
        )
        self.set_culling(cull)
        self._cells = prep.cells
        self.pieces: list = []  #: actors on ranges of the triangles (:meth:`add_pieces`)
        self._smooth(smooth, prep.normals)

    def add_pieces(self, plotter, faces: int = STEP_FACES) -> None:
        """Actors that draw the mesh in pieces of ``faces`` triangles (consecutive in draw
        order: each a compact region), hidden: a frame is composed of them in passes
        (:mod:`isochor.app.view.composer`). They share this mesh's points, point arrays
        (VTK uploads them once for all), property and mapper settings."""
        quads = np.asarray(self._cells).reshape(-1, 4)
        mapper = self.actor.GetMapper()
        for s in range(0, len(quads), faces):
            piece = pv.PolyData()
            piece.SetPoints(self.poly.GetPoints())
            piece.SetPolys(pv.CellArray(quads[s : s + faces].ravel()))
            own = vtkPolyDataMapper()
            own.ShallowCopy(mapper)
            own.SetInputData(piece)
            actor = vtkActor()
            actor.SetMapper(own)
            actor.SetProperty(self.actor.GetProperty())
            actor.SetPickable(False)
            actor.SetVisibility(False)
            plotter.renderer.AddActor(actor)
            self.pieces.append(actor)
        self._share()

    def remove_pieces(self, plotter) -> None:
        for actor in self.pieces:
            plotter.renderer.RemoveActor(actor)
        self.pieces = []

    def _share(self) -> None:
        """The pieces draw this mesh's point arrays (after they were replaced)."""
        for actor in self.pieces:
            actor.GetMapper().GetInput().GetPointData().ShallowCopy(self.poly.GetPointData())

    def set_culling(self, on: bool) -> None:
        """Cull back faces (on) when the mesh is closed: software OpenGL then shades about
        half the triangles (the 346k armadillo's full render 1.7x faster, its proxy's
        1.2-1.4x, see docs/BENCHMARKS.md); an open mesh shows its inside and is never
        culled."""
        self.actor.GetProperty().SetBackfaceCulling(bool(on and self.closed))

    def place(self, points: np.ndarray, normals: np.ndarray | None, volume: float) -> None:
        self.poly.points[:] = points
        if normals is not None:
            self.poly.point_data["Normals"][:] = normals
        self.volume = volume
        self.poly.Modified()
        if self.caps is not None:
            self.caps.place(points)

    def draw_at(self, points: np.ndarray, smooth: bool) -> None:
        normals, volume = self.shading(points)
        self.place(points, normals if smooth else None, volume)

    def set_smooth(self, on: bool) -> None:
        """Smooth shading (the vertex normals, interpolated) or flat (each triangle's own
        normal). VTK ignores the vertex normals under flat interpolation, which is what
        ``add_mesh(smooth_shading=False)`` sets, so the interpolation is set here too."""
        self._smooth(on, self.shading(np.asarray(self.poly.points))[0] if on else None)

    def _smooth(self, on: bool, normals: np.ndarray | None) -> None:
        poly = self.poly
        prop = self.actor.GetProperty()
        if on:
            poly.point_data["Normals"] = normals
            poly.point_data.active_normals_name = "Normals"
            prop.SetInterpolationToGouraud()
        else:
            poly.GetPointData().SetNormals(None)
            prop.SetInterpolationToFlat()
        poly.Modified()
        self._share()


class Caps:
    """The caps over an open model's holes (:mod:`isochor.core.io.caps`), drawn on demand:
    translucent, so that the artist sees which volume is kept. Hidden by default; placed
    with the full mesh only while shown."""

    def __init__(self, plotter, points: np.ndarray, cap_cells: np.ndarray, name: str) -> None:
        self.poly = pv.PolyData(np.array(points), cap_cells)
        self.actor = plotter.add_mesh(
            self.poly,
            color=style.CAPS,
            opacity=0.55,
            show_scalar_bar=False,
            render=False,
            pickable=False,
            name=f"{name} caps",
        )
        self.actor.SetVisibility(False)
        self.wanted = False

    def place(self, points: np.ndarray) -> None:
        if self.actor.GetVisibility():
            self.poly.points[:] = points
            self.poly.Modified()

    def show(self, on: bool, points: np.ndarray) -> None:
        if on and not self.actor.GetVisibility():
            self.poly.points[:] = points
            self.poly.Modified()
        self.actor.SetVisibility(bool(on))


class ModelView:
    """The model's actors ("model", the full mesh, and "proxy" when the model is big) and
    which of them is drawn."""

    def __init__(self, plotter) -> None:
        self.plotter = plotter
        self.full: MeshView | None = None
        self.proxy: MeshView | None = None
        self.proxy_k: int | None = None  #: the proxy's pyramid level
        self.nodes = np.zeros((0, 3))
        self.smooth = True
        self.cull = True  #: closed meshes are drawn without their back faces
        self.volume = 0.0  #: signed volume of the model at the nodes drawn
        self.estimated = False  #: :attr:`volume` is the proxy's estimate
        self.folded = 0  #: how many vertices are marked folded
        self.caps_wanted = False  #: draw the caps over an open model's holes
        self._surface = None
        self._full_nodes: np.ndarray | None = None  # the nodes the full mesh is placed at
        self._upgrade: Iterator[None] | None = None
        self._points: tuple[np.ndarray, np.ndarray] | None = None  # (nodes, full points)
        self._scale = 1.0  # full rest volume / proxy rest volume
        #: the most triangles a proxy may have, lowered when its paints overrun the budget
        self.proxy_cap: int | None = None
        self._proxy_costs: deque[float] = deque(maxlen=PROXY_SAMPLES)
        #: draws the full mesh's frame in passes when a big model stops moving
        self.composer = Composer(plotter.ren_win, plotter.renderer)

    # -- building ----------------------------------------------------------------------------
    def build(self, surface, nodes: np.ndarray, smooth: bool, prep: DisplayPrep | None = None):
        """Add the actors for ``surface`` at ``nodes`` (the plotter was cleared), from
        ``prep`` when it was computed for them (off the GUI thread), else computed here."""
        self._surface = surface
        self.smooth = bool(smooth)
        self.nodes = np.array(nodes, dtype=np.float64)
        self._upgrade, self._points = None, None
        if prep is None or not prep.fits(surface, self.nodes):
            prep = DisplayPrep.of(surface, self.nodes)
        self.composer.cancel()
        if self.full is not None:  # (the plotter removes the named actors, not the pieces)
            self.full.remove_pieces(self.plotter)
        self.full = MeshView(self.plotter, prep.full, "model", self.smooth, self.cull)
        self._full_nodes = self.nodes.copy()
        self.folded = 0
        self.volume, self.estimated = self.full.volume, False
        self.show_caps(self.caps_wanted)
        self.proxy_k = prep.proxy_k
        self.proxy = None
        if prep.proxy is not None:
            self.proxy = MeshView(self.plotter, prep.proxy, "proxy", self.smooth, self.cull)
            self._scale = prep.scale
            self.proxy.actor.SetVisibility(False)
            self.full.add_pieces(self.plotter)
            self._proxy_costs.clear()
            cap = self.proxy_cap
            k = self.proxy_k
            while cap is not None and k > 0 and surface.levels[k].n_faces > cap:
                k -= 1
            if k != self.proxy_k and surface.levels[k].n_faces >= PROXY_FLOOR:
                self._set_proxy(k)

    # -- the proxy's size ----------------------------------------------------------------------
    def proxy_painted(self, seconds: float) -> None:
        """The view painted a frame in ``seconds``: counted when it showed the proxy."""
        if self.proxy is not None and self.proxy.actor.GetVisibility():
            self._proxy_costs.append(float(seconds))

    def _fit_proxy(self) -> None:
        """A coarser proxy when the last paints of this one overran :data:`PROXY_BUDGET`."""
        costs = self._proxy_costs
        if len(costs) < PROXY_SAMPLES or float(np.median(costs)) <= PROXY_BUDGET:
            return
        k = self.proxy_k - 1
        if k < 0 or self._surface.levels[k].n_faces < PROXY_FLOOR:
            return
        self._set_proxy(k)
        self.proxy_cap = self._surface.levels[k].n_faces

    def _set_proxy(self, k: int) -> None:
        """Draw pyramid level ``k`` as the proxy from now on (a small level: its arrays are
        made here, in a few milliseconds)."""
        surface = self._surface
        mesh = capped_last(surface.levels[k], surface.full)
        prep = MeshPrep.of(mesh, surface.deform(self.nodes, level=k), surface.center)
        shown = bool(self.proxy.actor.GetVisibility())
        self.plotter.remove_actor(self.proxy.actor, render=False)
        self.proxy = MeshView(self.plotter, prep, "proxy", self.smooth, self.cull)
        self.proxy.actor.SetVisibility(shown)
        self.proxy_k = k
        rest = prep.shading(mesh.vertices)[1]
        self._scale = surface.rest_volume / rest if rest else 1.0
        self._proxy_costs.clear()

    def set_culling(self, on: bool) -> None:
        """Cull the back faces of the closed meshes (on, the default) or draw them."""
        self.cull = bool(on)
        for mesh in (self.full, self.proxy):
            if mesh is not None:
                mesh.set_culling(self.cull)

    def ghost_mesh(self, surface):
        """The rest shape the ghost draws (:func:`~isochor.app.view.meshprep.ghost_mesh`)."""
        return ghost_mesh(surface)

    # -- frames ------------------------------------------------------------------------------
    def draw(self, nodes: np.ndarray, moving: bool) -> None:
        """Draw the model at ``nodes``: the proxy while ``moving`` (a big model), else the
        full mesh (a big model's in steps and passes: :meth:`step`, the proxy on screen
        meanwhile)."""
        nodes = np.array(nodes, dtype=np.float64)
        self.nodes = nodes
        self.composer.cancel()
        if self.proxy is None or not moving:
            self._upgrade = None
            fresh = self._full_nodes is not None and np.array_equal(nodes, self._full_nodes)
            if not fresh and (self.proxy is None or self.full.n_faces <= AT_ONCE_FACES):
                self.full.draw_at(self._surface.deform(nodes), self.smooth)
                self._full_nodes, self._points, fresh = nodes.copy(), None, True
            # (a big model's full mesh placed already but not on screen, after a press or
            # during its passes, comes back in passes too: :meth:`_back`)
            at_once = self.proxy is None or self.full.n_faces <= AT_ONCE_FACES
            if fresh and (at_once or self.full.actor.GetVisibility()):
                self._show(full=True)
                self.volume, self.estimated = self.full.volume, False
                return
        self._fit_proxy()
        self.proxy.draw_at(self._surface.deform(nodes, level=self.proxy_k), self.smooth)
        self.volume, self.estimated = self.proxy.volume * self._scale, True
        self._show(full=False)
        self._upgrade = None if moving else self._back(nodes)

    def lower(self) -> None:
        """Draw the proxy at the nodes drawn now, and the full mesh again through
        :meth:`step` (at once when it is placed there already)."""
        if self.proxy is None:
            return
        nodes = self.nodes
        self.draw(nodes, moving=True)
        self._upgrade = self._back(nodes)

    def _back(self, nodes: np.ndarray) -> Iterator[None]:
        if self._full_nodes is None or not np.array_equal(nodes, self._full_nodes):
            yield from self._steps(nodes)
            return
        yield from self._compose()
        if self.estimated:
            self.volume, self.estimated = self.full.volume, False
        self._show(full=True)
        self.composer.arm()

    @property
    def upgrading(self) -> bool:
        """The full mesh is being prepared (the proxy is on screen until it is)."""
        return self._upgrade is not None

    @property
    def showing_full(self) -> bool:
        return self.proxy is None or (
            self._upgrade is None and bool(self.full.actor.GetVisibility())
        )

    def step(self) -> bool:
        """One step of preparing the full mesh; True when it is drawn (or nothing was being
        prepared)."""
        if self._upgrade is None:
            return True
        try:
            next(self._upgrade)
            return False
        except StopIteration:
            self._upgrade = None
            return True

    def finish(self) -> None:
        """Prepare the full mesh now (before a screenshot)."""
        while not self.step():
            pass

    def _steps(self, nodes: np.ndarray) -> Iterator[None]:
        points = np.asarray(self._surface.deform(nodes))
        yield
        normals, volume = yield from self.full.shading.steps(points)
        yield
        self.full.place(points, normals if self.smooth else None, volume)
        self._full_nodes = nodes.copy()
        self._points = None
        yield from self._compose()
        if self.estimated:  # (not when a solve's result said it meanwhile)
            self.volume, self.estimated = volume, False
        self._show(full=True)
        self.composer.arm()  # (the view's next paint shows the frame the passes drew)

    def _compose(self) -> Iterator[None]:
        """The frame with the full mesh drawn in passes, one a step (the proxy on screen
        meanwhile; :mod:`isochor.app.view.composer`)."""
        yield
        yield from self.composer.passes(self.full.pieces, [self.full.actor, self.proxy.actor])

    def _show(self, full: bool) -> None:
        self.full.actor.SetVisibility(full)
        if self.proxy is not None:
            self.proxy.actor.SetVisibility(not full)
        if self.full.caps is not None:  # (on the full mesh only: the proxy has no caps apart)
            self.full.caps.show(full and self.caps_wanted, np.asarray(self.full.poly.points))

    def show_caps(self, on: bool) -> None:
        """Draw the caps over the model's holes (when it has any) or not."""
        self.caps_wanted = bool(on)
        self._show(bool(self.full.actor.GetVisibility()))

    @property
    def has_caps(self) -> bool:
        return self.full is not None and self.full.caps is not None

    def know_volume(self, nodes: np.ndarray, volume: float) -> None:
        """The full mesh's volume at ``nodes`` is ``volume`` (measured by a solve): say it
        instead of an estimate when those are the nodes drawn."""
        if np.array_equal(np.asarray(nodes), self.nodes):
            self.volume, self.estimated = float(volume), False

    # -- what is drawn -----------------------------------------------------------------------
    def drawn(self) -> str:
        """Which mesh is on screen, for the status and the tests."""
        if self.proxy is not None and self.proxy.actor.GetVisibility():
            return f"proxy (level {self.proxy_k + 1}, {self.proxy.n_faces} triangles)"
        return f"full mesh ({self.full.n_faces} triangles)"

    def points(self) -> np.ndarray:
        """(m, 3) the full mesh's vertices at the nodes drawn (deformed now when the full
        mesh is not placed there: the proxy is on screen)."""
        if self._full_nodes is not None and np.array_equal(self._full_nodes, self.nodes):
            return np.asarray(self.full.poly.points)
        if self._points is None or not np.array_equal(self._points[0], self.nodes):
            self._points = (self.nodes.copy(), np.asarray(self._surface.deform(self.nodes)))
        return self._points[1]

    def faces(self) -> np.ndarray:
        """(f, 3) the full mesh's triangles."""
        return self.full.faces

    def bounds(self) -> np.ndarray:
        """(2, 3) lowest and highest corner of the model at the nodes drawn."""
        pts = self.points()
        return np.array([pts.min(axis=0), pts.max(axis=0)])

    # -- looks -------------------------------------------------------------------------------
    def set_smooth(self, on: bool) -> None:
        self.smooth = bool(on)
        for mesh in (self.full, self.proxy):
            if mesh is not None:
                mesh.set_smooth(self.smooth)

    def set_folds(self, vertices: np.ndarray | None) -> None:
        """Mark the folded vertices of the full mesh (a (m,) bool mask), or clear the marks
        (None)."""
        colors = self.full.poly.point_data["colors"]
        mask = None if vertices is None else np.asarray(vertices, bool)
        count = 0 if mask is None else int(mask.sum())
        if count == 0 and self.folded == 0:
            return
        colors[:] = rgb(style.MODEL)
        if count:
            colors[mask] = rgb(style.FOLDED)
        self.folded = count
        self.full.poly.Modified()

    def colours(self) -> np.ndarray:
        """(m, 3) uint8: each full-mesh vertex's colour as drawn."""
        return np.array(self.full.poly.point_data["colors"])
