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
the proxy on screen meanwhile, and then shown in place of the proxy.

The volume comes with the normals (the same cross products): the proxy's, scaled by the
full mesh's rest volume over the proxy's, is an *estimate* (:attr:`ModelView.estimated`);
the full mesh's is measured, or given by a solve's result (:meth:`ModelView.know_volume`).
Picking always uses the full mesh at the nodes drawn (:meth:`ModelView.points`), so a
surface point is a full-mesh triangle whatever is on screen.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pyvista as pv
import scipy.sparse as sp

from . import style

#: a model with more triangles is drawn as a proxy while it moves: the finest pyramid
#: level with at most this many (the armadillo's 21.6k level: a 27 ms render, see above)
PROXY_TRIANGLES = 50_000
#: triangles shaded per step when the full mesh is drawn again (about 5-10 ms a step)
STEP_FACES = 1 << 16
#: a full mesh of up to this many triangles is drawn again at once (in one frame)
AT_ONCE_FACES = 2 * STEP_FACES

#: how the model is lit (the same for the full mesh and the proxy)
LOOK = {"specular": 0.25, "specular_power": 20, "diffuse": 0.85, "ambient": 0.12}


def cells(faces: np.ndarray) -> np.ndarray:
    """VTK cell array of equal-sized cells: ``[k, i0, .., ik-1, k, ...]``."""
    faces = np.asarray(faces, dtype=np.int64)
    return np.hstack([np.full((len(faces), 1), faces.shape[1], dtype=np.int64), faces]).ravel()


