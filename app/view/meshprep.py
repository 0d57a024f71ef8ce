"""What drawing a model needs that is not drawing: numpy only, so that a worker thread may
compute it (no Qt, VTK or pyvista here; the view builds its actors from it on the GUI
thread, :mod:`isochor.app.view.modelview`).

- :func:`draw_order`: the triangles along a space-filling curve (software OpenGL draws them
  faster so);
- :class:`Shading`: vertex normals and the enclosed volume of a deforming mesh;
- :func:`proxy_level`: which pyramid level stands in for a big model while it moves, and
  :func:`capped_last` its triangles that simplify an open model's caps set apart;
- :func:`closed`: whether a mesh is closed and consistently wound (its back faces can never
  be seen from outside: the view culls them; an open model's own triangles, drawn without
  its virtual caps, are not closed);
- :class:`DisplayPrep`: all of it for one model at given nodes, computed where waiting does
  not hurt (the loading thread, a lattice rebuild's thread) and handed to the view, which
  then only makes the VTK objects.

Opening the 346k armadillo, the view's own preparation of its full mesh and proxy took
0.5-0.75 s of the GUI thread (the draw order, the shading matrices, the normals), a lattice
rebuild 0.2 s more than that on top of the full level's basis.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

#: a model with more triangles is drawn as a proxy while it moves: the finest pyramid
#: level with at most this many (the armadillo's 21.6k level: a 27 ms render, see above)
PROXY_TRIANGLES = 50_000
#: triangles shaded per step when the full mesh is drawn again (about 5-10 ms a step)
STEP_FACES = 1 << 16
#: a full mesh of up to this many triangles is drawn again at once (in one frame)
AT_ONCE_FACES = 2 * STEP_FACES


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


def proxy_level(levels, limit: int = PROXY_TRIANGLES) -> int | None:
    """The level drawn while a model of these ``levels`` (coarse to fine) moves: the finest
    coarser than the full mesh with at most ``limit`` triangles; None when the full mesh
    has no more than ``limit`` (it is drawn itself) or no level fits."""
    if levels[-1].n_faces <= limit:
        return None
    fits = [k for k, m in enumerate(levels[:-1]) if m.n_faces <= limit]
    return fits[-1] if fits else None


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


def closed(faces: np.ndarray) -> bool:
    """Whether the triangles ``faces`` (f, 3) close up consistently: every directed edge
    appears once and its reverse once (each edge between exactly two triangles that wind
    it opposite ways). Such a surface seen from outside never shows a back face, so culling
    them changes no pixel there; an open surface (or one capped only virtually, drawn
    without its caps) shows its inside through the hole and is not culled."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0 or len(faces) % 2:  # (3f half-edges must pair up)
        return False
    a, b = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    n = int(faces.max()) + 1
    key = np.minimum(a, b) * n + np.maximum(a, b)  # the undirected edge
    order = np.argsort(key, kind="stable")
    key, forward = key[order], (a < b)[order]
    # every edge exactly twice (equal keys in pairs, no key in two pairs), wound both ways
    return bool(
        (key[0::2] == key[1::2]).all()
        and (key[1:-1:2] != key[2::2]).all()
        and (forward[0::2] != forward[1::2]).all()
    )


def capped_last(level, full):
    """A coarse ``level`` of an open model with the triangles that simplify its caps put
    last and counted as caps (so they are drawn only with the caps): those whose centre is
    nearest a cap triangle of the ``full`` mesh. ``level`` itself for a closed model."""
    if not getattr(full, "cap_faces", 0):
        return level
    from scipy.spatial import cKDTree

    def centres(mesh):
        return np.asarray(mesh.vertices)[np.asarray(mesh.faces)].mean(axis=1)

    _, nearest = cKDTree(centres(full)).query(centres(level))
    cap = nearest >= full.own_faces
    faces = np.asarray(level.faces)
    return type(level)(level.vertices, np.vstack([faces[~cap], faces[cap]]), 0, int(cap.sum()))


def ghost_mesh(surface):
    """The rest shape the ghost draws: the proxy's level when there is one (faint and
    translucent, it looks the same at a fraction of the cost), else the model's own
    triangles (never its caps)."""
    k = proxy_level(surface.levels)
    full = surface.full
    return getattr(full, "own", full) if k is None else surface.levels[k]


@dataclass(frozen=True)
class MeshPrep:
    """One drawn mesh of the model, computed: the points at the nodes, the model's own
    triangles (what is drawn and picked, never an open model's caps) and their VTK cell
    array in draw order, the caps' cell array (None without caps), the shading of the whole
    solid (the capped volume) with its normals and volume there, and whether the drawn
    triangles are closed."""

    faces: np.ndarray
    points: np.ndarray
    cells: np.ndarray
    cap_cells: np.ndarray | None
    shading: Shading
    normals: np.ndarray
    volume: float
    closed: bool

    @classmethod
    def of(cls, mesh, points: np.ndarray, center) -> MeshPrep:
        faces = np.asarray(mesh.faces)
        own = faces[: len(faces) - getattr(mesh, "cap_faces", 0)]  # never the caps
        points = np.asarray(points, dtype=np.float64)
        shading = Shading(faces, len(points), center)  # (the capped solid's volume)
        normals, volume = shading(points)
        caps = cells(faces[len(own) :]) if len(own) < len(faces) else None
        drawn = cells(own[draw_order(points, own)])
        return cls(own, points, drawn, caps, shading, normals, volume, closed(own))


@dataclass(frozen=True)
class DisplayPrep:
    """What the view draws a model with at ``nodes``, computed off the GUI thread: the full
    mesh, the proxy (None for a small model) with its level and volume scale, the ghost's
    rest mesh with its cells. :meth:`fits` says whether it is for this surface and nodes."""

    surface: object
    nodes: np.ndarray
    full: MeshPrep
    proxy: MeshPrep | None
    proxy_k: int | None
    scale: float
    ghost_cells: np.ndarray

    @classmethod
    def of(cls, surface, nodes) -> DisplayPrep:
        """Compute it (Qt-free: any thread). ``surface`` an embedded surface."""
        nodes = np.array(nodes, dtype=np.float64)
        center = surface.center
        full = MeshPrep.of(surface.full, surface.deform(nodes), center)
        k = proxy_level(surface.levels)
        proxy, scale = None, 1.0
        if k is not None:
            mesh = capped_last(surface.levels[k], surface.full)
            proxy = MeshPrep.of(mesh, surface.deform(nodes, level=k), center)
            rest = proxy.shading(mesh.vertices)[1]
            scale = surface.rest_volume / rest if rest else 1.0
        ghost = cells(np.asarray(ghost_mesh(surface).faces))
        return cls(surface, nodes, full, proxy, k, scale, ghost)

    def fits(self, surface, nodes) -> bool:
        """It was computed for ``surface`` at ``nodes``."""
        return self.surface is surface and np.array_equal(self.nodes, np.asarray(nodes))
