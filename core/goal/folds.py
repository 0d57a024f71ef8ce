"""Folds of the deformation: where the FFD turns the model inside out, and a guard against it.

The solver preserves the *signed* volume, so it can meet its target by turning part of the
model inside out: there the determinant of the FFD's Jacobian ``J = dX/dx`` is zero or
negative. This module

- measures how much of a model is folded (:class:`FoldCheck` -> :class:`Folds`), at the
  model's vertices and at points of a regular grid inside the solid (:func:`interior_points`),
  and, where no sample is folded, proves det J > 0 over the whole solid or finds the pocket
  between the samples (:mod:`.certify`);
- guards against folds (:class:`FoldGuard`): a smooth penalty on ``det J`` below a margin at
  fixed sample points, with its exact gradient with respect to the node positions.

At the rest lattice the FFD is the identity, so ``det J = 1`` everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from math import comb
from typing import cast

import numpy as np
import scipy.sparse as sp

from .. import kernels
from .. import localbasis as lb
from ..bodies import WINDING_INSIDE
from ..errors import IsochorError
from ..inside import grid_winding
from ..lattice import Lattice
from ..mesh import TriMesh
from ..springs import sparse_hessian
from ..volume import signed_volume
from .certify import Occupancy, certify, supported

#: points per block of the blocked determinant evaluation (temporaries stay in cache). A
#: process's first evaluation finds its temporaries in fresh pages: at 2048 a block the
#: fold check of the torus compression's 35k samples faulted 1045 pages instead of 1700 at
#: 4096 (5.1 against 6.3 ms; its first solve 23.1 -> 22.5 ms); warm, 3.2 against 2.9 ms
BLOCK = 2048
#: (point, node) entries per block while building the guard's basis gradients (their
#: temporaries, a few of this size, stay small enough to be reused from block to block)
GUARD_BLOCK = 1 << 16
#: the fold guard evaluates only the samples its bound leaves (:meth:`FoldGuard._candidates`)
#: while they are at most this share of all; more, and it evaluates every one, which renews
#: the bound's reference (a partial evaluation does not, so the same samples would come
#: back at every later step: on the torus stretch 0.25 took 33 partial evaluations and 11 ms
#: in the guard, 0.05 one and 8.4 ms)
PARTIAL = 0.05


def interior_points(mesh: TriMesh, count: int = 2000, budget: int = 20_000_000) -> np.ndarray:
    """Points of a regular grid strictly inside a closed mesh.

    The grid spacing is first chosen from the volume of the mesh's bounding box so that
    about ``count`` grid points (cell centres) fall in the box; those with ``|winding number|
    > 0.5`` are kept (signed ray crossings per grid column,
    :func:`isochor.core.inside.grid_winding`, whatever the mesh: several bodies, cavities,
    capped openings). A thin model (a flat torus) fills little of its box, so while fewer
    than ``count / 2`` are inside, the grid is refined (twice at most); the mesh's own
    volume over its box's predicts that share, so such a model starts on the refined grid
    (one inside test instead of two: the torus and the club fill 49 % of theirs). The
    grid never has more than ``budget / triangles`` points (the fold guard's cost grows
    with them).
    Deterministic.

    Parameters
    ----------
    mesh : a closed triangle mesh
    count : about how many points inside to aim for
    budget : most (point, triangle) pairs: the grid has at most ``budget // triangles`` points

    Returns
    -------
    (k, 3) float64, empty (0, 3) when nothing is inside (or the mesh is flat or empty)
    """
    empty = np.zeros((0, 3))
    if mesh.n_faces == 0 or count < 1:
        return empty
    lo, hi = mesh.bounds
    ext = hi - lo
    box = float(np.prod(ext))
    if not (np.isfinite(box) and box > 0):
        return empty
    most = min(int(count), int(budget) // mesh.n_faces)
    if most < 1:
        return empty
    fill = abs(signed_volume(mesh.vertices, mesh.faces)) / box  # (overlaps count twice)
    if np.isfinite(fill) and 0 < fill * most < count / 2:  # the loop below would refine
        most = min(int(budget) // mesh.n_faces, int(most * min(8.0, count / (fill * most))))
    inside = empty
    for _ in range(3):  # a thin model fills little of its box: refine until about `count`
        cells = _cells(ext, (box / most) ** (1.0 / 3.0), mesh.n_faces, budget)
        step = ext / cells
        winding = grid_winding(mesh.vertices, mesh.faces, lo, step, cells)
        axes = [lo[c] + (np.arange(cells[c]) + 0.5) * step[c] for c in range(3)]
        where = np.nonzero(np.abs(winding) > WINDING_INSIDE)
        inside = np.stack([axes[c][where[c]] for c in range(3)], axis=1)
        room = int(budget) // mesh.n_faces
        if len(inside) >= count / 2 or int(np.prod(cells)) >= room:
            break
        most = min(room, int(most * min(8.0, count / max(len(inside), 1))))
    return np.ascontiguousarray(inside)


def _cells(ext: np.ndarray, spacing: float, faces: int, budget: int) -> np.ndarray:
    """Cells per axis of a regular grid over the box, about ``spacing`` apart, with at most
    ``budget // faces`` cells."""
    cells = np.maximum(1, np.rint(ext / spacing)).astype(np.int64)
    while int(np.prod(cells)) * faces > budget:  # rounding went over the budget
        spacing *= 1.05
        cells = np.maximum(1, np.rint(ext / spacing)).astype(np.int64)
    return cells


