"""Blender's lattice as a lattice basis: per-axis Linear, Cardinal, Catmull-Rom and B-spline.

Blender's Lattice modifier (``BKE_lattice_deform_data_create`` and
``BKE_lattice_deform_data_eval_co`` in ``lattice_deform.cc``) does not blend node
positions as the paper's Bernstein FFD does; it blends their *displacements* from the rest
grid. Along an axis with ``count`` nodes a point's lattice coordinate ``u`` (0..1 over the
box) is ``t = u (count - 1)`` node spacings from the first node; with ``f = t - floor(t)``
the four weights ``key_curve_position_weights(f)`` (``key.cc``) go to the nodes
``floor(t) - 1 .. floor(t) + 2``, each index clamped to ``0 .. count - 1``. The deformed
point is

    x(p) = p + sum_ijk wu_i(p) wv_j(p) ww_k(p) (P_ijk - R_ijk)

with ``R`` the rest grid: linear in the nodes plus a per-point offset, and each point
depends on at most 4 x 4 x 4 nodes. A point outside the box gets weights past the last
node, clamped: far outside it moves with the displacement of the nearest face of the
lattice, as in Blender. An axis with one node (Blender allows it) gives that node the whole
weight, its rest position in the middle of the box.

The four weights at ``f`` (``key_curve_position_weights``):

- ``linear``       ``0, 1 - f, f, 0``
- ``cardinal``     the cardinal cubic with tension ``fc = 0.71``
- ``catmull-rom``  the same with ``fc = 0.5``
- ``bspline``      the uniform cubic B-spline (``(1 - f)^3 / 6`` ...)

Blender writes the B-spline's 1/6 and 2/3 as the float constants ``0.16666666f`` and
``0.66666666f`` and evaluates in single precision; this module takes the exact fractions in
float64 (the weights then sum to 1 exactly; the two differ by less than 3e-8).

Blender's "Outside" option (``outside_lattice`` in ``lattice.cc``) derives every inner node
from the six faces: the mean over the three axes of the linear blend between the two face
nodes on its row. :func:`outside_matrix` is that map; a lattice with ``outside`` applies it
to the nodes before the displacements are taken.

:class:`LocalPointBasis` is the local counterpart of :class:`core.lattice.PointBasis`:
compiled kernels (:mod:`core.kernels.local`) evaluate the windows per point; the NumPy path
builds sparse matrices of the 64 weights per point (kept for small point sets, made block
by block for large ones).
"""

from __future__ import annotations

from typing import cast

import numpy as np
import scipy.sparse as sp

from . import kernels

#: the local bases, in the order of their codes in the compiled kernels
KINDS = ("linear", "cardinal", "catmull-rom", "bspline")
#: the paper's basis, the default
BERNSTEIN = "bernstein"
#: every basis name a lattice axis accepts
NAMES = (BERNSTEIN, *KINDS)
#: Blender's tension of the cardinal spline and of Catmull-Rom (``key_curve_position_weights``)
TENSION = {"cardinal": 0.71, "catmull-rom": 0.5}
#: nodes per axis a local basis allows (Blender's range)
MIN_LOCAL, MAX_LOCAL = 1, 64
#: up to this many (point, weight) entries the NumPy path keeps its sparse matrix
KEEP_ENTRIES = 4_000_000
#: points per block of the NumPy path's products
BLOCK = 1 << 13


def codes(kinds: tuple[str, str, str]) -> np.ndarray:
    """(3,) int64 the kernels' codes of the three axes' bases."""
    return np.array([KINDS.index(k) for k in kinds], dtype=np.int64)


def key_weights(kind: str, f: np.ndarray) -> np.ndarray:
    """(p, 4) Blender's ``key_curve_position_weights`` at fractions ``f`` (p,) in [0, 1)."""
    f = np.asarray(f, dtype=np.float64)
    out = np.empty((len(f), 4))
    if kind == "linear":
        out[:, 0] = 0.0
        out[:, 1] = 1.0 - f
        out[:, 2] = f
        out[:, 3] = 0.0
        return out
    f2 = f * f
    f3 = f2 * f
    if kind == "bspline":
        out[:, 0] = -f3 / 6.0 + 0.5 * f2 - 0.5 * f + 1.0 / 6.0
        out[:, 1] = 0.5 * f3 - f2 + 2.0 / 3.0
        out[:, 2] = -0.5 * f3 + 0.5 * f2 + 0.5 * f + 1.0 / 6.0
        out[:, 3] = f3 / 6.0
        return out
    fc = TENSION[kind]
    out[:, 0] = -fc * f3 + 2.0 * fc * f2 - fc * f
    out[:, 1] = (2.0 - fc) * f3 + (fc - 3.0) * f2 + 1.0
    out[:, 2] = (fc - 2.0) * f3 + (3.0 - 2.0 * fc) * f2 + fc * f
    out[:, 3] = fc * f3 - fc * f2
    return out