def draw_order(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The triangles in the order they are drawn: along a Morton (Z-order) curve through
    their first corners, so that triangles near in space come near in the draw order.
    Software OpenGL (llvmpipe) bins and shades them faster that way, its tiles and caches
    meeting one region at a time. Off screen, the 346k armadillo's full render: in its
    file's order 93 ms, shuffled 126 ms, shuffled and then put in this order 90 ms. A
    file's order is often local already (the armadillo's, a subdivision's); this order
    keeps every file there. The picture is the same; picking and shading keep the mesh's
    own order (:attr:`MeshView.faces`). About 25 ms for 346k triangles (the first corner
    instead of the centroid: the same grid cell but for one in a few, at a seventh of the
    cost)."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) < 2:
        return np.arange(len(faces))
    corners = np.asarray(points, dtype=np.float64)[faces[:, 0]]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    cells = (corners - lo) / np.where(hi > lo, hi - lo, 1.0) * (MORTON_CELLS - 1)
    code = np.zeros(len(faces), dtype=np.uint64)
    for axis in range(3):
        code |= _spread(cells[:, axis].astype(np.uint64)) << np.uint64(axis)
    return np.argsort(code)


#: cells per axis of the draw order's grid (10 bits: a 30-bit Morton code)
MORTON_CELLS = 1 << 10


def _spread(x: np.ndarray) -> np.ndarray:
    """The low 10 bits of ``x`` spread to every third bit (Morton interleaving)."""
    x = x & np.uint64(0x3FF)
    for shift, mask in ((16, 0x30000FF), (8, 0x300F00F), (4, 0x30C30C3), (2, 0x9249249)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def rgb(color: str) -> np.ndarray:
    return np.array(style.hex_to_rgb(color), dtype=np.uint8)


def proxy_level(levels, limit: int = PROXY_TRIANGLES) -> int | None:
    """The level drawn while a model of these ``levels`` (coarse to fine) moves: the finest
    coarser than the full mesh with at most ``limit`` triangles; None when the full mesh
    has no more than ``limit`` (it is drawn itself) or no level fits."""
    if levels[-1].n_faces <= limit:
        return None
    fits = [k for k, m in enumerate(levels[:-1]) if m.n_faces <= limit]
    return fits[-1] if fits else None


def capped_last(level, full):
    """A coarse ``level`` of an open model with the triangles that simplify its caps put
    last and counted as caps (so they are drawn only with the caps): those whose centre is
    nearest a cap triangle of the ``full`` mesh. ``level`` itself for a closed model."""
    if not full.cap_faces:
        return level
    from scipy.spatial import cKDTree

    def centres(mesh):
        return np.asarray(mesh.vertices)[np.asarray(mesh.faces)].mean(axis=1)

    _, nearest = cKDTree(centres(full)).query(centres(level))
    cap = nearest >= full.own_faces
    faces = np.asarray(level.faces)
    return type(level)(level.vertices, np.vstack([faces[~cap], faces[cap]]), 0, int(cap.sum()))


class Shading:
    """Vertex normals and the enclosed volume of a deforming mesh with a fixed face list.

    The face normals (cross products of two edges) are gathered to the vertices by sparse
    incidence matrices built once, one per block of :data:`STEP_FACES` faces, and the
    volume is the sum of ``(a - c) . ((b - a) x (c' - a)) / 6`` over the faces (``c`` a
    centre near the mesh): the same cross products.
    """

    def __init__(self, faces: np.ndarray, n_vertices: int, center) -> None:
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.n_vertices = int(n_vertices)
        self.center = np.asarray(center, dtype=np.float64)
        self.blocks: list[tuple[int, int, sp.csr_matrix]] = []
        f = len(self.faces)
        for s in range(0, f, STEP_FACES):
            t = min(s + STEP_FACES, f)
            rows = self.faces[s:t].ravel()
            cols = np.repeat(np.arange(t - s), 3)
            gather = sp.csr_matrix(
                (np.ones(3 * (t - s)), (rows, cols)), shape=(self.n_vertices, t - s)
            )
            self.blocks.append((s, t, gather))

    def steps(self, points: np.ndarray) -> Iterator[None]:
        """Compute in steps (one per block of faces); yields between them, returns
        ``(normals (m, 3), volume)``."""
        points = np.asarray(points, dtype=np.float64)
        vn = np.zeros((self.n_vertices, 3))
        volume = 0.0
        for s, t, gather in self.blocks:
            f = self.faces[s:t]
            a = points[f[:, 0]]
            n = np.cross(points[f[:, 1]] - a, points[f[:, 2]] - a)
            a -= self.center
            volume += float(np.einsum("ij,ij->", a, n)) / 6.0
            vn += gather @ n
            if t < len(self.faces):
                yield
        norm = np.sqrt(np.einsum("ij,ij->i", vn, vn))[:, None]
        norm[norm == 0] = 1.0
        return vn / norm, volume

    def __call__(self, points: np.ndarray) -> tuple[np.ndarray, float]:
        """``(normals (m, 3), volume)`` at once."""
        run = self.steps(points)
        while True:
            try:
                next(run)
            except StopIteration as done:
                return done.value


class MeshView:
    """One drawn mesh of the model: its polydata, actor and shading."""

    def __init__(self, plotter, mesh, points: np.ndarray, center, name: str, smooth: bool):
        faces = np.asarray(mesh.faces)
        own = faces[: len(faces) - getattr(mesh, "cap_faces", 0)]  # never the caps
        self.faces = own  # (what is drawn and picked: the model's own triangles)
        self.n_faces = len(own)
        self.shading = Shading(faces, len(points), center)  # (the capped solid's volume)
        self.poly = pv.PolyData(np.array(points), cells(own[draw_order(points, own)]))
        self.caps = (
            Caps(plotter, points, faces[len(own) :], name) if len(own) < len(faces) else None
        )
        self.poly.point_data["colors"] = np.tile(rgb(style.MODEL), (len(points), 1))
        normals, self.volume = self.shading(points)
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
        self._smooth(smooth, normals)

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


class Caps:
    """The caps over an open model's holes (:mod:`isochor.core.io.caps`), drawn on demand:
    translucent, so that the artist sees which volume is kept. Hidden by default; placed
    with the full mesh only while shown."""

    def __init__(self, plotter, points: np.ndarray, faces: np.ndarray, name: str) -> None:
        self.poly = pv.PolyData(np.array(points), cells(faces))
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
        self.volume = 0.0  #: signed volume of the model at the nodes drawn
        self.estimated = False  #: :attr:`volume` is the proxy's estimate
        self.folded = 0  #: how many vertices are marked folded
        self.caps_wanted = False  #: draw the caps over an open model's holes
        self._surface = None
        self._full_nodes: np.ndarray | None = None  # the nodes the full mesh is placed at
        self._upgrade: Iterator[None] | None = None
        self._points: tuple[np.ndarray, np.ndarray] | None = None  # (nodes, full points)
        self._scale = 1.0  # full rest volume / proxy rest volume

    # -- building ----------------------------------------------------------------------------
    def build(self, surface, nodes: np.ndarray, smooth: bool) -> None:
        """Add the actors for ``surface`` at ``nodes`` (the plotter was cleared)."""
        self._surface = surface
        self.smooth = bool(smooth)
        self.nodes = np.array(nodes, dtype=np.float64)
        self._upgrade, self._points = None, None
        center = surface.center
        points = surface.deform(self.nodes)
        self.full = MeshView(self.plotter, surface.full, points, center, "model", self.smooth)
        self._full_nodes = self.nodes.copy()
        self.folded = 0
        self.volume, self.estimated = self.full.volume, False
        self.show_caps(self.caps_wanted)
        self.proxy_k = proxy_level(surface.levels)
        self.proxy = None
        if self.proxy_k is not None:
            mesh = capped_last(surface.levels[self.proxy_k], surface.full)
            points = surface.deform(self.nodes, level=self.proxy_k)
            self.proxy = MeshView(self.plotter, mesh, points, center, "proxy", self.smooth)
            rest = self.proxy.shading(mesh.vertices)[1]
            self._scale = surface.rest_volume / rest if rest else 1.0
            self.proxy.actor.SetVisibility(False)

    def ghost_mesh(self, surface):
        """The rest shape the ghost draws: the proxy's level when there is one (faint and
        translucent, it looks the same at a fraction of the cost)."""
        k = proxy_level(surface.levels)
        return surface.full.own if k is None else surface.levels[k]

    # -- frames ------------------------------------------------------------------------------
    def draw(self, nodes: np.ndarray, moving: bool) -> None:
        """Draw the model at ``nodes``: the proxy while ``moving`` (a big model), else the
        full mesh (a big model's in steps: :meth:`step`, the proxy on screen meanwhile)."""
        nodes = np.array(nodes, dtype=np.float64)
        self.nodes = nodes
        if self.proxy is None or not moving:
            self._upgrade = None
            fresh = self._full_nodes is not None and np.array_equal(nodes, self._full_nodes)
            if not fresh and (self.proxy is None or self.full.n_faces <= AT_ONCE_FACES):
                self.full.draw_at(self._surface.deform(nodes), self.smooth)
                self._full_nodes, self._points, fresh = nodes.copy(), None, True
            if fresh:
                self._show(full=True)
                self.volume, self.estimated = self.full.volume, False
                return
        self.proxy.draw_at(self._surface.deform(nodes, level=self.proxy_k), self.smooth)
        self.volume, self.estimated = self.proxy.volume * self._scale, True
        self._show(full=False)
        self._upgrade = None if moving else self._steps(nodes)

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
        if self.estimated:  # (not when a solve's result said it meanwhile)
            self.volume, self.estimated = volume, False
        self._show(full=True)

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