def _bernstein_pair(degree: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bernstein polynomials of ``degree`` >= 1 and their derivatives, point-minor.

    The same values as :func:`core.lattice.bernstein` and
    :func:`core.lattice.bernstein_derivative`, transposed to ``(degree + 1, p)``; the lower
    degree is built from running powers and raised by one step of the recurrence.
    """
    s = 1.0 - t
    low_degree = degree - 1
    t_pow = [np.ones_like(t)]
    s_pow = [np.ones_like(t)]
    for _ in range(low_degree):
        t_pow.append(t_pow[-1] * t)
        s_pow.append(s_pow[-1] * s)
    low = np.stack([comb(low_degree, i) * t_pow[i] * s_pow[low_degree - i] for i in range(degree)])
    b = np.zeros((degree + 1, len(t)))
    b[:-1] = s * low
    b[1:] += t * low
    db = np.zeros((degree + 1, len(t)))
    db[1:] = low
    db[:-1] -= low
    db *= degree
    return b, db


def _parameter_bases(
    lattice: Lattice, uvw_t: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Bases ``[Bu, Bv, Bw]`` and derivatives ``[dBu, dBv, dBw]``, each ``(nodes on the axis,
    p)``, at lattice coordinates ``uvw_t`` (3, p)."""
    pairs = [_bernstein_pair(d - 1, uvw_t[c]) for c, d in enumerate(lattice.shape)]
    return [b for b, _ in pairs], [db for _, db in pairs]


def jacobian_determinants(lattice: Lattice, points: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(p,) ``det J`` of the FFD at world points: ``np.linalg.det(lattice.jacobian(points,
    nodes))``, evaluated in factored form over blocks of points (several times faster)."""
    uvw_t = np.ascontiguousarray(lattice.to_parameters(np.reshape(points, (-1, 3))).T)
    return _determinants(lattice, uvw_t, nodes)


def _determinants(lattice: Lattice, uvw_t: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """``det J`` at lattice coordinates ``uvw_t`` (3, p), blocked over points (the compiled
    kernels where they are in use, else :func:`_numpy_determinants`)."""
    l, m, n = lattice.shape
    to_world = np.linalg.inv(lattice.axes).T
    if lattice.local:
        d = lattice.displacements(nodes)
        return lb.determinants(lattice.basis, lattice.shape, uvw_t, d, to_world)
    grid = np.asarray(nodes, dtype=np.float64).reshape(l, m, n, 3)
    fast = kernels.determinants(uvw_t, grid, to_world)
    if fast is not None:
        return fast
    return _numpy_determinants(lattice, uvw_t, grid)[0]


def _numpy_determinants(
    lattice: Lattice, uvw_t: np.ndarray, grid: np.ndarray, count: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """``det J`` at lattice coordinates ``uvw_t`` (3, p) of a Bernstein lattice with nodes
    ``grid`` (l, m, n, 3), and the first ``count`` points moved by them ((3, count): the FFD
    itself, one more contraction of what det J takes; relative to where ``grid`` is).

    Per block, the three parameter derivatives ``dX/du``, ``dX/dv``, ``dX/dw`` are contracted
    axis by axis (w by a matrix product, then v, then u, each a sum of products in
    ``einsum``: no (l, m, 3, block) temporaries), point-minor throughout; the world Jacobian
    is ``J = Ju @ inv(axes).T``, so ``det J = det Ju / det axes`` (one scale at the end)."""
    l, m, n = lattice.shape
    # rows (j, i, a): the v axis leads, so that its sums run over whole leading blocks
    x_t = np.ascontiguousarray(grid.transpose(1, 0, 3, 2)).reshape(m * l * 3, n)
    p = uvw_t.shape[1]
    out = np.empty(p)
    points = np.empty((3, count))
    for s in range(0, p, BLOCK):
        (bu, bv, bw), (dbu, dbv, dbw) = _parameter_bases(lattice, uvw_t[:, s : s + BLOCK])
        width = bu.shape[1]
        y_w = (x_t @ bw).reshape(m, l, 3, width)
        y_dw = (x_t @ dbw).reshape(m, l, 3, width)
        z_v = np.einsum("jiap,jp->iap", y_w, bv)  # (l, 3, width)
        z_dv = np.einsum("jiap,jp->iap", y_w, dbv)
        z_dw = np.einsum("jiap,jp->iap", y_dw, bv)
        if s < count:
            t = min(s + width, count)
            np.einsum("iap,ip->ap", z_v[:, :, : t - s], bu[:, : t - s], out=points[:, s:t])
        c0 = np.einsum("iap,ip->ap", z_v, dbu)  # (3, width): dX/du
        c1 = np.einsum("iap,ip->ap", z_dv, bu)
        c2 = np.einsum("iap,ip->ap", z_dw, bu)
        out[s : s + width] = _triple(c0, c1, c2)
    out *= np.linalg.det(np.linalg.inv(lattice.axes))
    return out, points


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3, p) cross products of the (3, p) coordinate rows ``u`` and ``v``."""
    return np.stack(
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    )


def _triple(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(p,) ``a . (b x c)`` of the (3, p) coordinate rows: the determinant of the columns
    ``a, b, c``."""
    bc = _cross(b, c)
    return a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]


def _det3(j: np.ndarray) -> np.ndarray:
    """(p,) determinants of the coordinate-major Jacobians ``j[a, b, p]`` (3, 3, p)."""
    return _triple(j[:, 0], j[:, 1], j[:, 2])


@dataclass(frozen=True)
class Folds:
    """Where the FFD turns the model inside out (``det J <= 0``).

    Attributes
    ----------
    fraction : folded share of all samples (vertices and interior points)
    vertex_fraction : folded share of the model's vertices
    interior_fraction : folded share of the interior points, 0.0 when there are none
    min_det : smallest ``det J`` over the samples (``inf`` when there are none)
    vertices : (m,) bool, read-only: which model vertices are folded
    proven : det J > 0 over the whole solid, proven (:mod:`.certify`); False: a fold was
        found between the samples (``witness``) or the proof did not conclude; None: not
        certified (folded samples, or a lattice the proof does not cover)
    witness : (3,) a point inside the model, between the samples, where det J <= 0
    witness_det : det J at ``witness``
    """

    fraction: float
    vertex_fraction: float
    interior_fraction: float
    min_det: float
    vertices: np.ndarray
    proven: bool | None = None
    witness: tuple[float, float, float] | None = None
    witness_det: float | None = None

    def __post_init__(self) -> None:
        flags = np.array(self.vertices, dtype=bool).reshape(-1)
        flags.flags.writeable = False
        object.__setattr__(self, "vertices", flags)

    @property
    def folded(self) -> bool:
        """True when any sample is folded, or the certification found a fold between them."""
        return self.fraction > 0 or self.witness is not None

    @property
    def unproven(self) -> bool:
        """No fold found, but the absence of folds is not proven either."""
        return not self.folded and self.proven is False


class FoldCheck:
    """``det J`` over a model's vertices and interior points, for one lattice.

    Parameters
    ----------
    lattice : the FFD lattice
    vertices : (m, 3) the model's vertices
    interior : (k, 3) points inside the solid (:func:`interior_points`), may be empty
    """

    def __init__(
        self,
        lattice: Lattice,
        vertices: np.ndarray,
        interior: np.ndarray,
        faces: np.ndarray | None = None,
        vertex_parameters: np.ndarray | None = None,
    ) -> None:
        self.lattice = lattice
        vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
        #: where the solid is, for the proof (:mod:`.certify`); needs the faces
        self._occupancy = (
            Occupancy(lattice, vertices, faces)
            if faces is not None and supported(lattice)
            else None
        )
        interior = np.asarray(interior, dtype=np.float64).reshape(-1, 3)
        self.n_vertices, self.n_interior = len(vertices), len(interior)
        if vertex_parameters is None:  # (3, m) the vertices' lattice coordinates, when known
            vertex_parameters = lattice.to_parameters(vertices).T
        inside = lattice.to_parameters(interior).T
        self._uvw_t = np.ascontiguousarray(np.concatenate([vertex_parameters, inside], axis=1))
        #: the last nodes measured and det J there (:meth:`survey` fills it too)
        self._last: tuple[bytes, np.ndarray] | None = None

    def determinants(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``det J`` at node positions ``nodes`` (nodes, 3).

        Returns
        -------
        (m,) at the vertices, (k,) at the interior points
        """
        key = np.asarray(nodes, dtype=np.float64).tobytes()
        last = self._last  # one tuple: another thread may replace it, never half of it
        if last is not None and last[0] == key:
            dets = last[1]
        else:
            dets = _determinants(self.lattice, self._uvw_t, nodes)
            dets.flags.writeable = False  # kept, and handed out in views
            self._last = (key, dets)
        return dets[: self.n_vertices], dets[self.n_vertices :]

    @property
    def parameters(self) -> np.ndarray:
        """(3, m + k) the samples' lattice coordinates, the vertices' first (read-only)."""
        view = self._uvw_t.view()
        view.flags.writeable = False
        return view

    def refresh(self, nodes: np.ndarray, base: np.ndarray, rows: np.ndarray) -> None:
        """Make det J at ``nodes`` known (for :meth:`determinants` and :meth:`measure`) from
        ``base``, det J at every sample at other nodes that differ from ``nodes`` only in
        nodes whose windows hold the samples ``rows`` alone: those are evaluated again,
        the rest taken as they are (a local release, :mod:`isochor.core.solve.local`)."""
        dets = np.array(base, dtype=np.float64)
        rows = np.asarray(rows, dtype=np.intp)
        if len(rows):
            uvw = np.ascontiguousarray(self._uvw_t[:, rows])
            dets[rows] = _determinants(self.lattice, uvw, nodes)
        dets.flags.writeable = False
        self._last = (np.asarray(nodes, dtype=np.float64).tobytes(), dets)

    def survey(self, nodes: np.ndarray, center: np.ndarray) -> np.ndarray | None:
        """The model's vertices moved by ``nodes``, relative to ``center`` ((3, m)), from the
        pass that finds det J at every sample (kept for :meth:`determinants` and
        :meth:`measure` at the same nodes): on the NumPy path of a Bernstein lattice, where
        the points cost one more contraction of the same bases (the full mesh's volume
        without a pass of its own). None elsewhere: nothing is computed."""
        if self.lattice.local or kernels.active():
            return None
        x = np.asarray(nodes, dtype=np.float64).reshape(self.lattice.n_nodes, 3)
        grid = (x - center).reshape(*self.lattice.shape, 3)  # det J does not see the shift
        dets, points = _numpy_determinants(self.lattice, self._uvw_t, grid, self.n_vertices)
        dets.flags.writeable = False
        self._last = (x.tobytes(), dets)
        return points

    def measure(self, nodes: np.ndarray) -> Folds:
        """How much of the model the FFD with node positions ``nodes`` turns inside out."""
        at_vertices, inside = self.determinants(nodes)
        folded_vertices = at_vertices <= 0
        n_folded_vertices = int(np.count_nonzero(folded_vertices))
        n_folded_inside = int(np.count_nonzero(inside <= 0))
        total = self.n_vertices + self.n_interior
        every = np.concatenate([at_vertices, inside])
        folds = Folds(
            fraction=(n_folded_vertices + n_folded_inside) / total if total else 0.0,
            vertex_fraction=n_folded_vertices / self.n_vertices if self.n_vertices else 0.0,
            interior_fraction=n_folded_inside / self.n_interior if self.n_interior else 0.0,
            min_det=float(every.min()) if total else float("inf"),
            vertices=folded_vertices,
        )
        if folds.folded or self._occupancy is None:
            return folds
        # no sample folded: prove it between them, or find the pocket they missed
        proof = certify(self.lattice, nodes, self._occupancy)
        witness = (
            None
            if proof.witness is None
            else cast("tuple[float, float, float]", tuple(map(float, proof.witness)))
        )
        return replace(
            folds,
            proven=proof.proven,
            witness=witness,
            witness_det=None if witness is None else proof.witness_det,
            min_det=min(folds.min_det, proof.witness_det) if witness else folds.min_det,
        )


class SparseGradients:
    """A local basis's world gradients at fixed samples, sparse: ``G_b`` (k, nodes) CSR for
    b = x, y, z, each row the 64 entries of a sample's window (composed with the "Outside"
    map), and the constant ``offset`` (3, k, 3) so that column b of ``J_p`` is
    ``G_b[p] @ X + offset[b, p]`` (the identity minus the rest nodes' share)."""

    def __init__(self, lattice: Lattice, uvw_t: np.ndarray) -> None:
        inv = np.linalg.inv(lattice.axes)  # du_c / dx_b = inv[b, c]
        rows, _, deriv = lb.windows(lattice.basis, lattice.shape, uvw_t)
        k = rows.shape[0]
        indptr = np.arange(0, 64 * k + 1, 64)
        outside = lattice.outside_map
        self.g = []
        for b in range(3):
            data = inv[b, 0] * deriv[0] + inv[b, 1] * deriv[1] + inv[b, 2] * deriv[2]
            g = sp.csr_matrix((data.ravel(), rows.ravel(), indptr), shape=(k, lattice.n_nodes))
            self.g.append((g @ outside).tocsr() if outside is not None else g)
        rest = lattice.rest_nodes
        self.offset = np.stack([np.eye(3)[b] - self.g[b] @ rest for b in range(3)])

    @property
    def nbytes(self) -> int:
        return int(sum(g.data.nbytes + g.indices.nbytes + g.indptr.nbytes for g in self.g))

    def reach(self) -> np.ndarray:
        """(3, nodes) the largest ``|d w_node / dx_b|`` over the samples, per axis b."""
        return np.stack([np.asarray(abs(g).max(axis=0).todense()).ravel() for g in self.g])

    def columns(self, x: np.ndarray, rows=slice(None)) -> np.ndarray:
        """(3, a, 3) columns of the Jacobians at the samples ``rows``."""
        return np.stack([self.g[b][rows] @ x + self.offset[b, rows] for b in range(3)])

    def gradient(self, w: np.ndarray, rows) -> np.ndarray:
        """(nodes, 3) ``sum_b G_b[rows]^T w[b]`` for ``w`` (3, a, 3)."""
        return sum(self.g[b][rows].T @ w[b] for b in range(3))

    def det_rows(self, cof: np.ndarray, rows) -> sp.csr_matrix:
        """(a, 3 nodes) sparse ``grad det_p`` over (node, axis) at the samples ``rows``."""
        parts = []
        for axis in range(3):
            part = sum(sp.diags(cof[b, :, axis]) @ self.g[b][rows] for b in range(3)).tocoo()
            parts.append((part.row, part.col * 3 + axis, part.data))
        r, c, v = (np.concatenate(t) for t in zip(*parts))
        a = len(cof[0])
        return sp.csr_matrix((v, (r, c)), shape=(a, 3 * self.g[0].shape[1]))


def by_cell(shape: tuple[int, int, int], uvw_t: np.ndarray) -> np.ndarray:
    """(p,) the order of the points at lattice coordinates ``uvw_t`` (3, p) that visits a
    local basis's lattice cell by cell (u slowest, as the nodes are stored): consecutive
    points then share their 4x4x4 window of nodes (det J of the 16^3 lattice's windows 1.5x
    faster than in a mesh's own order)."""
    cell = [np.clip(np.floor(uvw_t[a] * max(c - 1, 1)), -1, c) for a, c in enumerate(shape)]
    return np.lexsort((cell[2], cell[1], cell[0]))


class FoldGuard:
    """A penalty that keeps ``det J`` above a margin at fixed sample points.

    ``P(X) = weight / k * sum_p max(0, margin - det J_p(X))**3``: a cubic hinge, twice
    continuously differentiable and zero wherever ``det J >= margin``.

    The world-space gradients of every node's basis function at the k sample points are
    precomputed: ``G[node, b, p] = dB_node(x_p) / dx_b`` (memory ``3 * k * nodes`` float64, 72
    MB for 3000 points and 1000 nodes), so that ``X^T G`` is every sample's Jacobian at once,
    coordinate-major (``J[a, b, p]``: each entry a contiguous row over the samples, which the
    determinant, the column lengths and the cofactors read as whole rows: a full evaluation
    of the torus examples' 2500 samples took 0.10 ms instead of 0.18 sample-major), and
    ``dP/dX[node, a] = sum_p sum_b phi'(det_p) cof_p[a, b] G[node, b, p]``, two matrix
    products per evaluation, over the samples within the margin only: det J at every
    sample comes from the compiled kernels when they are ready (the NumPy path takes it
    from ``G`` too). Samples that a bound from the last full evaluation proves above the
    margin are not evaluated at all (:meth:`_candidates`; usually every one). A local basis
    keeps ``G`` sparse (:class:`SparseGradients`: 64 nodes per sample), and its Gauss-Newton
    term is sparse too above :data:`core.springs.SPARSE_VARIABLES` node coordinates.

    Parameters
    ----------
    lattice : the FFD lattice
    points : (k, 3) world sample points (rest positions)
    margin : the smallest ``det J`` that costs nothing (1 is the rest value)
    weight : scale of the penalty, >= 0
    """

    def __init__(self, lattice: Lattice, points: np.ndarray, margin: float, weight: float) -> None:
        if not np.isfinite(margin):
            raise IsochorError(f"The fold margin must be a finite number, got {margin}.")
        if not (np.isfinite(weight) and weight >= 0):
            raise IsochorError(f"The fold weight must be finite and >= 0, got {weight}.")
        self.lattice = lattice
        self.margin, self.weight = float(margin), float(weight)
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self.n_points = k = len(points)
        nodes = lattice.n_nodes
        inv = np.linalg.inv(lattice.axes)  # du_c / dx_b = inv[b, c]
        uvw_t = lattice.to_parameters(points).T
        #: a local basis's samples are kept by cell (each cell's 4x4x4 nodes read once,
        #: from the cache): where each of the given points went, else None
        self._place = None
        if lattice.local and k:
            order = by_cell(lattice.shape, uvw_t)
            uvw_t = uvw_t[:, order]
            self._place = np.empty(k, dtype=np.intp)
            self._place[order] = np.arange(k)
        uvw_t = np.ascontiguousarray(uvw_t)
        #: (3, k, 3) the samples' lattice coordinates and inv(axes).T: det J by the kernels
        self._uvw_t, self._to_world = uvw_t, inv.T
        #: the last full evaluation (see :meth:`_candidates`): its nodes, each sample's
        #: det J - margin, a bound on each sample's column lengths of J ((3, k), or (1, k)
        #: for all three), their least and largest values
        self._ref: tuple | None = None
        #: a local basis's sparse gradients (None: Bernstein's dense ``_g``)
        self._sparse = SparseGradients(lattice, uvw_t) if lattice.local else None
        if self._sparse is not None:
            self._g = np.zeros((0, 3, 0))
            self._reach = self._sparse.reach() if k else np.zeros((3, nodes))
            return
        #: (nodes, 3, k) ``G`` (see the class)
        self._g = g = np.empty((nodes, 3, k))
        #: (3, nodes) the largest |dB_node / dx_b| over the samples (see :meth:`_candidates`)
        self._reach = reach = np.zeros((3, nodes))
        step = max(1, GUARD_BLOCK // nodes)
        for s in range(0, k, step):
            (bu, bv, bw), (dbu, dbv, dbw) = _parameter_bases(lattice, uvw_t[:, s : s + step])
            width = bu.shape[1]
            d = [
                (x[:, None, None] * y[None, :, None] * z[None, None, :]).reshape(nodes, width)
                for x, y, z in ((dbu, bv, bw), (bu, dbv, bw), (bu, bv, dbw))
            ]
            for b in range(3):
                block = inv[b, 0] * d[0] + inv[b, 1] * d[1] + inv[b, 2] * d[2]
                g[:, b, s : s + width] = block
                np.maximum(reach[b], np.abs(block, out=block).max(axis=1), out=reach[b])

    @property
    def nbytes(self) -> int:
        """Memory held by the precomputed basis gradients, in bytes."""
        return int(self._g.nbytes if self._sparse is None else self._sparse.nbytes)

    def _columns(self, nodes: np.ndarray, rows=slice(None)) -> np.ndarray:
        """(3, 3, k) the Jacobians (at the samples ``rows``), coordinate-major:
        ``out[a, b, p] = J_p[a, b]`` (column b of ``J_p`` is ``out[:, b, p]``)."""
        x = np.asarray(nodes, dtype=np.float64).reshape(self.lattice.n_nodes, 3)
        if self._sparse is not None:
            return self._sparse.columns(x, rows).transpose(2, 0, 1)
        g = self._g if isinstance(rows, slice) and rows == slice(None) else self._g[:, :, rows]
        # (G^T X)[(b, p), a] by rows of G^T: each sample's numbers are the same whichever
        # samples are evaluated with it (a partial evaluation's; X^T G rounds by position)
        cols = g.reshape(len(x), -1).T @ x
        return np.ascontiguousarray(cols.reshape(3, -1, 3).transpose(2, 0, 1))

    def determinants(self, nodes: np.ndarray) -> np.ndarray:
        """(k,) ``det J`` at the sample points (in the order given) for node positions
        ``nodes`` (nodes, 3)."""
        dets = self._evaluate(nodes)[0]
        return dets if self._place is None else dets[self._place]

    def _candidates(self, nodes: np.ndarray) -> np.ndarray | None:
        """The samples that may be within the margin at ``nodes``, proven from the last full
        evaluation (every other one is above it, so its penalty and derivatives are exactly
        zero, unevaluated); None: no full evaluation to prove it from.

        ``J_p`` moves by ``D_p = sum_n grad B_n(p) d_n^T`` for node moves ``d_n``: its
        column b by ``sum_n dB_n(p)/dx_b d_n``, at most ``e_b = |sum_n reach[b, n] |d_n||``
        long (``|d_n|`` taken per coordinate). det is multilinear in the columns and
        ``|det [a b c]| <= |a| |b| |c|`` (Hadamard), so with ``L_b`` the columns' lengths at
        the evaluation, ``|det(J_p + D_p) - det J_p| <= prod_b (L_b + e_b) - prod_b L_b``,
        which grows with each ``L_b``. A sample whose slack ``det J_p - margin`` exceeds
        that bound stays above the margin. The test runs once over all samples with the
        largest lengths and the least slack (the usual case: none can be near), and only
        where that fails sample by sample."""
        ref = self._ref  # one tuple: another thread may replace it, never half of it
        if ref is None:
            return None
        x0, slack, lengths, least, longest = ref
        moved = self._reach @ np.abs(nodes - x0)  # (3, 3): axis b of J, coordinate
        e0, e1, e2 = np.sqrt(np.einsum("ij,ij->i", moved, moved)).tolist()
        l0, l1, l2 = longest
        if (l0 + e0) * (l1 + e1) * (l2 + e2) - l0 * l1 * l2 < least:
            return np.zeros(0, dtype=np.intp)  # the usual case: nowhere near a fold
        a, b, c = lengths if len(lengths) == 3 else (lengths[0],) * 3
        # prod (L_b + e_b) - prod L_b, expanded: no cancellation of the lengths' product
        bound = e0 * (b + e1) * (c + e2) + a * (e1 * (c + e2) + b * e2)
        return np.flatnonzero(bound >= slack)

    def _evaluate(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """det J at every sample, and the columns of J where the NumPy path made them
        ((3, k, 3), as :meth:`_columns`; None from the kernels); remembers, for
        :meth:`_candidates`, each sample's slack and a bound on its columns' lengths. The
        compiled kernels evaluate the Bernstein polynomials per sample
        (:func:`isochor.core.kernels.determinants`, with ``|J|_F``, which bounds every
        column); the NumPy path multiplies the stored basis gradients (``3 k nodes``
        numbers read each time) and measures each column."""
        x = np.array(nodes, dtype=np.float64).reshape(self.lattice.n_nodes, 3)
        fast = self._compiled(x, self._uvw_t, frobenius=True)
        cols = None
        if fast is not None:
            dets, squares = fast
            squares = squares[None]
        else:
            cols = self._columns(x)
            dets = _det3(cols)
            squares = cols[0] * cols[0] + cols[1] * cols[1] + cols[2] * cols[2]  # (b, k)
        if self.n_points:
            lengths = np.sqrt(squares)
            slack = dets - self.margin
            longest = lengths.max(axis=1)
            longest = tuple(float(v) for v in (longest if len(longest) == 3 else [longest[0]] * 3))
            self._ref = (x, slack, lengths, float(slack.min()), longest)
        return dets, cols

    def _compiled(self, x: np.ndarray, uvw_t: np.ndarray, frobenius: bool = False):
        """det J (and ``|J|_F^2`` with ``frobenius``) at lattice coordinates ``uvw_t`` by
        the compiled kernels; None where they are not ready."""
        lat = self.lattice
        if lat.local:
            return kernels.local_determinants(
                uvw_t,
                lb.codes(lat.basis),
                lat.displacements(x),
                lat.shape,
                self._to_world,
                frobenius=frobenius,
            )
        grid = x.reshape(*lat.shape, 3)
        return kernels.determinants(uvw_t, grid, self._to_world, frobenius=frobenius)

    def _determinants_at(self, nodes: np.ndarray, rows: np.ndarray):
        """det J at the samples ``rows`` only, the same numbers as :meth:`_evaluate` there,
        and their columns (None from the kernels)."""
        x = np.asarray(nodes, dtype=np.float64).reshape(self.lattice.n_nodes, 3)
        fast = self._compiled(x, np.ascontiguousarray(self._uvw_t[:, rows]))
        if fast is not None:
            return fast, None
        cols = self._columns(x, rows)
        return _det3(cols), cols

    def _near(self, nodes: np.ndarray):
        """``(short, active, cof)`` at the samples within the margin: how far each is below
        it, which they are, and the cofactors of their J (``cof[b, a, p] = d det_p / d J_p[a,
        b]``, (3, 3, a)); None where none is (or the guard is off). Only the samples
        :meth:`_candidates` leaves are evaluated, all of them (a full evaluation, which the
        next proofs start from) when there are many."""
        if self.n_points == 0 or self.weight == 0:
            return None
        nodes = np.asarray(nodes, dtype=np.float64).reshape(self.lattice.n_nodes, 3)
        rows = self._candidates(nodes)
        if rows is not None and rows.size == 0:  # provably nowhere near a fold
            return None
        if rows is None or rows.size > PARTIAL * self.n_points:
            rows = slice(None)
            dets, cols = self._evaluate(nodes)
        else:
            dets, cols = self._determinants_at(nodes, rows)
        below = self.margin - dets
        within = np.flatnonzero(below > 0)
        if within.size == 0:  # nowhere near a fold after all
            return None
        short = below[within]
        active = within if isinstance(rows, slice) else rows[within]
        # the Jacobians the determinants came from (the kernels make none: made here)
        if cols is None:
            cols = self._columns(nodes, active)
        elif within.size != len(dets):
            cols = cols[:, :, within]
        # cof[b, a] = d det / d J[a, b]: column b's is the cross product of the other two
        pairs = ((1, 2), (2, 0), (0, 1))
        cof = np.stack([_cross(cols[:, i], cols[:, j]) for i, j in pairs])
        return short, active, cof

    def value_and_gradient(self, nodes: np.ndarray) -> tuple[float, np.ndarray]:
        """The penalty and its exact gradient with respect to the node positions.

        Returns
        -------
        (value, (nodes, 3) gradient)
        """
        k = self.n_points
        grad = np.zeros((self.lattice.n_nodes, 3))
        near = self._near(nodes)
        if near is None:
            return 0.0, grad
        short, active, cof = near
        scale = self.weight / k
        value = scale * float(np.sum(short**3))
        slope = -3.0 * scale * short**2  # phi'(det) at the active points
        w = (slope * cof).transpose(0, 2, 1)  # (b, p, a): phi' d det_p / d J_p[a, b]
        if self._sparse is not None:
            grad += self._sparse.gradient(w, active)
            return value, grad
        g = self._g if active.size == k else self._g[:, :, active]
        # grad[node, a] = sum_b sum_p G[node, b, p] w[b, p, a]
        grad += g.reshape(len(grad), -1) @ w.reshape(-1, 3)
        return value, grad

    def gauss_newton(self, nodes: np.ndarray) -> np.ndarray:
        """``(3 nodes, 3 nodes)``: the penalty's Hessian without the determinants' own
        curvature, ``sum_p phi''(det_p) grad det_p grad det_p^T`` over the points within the
        margin (positive semi-definite; zero when nowhere near a fold). For the solver's
        preconditioner (:mod:`isochor.core.solve.precondition`)."""
        n = 3 * self.lattice.n_nodes
        near = self._near(nodes)
        big = sparse_hessian(self.lattice.n_nodes)
        if near is None:
            return sp.csr_matrix((n, n)) if big else np.zeros((n, n))
        short, active, cof = near
        if self._sparse is not None:
            rows = self._sparse.det_rows(cof.transpose(0, 2, 1), active)
            curvature = 6.0 * self.weight / self.n_points * short
            out = (rows.T @ sp.diags(curvature) @ rows).tocsr()
            return out if big else out.toarray()
        # grad det_p over (node, axis a): sum_b G[node, b, p] cof[b, a, p]
        rows = np.einsum("nbp,bap->pna", self._g[:, :, active], cof).reshape(active.size, n)
        curvature = 6.0 * self.weight / self.n_points * short  # phi''(det)
        return rows.T @ (curvature[:, None] * rows)