def key_derivatives(kind: str, f: np.ndarray) -> np.ndarray:
    """(p, 4) d/df of :func:`key_weights`."""
    f = np.asarray(f, dtype=np.float64)
    out = np.empty((len(f), 4))
    if kind == "linear":
        out[:] = (0.0, -1.0, 1.0, 0.0)
        return out
    f2 = f * f
    if kind == "bspline":
        out[:, 0] = -0.5 * f2 + f - 0.5
        out[:, 1] = 1.5 * f2 - 2.0 * f
        out[:, 2] = -1.5 * f2 + f + 0.5
        out[:, 3] = 0.5 * f2
        return out
    fc = TENSION[kind]
    out[:, 0] = -3.0 * fc * f2 + 4.0 * fc * f - fc
    out[:, 1] = 3.0 * (2.0 - fc) * f2 + 2.0 * (fc - 3.0) * f
    out[:, 2] = 3.0 * (fc - 2.0) * f2 + 2.0 * (3.0 - 2.0 * fc) * f + fc
    out[:, 3] = 3.0 * fc * f2 - 2.0 * fc * f
    return out


def axis_window(kind: str, count: int, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One axis's window at lattice coordinates ``u`` (p,): node indices (p, 4) int64
    (clamped to the axis), weights (p, 4) and their derivatives d/du (p, 4)."""
    u = np.asarray(u, dtype=np.float64)
    p = len(u)
    if count == 1:
        weights = np.zeros((p, 4))
        weights[:, 1] = 1.0
        return np.zeros((p, 4), dtype=np.int64), weights, np.zeros((p, 4))
    t = u * (count - 1)
    low = np.floor(t)
    f = t - low
    index = np.clip(low.astype(np.int64)[:, None] - 1 + np.arange(4), 0, count - 1)
    return index, key_weights(kind, f), key_derivatives(kind, f) * (count - 1)


def windows(
    kinds: tuple[str, str, str], shape: tuple[int, int, int], uvw_t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 64 (node, weight) pairs of each point at lattice coordinates ``uvw_t`` (3, p):
    node rows (p, 64) int64 (Isochor's order, a node may repeat at the edges), weights
    (p, 64) and their derivatives (3, p, 64) along u, v and w."""
    l, m, n = shape
    (iu, wu, du), (iv, wv, dv), (iw, ww, dw) = (
        axis_window(k, c, uvw_t[a]) for a, (k, c) in enumerate(zip(kinds, shape))
    )
    p = uvw_t.shape[1]
    rows = ((iu[:, :, None, None] * m + iv[:, None, :, None]) * n + iw[:, None, None, :]).reshape(
        p, 64
    )

    def outer(a, b, c):
        return (a[:, :, None, None] * b[:, None, :, None] * c[:, None, None, :]).reshape(p, 64)

    weights = outer(wu, wv, ww)
    derivatives = np.stack([outer(du, wv, ww), outer(wu, dv, ww), outer(wu, wv, dw)])
    return rows, weights, derivatives


def weight_matrix(
    kinds: tuple[str, str, str], shape: tuple[int, int, int], uvw_t: np.ndarray
) -> sp.csr_matrix:
    """(p, nodes) sparse: the weights of the points at lattice coordinates ``uvw_t`` (3, p)."""
    rows, weights, _ = windows(kinds, shape, uvw_t)
    p = rows.shape[0]
    return sp.csr_matrix(
        (weights.ravel(), rows.ravel(), np.arange(0, 64 * p + 1, 64)),
        shape=(p, int(np.prod(shape))),
    )


def outside_matrix(shape: tuple[int, int, int]) -> sp.csr_matrix:
    """(nodes, nodes) sparse: Blender's "Outside" map (``outside_lattice``): the nodes on the
    lattice's faces stay, each inner node becomes the mean over the three axes of the
    linear blend between the two face nodes on its row."""
    l, m, n = shape
    index = np.arange(l * m * n).reshape(l, m, n)
    i, j, k = (a.ravel() for a in np.indices(shape))
    inner = (i > 0) & (j > 0) & (k > 0) & (i < l - 1) & (j < m - 1) & (k < n - 1)
    rows, cols, vals = [np.flatnonzero(~inner)], [np.flatnonzero(~inner)], [np.ones((~inner).sum())]
    i, j, k = i[inner], j[inner], k[inner]
    at = np.flatnonzero(inner)
    for a, (c, count) in enumerate(zip((i, j, k), shape)):
        f = c / (count - 1)
        for end, weight in ((0, 1.0 - f), (count - 1, f)):
            ijk = [i, j, k]
            ijk[a] = np.full_like(c, end)
            rows.append(at)
            cols.append(index[ijk[0], ijk[1], ijk[2]])
            vals.append(weight / 3.0)
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(l * m * n, l * m * n),
    )


def blender_order(shape: tuple[int, int, int]) -> np.ndarray:
    """(nodes,) Isochor's node rows in Blender's point order: ``nodes[blender_order(shape)]``
    lists the points as Blender's lattice does (u fastest: ``(w * pntsv + v) * pntsu + u``),
    and ``nodes[blender_order(shape)] = points`` reads them back."""
    return np.arange(int(np.prod(shape))).reshape(shape).transpose(2, 1, 0).ravel()


def blender_frame(matrix, low=(-0.5, -0.5, -0.5), high=(0.5, 0.5, 0.5)):
    """``(origin, axes)``: Isochor's lattice frame for a Blender lattice object whose
    ``object_to_world`` is ``matrix`` (4x4) and whose rest points span ``low .. high`` in
    its lattice space (-0.5 .. 0.5, Blender's ``fu`` to ``fu + (pnts - 1) du``, once the
    lattice was resized with its object; an axis with one point keeps the unit extent).
    World positions of the nodes then equal ``matrix`` applied to Blender's points."""
    m = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    flat = high - low == 0
    low, high = np.where(flat, low - 0.5, low), np.where(flat, high + 0.5, high)
    origin = m[:3, :3] @ low + m[:3, 3]
    axes = (m[:3, :3] * (high - low)).T  # rows: the edge vectors along u, v, w
    return origin, axes


class LocalPointBasis:
    """The local basis of a fixed point set: ``apply(X) = points + W (T X - T R)``.

    ``W`` (points, nodes) holds each point's 64 weights, ``R`` the rest nodes and ``T`` the
    "Outside" map (the identity without it). The same interface as
    :class:`core.lattice.PointBasis`: :meth:`apply` returns a Fortran-ordered view of a
    ``(3, p)`` array, :meth:`apply_transpose` takes one (``W^T`` then ``T^T``: the derivative
    of :meth:`apply` with respect to the nodes). The compiled kernels evaluate the windows
    per point from ``uvw``; the NumPy path uses :func:`weight_matrix` (kept up to
    :data:`KEEP_ENTRIES` entries, else made per block of points).
    """

    def __init__(
        self,
        uvw: np.ndarray,
        points: np.ndarray,
        shape: tuple[int, int, int],
        kinds: tuple[str, str, str],
        rest: np.ndarray,
        outside: sp.csr_matrix | None = None,
    ) -> None:
        uvw = np.asarray(uvw, dtype=np.float64).reshape(-1, 3)
        self.shape = cast("tuple[int, int, int]", tuple(int(d) for d in shape))
        self.kinds = cast("tuple[str, str, str]", tuple(kinds))
        self.codes = codes(self.kinds)
        self.n_points = len(uvw)
        #: (3, p) lattice coordinates and world positions, what the kernels read
        self.uvw = np.ascontiguousarray(uvw.T)
        self.points = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3).T)
        self.outside = outside
        self.rest = np.ascontiguousarray(self._mapped(np.asarray(rest, dtype=np.float64)))
        self._matrix: sp.csr_matrix | None = None

    def _mapped(self, nodes: np.ndarray) -> np.ndarray:
        return nodes if self.outside is None else self.outside @ nodes

    @property
    def matrix(self) -> sp.csr_matrix | None:
        """(p, nodes) the weights as a sparse matrix when the point set is small enough to
        keep it (see the class), else None."""
        if self._matrix is None and 64 * self.n_points <= KEEP_ENTRIES:
            self._matrix = weight_matrix(self.kinds, self.shape, self.uvw)
        return self._matrix

    @property
    def nbytes(self) -> int:
        held = [self.uvw, self.points]
        if self._matrix is not None:
            m = self._matrix
            held += [m.data, m.indices, m.indptr]
        return int(sum(a.nbytes for a in held))

    def displacements(self, nodes: np.ndarray) -> np.ndarray:
        """(nodes, 3) what the weights blend: ``T X - T R``."""
        return self._mapped(np.asarray(nodes, dtype=np.float64)) - self.rest

    def _blocks(self):
        """(start, stop, weights (stop - start, nodes)) over the points."""
        kept = self.matrix
        if kept is not None:
            yield 0, self.n_points, kept
            return
        for s in range(0, self.n_points, BLOCK):
            t = min(s + BLOCK, self.n_points)
            yield s, t, weight_matrix(self.kinds, self.shape, self.uvw[:, s:t])

    def apply(self, nodes: np.ndarray) -> np.ndarray:
        """Deformed points ``(p, 3)`` for node positions ``(nodes, 3)``."""
        d = np.ascontiguousarray(self.displacements(nodes))
        out = kernels.local_apply(self.uvw, self.points, self.codes, d, self.shape)
        if out is not None:
            return out.T
        out = self.points.copy()
        for s, t, w in self._blocks():
            out[:, s:t] += (w @ d).T
        return out.T

    def apply_transpose(self, point_values: np.ndarray) -> np.ndarray:
        """Chain rule: per-point ``(p, 3)`` -> per-node ``(nodes, 3)``."""
        v = np.asarray(point_values, dtype=np.float64).T  # (3, p)
        out = kernels.local_transpose(self.uvw, self.codes, v, self.shape)
        if out is None:
            out = np.zeros((int(np.prod(self.shape)), 3))
            for s, t, w in self._blocks():
                out += w.T @ np.ascontiguousarray(v[:, s:t].T)
        if self.outside is not None:
            out = self.outside.T @ out
        return np.ascontiguousarray(out)


def jacobian_columns(
    kinds: tuple[str, str, str],
    shape: tuple[int, int, int],
    uvw_t: np.ndarray,
    displacements: np.ndarray,
) -> np.ndarray:
    """(3, p, 3) the parameter derivatives of the displacement field: ``out[e, p, a] =
    d(sum_i w_i D_i)_a / du_e`` at lattice coordinates ``uvw_t`` (3, p)."""
    rows, _, deriv = windows(kinds, shape, uvw_t)
    d = np.asarray(displacements, dtype=np.float64)
    gathered = d[rows]  # (p, 64, 3)
    return np.einsum("epk,pka->epa", deriv, gathered)


def determinants(
    kinds: tuple[str, str, str],
    shape: tuple[int, int, int],
    uvw_t: np.ndarray,
    displacements: np.ndarray,
    to_world: np.ndarray,
) -> np.ndarray:
    """(p,) det J of ``x + sum_i w_i(x) D_i`` at lattice coordinates ``uvw_t`` (3, p);
    ``to_world`` is ``inv(axes).T``."""
    fast = kernels.local_determinants(
        uvw_t, codes(kinds), np.ascontiguousarray(displacements, dtype=np.float64), shape, to_world
    )
    if fast is not None:
        return fast
    p = uvw_t.shape[1]
    out = np.empty(p)
    for s in range(0, p, BLOCK):
        jac = world_jacobians(kinds, shape, uvw_t[:, s : s + BLOCK], displacements, to_world)
        out[s : s + BLOCK] = np.linalg.det(jac)
    return out


def world_jacobians(kinds, shape, uvw_t, displacements, to_world) -> np.ndarray:
    """(p, 3, 3) ``J[p, a, b] = dX_a / dx_b``: the identity plus the displacement field's
    parameter derivatives turned into world ones by ``to_world`` (``inv(axes).T``)."""
    cols = jacobian_columns(kinds, shape, uvw_t, displacements)  # (e, p, a)
    return np.eye(3) + np.einsum("epa,eb->pab", cols, to_world)
