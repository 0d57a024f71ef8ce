"""Signed volume of a closed triangle mesh and its gradient (paper Eq 7-13).

The paper sums, per triangle, the prism swept down to the x-y plane (Eq 7-8). For a closed
mesh that is the same number as the divergence-theorem sum of signed tetrahedra
``P1 . (P2 x P3) / 6``, which we use: it is exact for the triangle mesh as given, and its
gradient per corner is a single cross product (``dV/dP1 = P2 x P3 / 6``; summed over a
closed mesh it equals the paper's Eq 13b). Coordinates are taken relative to a centre near
the mesh, which keeps the triple products well conditioned for models far from the origin.

How :class:`VolumeOperator` evaluates it (see ``docs/BENCHMARKS.md`` for the measurements):

- **One cross product per edge, not three per face.** The corner gradient of vertex ``o`` in
  a face ``(j, k, o)`` is ``P_j x P_k / 6``: a cross product of the edge opposite ``o``.
  Every undirected edge ``{j, k}`` is shared by the faces on both sides, with opposite
  directions, so its cross product is computed once and added with sign ``+1`` or ``-1`` to
  the vertex opposite each of its half-edges. A closed surface has ``1.5 f`` edges: half the
  cross products of the per-face form. The signed scatter is a sparse ``(m, edges)`` matrix
  of ``+-1/6`` built once, so meshes that are open, non-manifold or inconsistently wound
  still get the exact gradient (an edge used by any number of faces just has more entries).
- **The volume comes from the gradient**: ``sum_i P_i . dV/dP_i = 3 V`` for any triangle
  set (each face contributes its triple product three times), so it costs one dot product.
- **Coordinate-major (structure-of-arrays) layout**: the x, y and z of all vertices are three
  contiguous rows, the cross product is written out by hand on those rows (``np.cross`` on
  ``(n, 3)`` rows moves axes and allocates), and the work runs over blocks of edges that
  stay in the CPU cache with scratch buffers reused from block to block. Small meshes (the
  coarse levels) skip the blocks: a few whole-array operations on a ``(5, m)`` copy whose
  rows are x, y, z, x, y, so that rows 1-3 and 2-4 are the two rotations a cross product
  needs, because there the number of NumPy calls is what costs.
- **No BLAS for dot products**: a threaded BLAS wakes its threads for every call, which on a
  busy machine costs milliseconds; ``einsum`` sums in the calling thread.

Everything is float64: results equal the per-face formula to rounding.

Once :mod:`core.kernels` has its compiled kernels (numba, optional), the evaluations run
there instead: vertex by vertex over the *fans* of faces around each vertex, with no
scatter (:mod:`core.kernels.volume`), the same numbers to rounding (closer to exact on large
models: the fans' cross products are of edge vectors, not of positions).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from . import kernels
from .lattice import PointBasis

try:  # the C++ kernel behind ``csc_matrix @ vector``, called on column blocks in place
    from scipy.sparse import _sparsetools as _st

    _csc_matvec = _st.csc_matvec
except (ImportError, AttributeError):  # pragma: no cover - other scipy layouts
    _csc_matvec = None

#: Edges (or faces) per block of the evaluation loop: 10 scratch rows of this many float64
#: fit in the L2 cache together with the block's slice of the scatter matrix.
BLOCK = 1 << 14

#: Up to this many faces (the volume alone), and twice as many edges (the volume and its
#: gradient), one evaluation runs as a handful of whole-array operations instead of the
#: block loop: fewer NumPy calls, which is what costs on coarse levels (the gradient of the
#: 1024-triangle level, 1536 edges, the examples' first level: 21 against 25 us; from
#: about 4000 edges the blocks are faster). Both ways give the same numbers.
SMALL = 1024

#: rows x, y, z, x, y: rows 1-3 are (y, z, x) and rows 2-4 (z, x, y), the two rotations a
#: cross product needs
_ROLL = np.array([0, 1, 2, 0, 1])


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume of a closed triangle mesh (positive when the faces wind outward).

    Parameters
    ----------
    vertices : (m, 3) float64
    faces : (f, 3) int
    """
    v = np.asarray(vertices, dtype=np.float64)
    small = len(v) <= np.iinfo(np.int32).max  # int32 corners: what the compiled volume reads
    corners = np.ascontiguousarray(np.asarray(faces).T, dtype=np.int32 if small else np.intp)
    mean = np.einsum("ij->j", v) / max(len(v), 1)  # v.mean(axis=0), several times faster
    rows = _coordinate_rows(v, mean)
    compiled = corners.size > 0 and kernels.active(corners.shape[1])
    if compiled and corners.min() >= 0 and corners.max() < len(v):
        fast = kernels.face_volume(corners, rows, None)
        if fast is not None:
            return fast
    return _triple_product_sum(rows, *corners) / 6.0


def locality_order(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n,) a vertex order for fast gathers: every vertex placed where the faces, in their
    order, first reach it (vertices of no face last), as the old index of each new place.

    A model subdivided or stitched together numbers its vertices far from the faces that
    use them (the 1.38M armadillo's edge midpoints come after all its corners), so the
    volume's per-face gathers miss the caches; in this order a face's corners lie close
    together (the 1.38M armadillo's face volume with int32 corners: 11.5 ms instead of
    19-20)."""
    n = int(n_vertices)
    flat = np.asarray(faces).reshape(-1)
    first = np.full(n, len(flat), dtype=np.int64)
    # the later of repeated indices is assigned last: the reversed order keeps the first
    first[flat[::-1]] = np.arange(len(flat) - 1, -1, -1, dtype=np.int64)
    return np.argsort(first, kind="stable")


def face_volumes(
    vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray | None = None
) -> np.ndarray:
    """(f,) signed volume of the tetrahedron each face spans with ``origin`` (by default
    the bounding-box centre); their sum is :func:`signed_volume`, their sum over one body
    is that body's volume."""
    v = np.asarray(vertices, dtype=np.float64)
    v = v - ((v.min(axis=0) + v.max(axis=0)) / 2 if origin is None else origin)
    tri = v[np.asarray(faces)]
    return np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0


def _triple_product_sum(vt: np.ndarray, f0: np.ndarray, f1: np.ndarray, f2: np.ndarray) -> float:
    """``sum_f a . (b x c)`` over the faces ``(f0, f1, f2)`` of the (3, m) rows ``vt``."""
    f = len(f0)
    if f <= SMALL:
        v5 = vt[_ROLL]
        a = vt.take(f0, axis=1)
        b, c = v5.take(f1, axis=1), v5.take(f2, axis=1)
        bc = b[1:4] * c[2:5]
        bc -= b[2:5] * c[1:4]
        return float(np.einsum("ij,ij->", a, bc))
    x, y, z = vt
    buf = np.empty((10, min(BLOCK, f)))
    total = 0.0
    for s in range(0, f, BLOCK):
        t = min(s + BLOCK, f)
        ax, ay, az, bx, by, bz, cx, cy, cz, tmp = buf[:, : t - s]
        i0, i1, i2 = f0[s:t], f1[s:t], f2[s:t]
        np.take(x, i0, out=ax, mode="clip")
        np.take(y, i0, out=ay, mode="clip")
        np.take(z, i0, out=az, mode="clip")
        np.take(x, i1, out=bx, mode="clip")
        np.take(y, i1, out=by, mode="clip")
        np.take(z, i1, out=bz, mode="clip")
        np.take(x, i2, out=cx, mode="clip")
        np.take(y, i2, out=cy, mode="clip")
        np.take(z, i2, out=cz, mode="clip")
        # a . (b x c), component by component (einsum, not a BLAS dot: a threaded BLAS
        # wakes its threads for every call, which costs milliseconds on a busy machine)
        np.multiply(by, cz, out=tmp)
        tmp -= bz * cy
        total += float(np.einsum("i,i->", ax, tmp))
        np.multiply(bz, cx, out=tmp)
        tmp -= bx * cz
        total += float(np.einsum("i,i->", ay, tmp))
        np.multiply(bx, cy, out=tmp)
        tmp -= by * cx
        total += float(np.einsum("i,i->", az, tmp))
    return total


def _coordinate_rows(vertices: np.ndarray, center: np.ndarray | None) -> np.ndarray:
    """(3, m) contiguous rows x, y, z of ``vertices - center``."""
    v = np.asarray(vertices, dtype=np.float64)
    vt = v.T
    if center is None:
        return vt if vt.flags.c_contiguous else np.ascontiguousarray(vt)
    out = np.empty(vt.shape)
    np.subtract(vt, np.asarray(center, dtype=np.float64).reshape(3, 1), out=out)
    return out


class _Edges(NamedTuple):
    """A mesh's undirected edges (sorted by their end points) and the signed
    edge-to-vertex scatter matrix, whole and in blocks of columns."""

    ej: np.ndarray
    ek: np.ndarray
    n_edges: int
    scatter: sp.csc_matrix
    width: int
    blocks: list


class VolumeOperator:
    """Volume and its gradient for a fixed face list; vertex positions vary.

    Building it once finds the mesh's edges and the signed edge-to-vertex scatter matrix, so
    each evaluation is a few cache-sized passes of gathers, products and one sparse
    product per coordinate.

    Vertex arrays may be in either memory order; the gradient is returned as an ``(m, 3)``
    view of a coordinate-major ``(3, m)`` buffer (Fortran order), which
    :meth:`core.lattice.PointBasis.apply_transpose` reads without copying.
    """

    def __init__(self, faces: np.ndarray, n_vertices: int) -> None:
        faces = np.asarray(faces)
        # int32 faces are kept as they are (a big level's own, renumbered ones)
        self.faces = np.ascontiguousarray(faces, np.int32 if faces.dtype == np.int32 else np.int64)
        self.n_vertices = n = int(n_vertices)
        f = len(self.faces)
        # int32 where the vertices allow: half the bytes the volume reads (12 a triangle)
        small = n <= np.iinfo(np.int32).max
        if f and (self.faces.min() < 0 or self.faces.max() >= n):
            raise ValueError(f"face indices must lie in [0, {n}) for {n} vertices")
        faces_t = np.ascontiguousarray(self.faces.T, dtype=np.int32 if small else np.intp)
        self._faces_t = faces_t  # (3, f): the compiled volume's corners
        self._corners = tuple(faces_t)  # for the volume-only path (views of its rows)
        self._fans = None  # for the compiled path, made on its first use
        self._plan = None  # the fans renumbered for node_gradient's one pass (first use)
        #: the edges and their scatter matrix (the gradient's), made on its first use: a
        #: level that is only measured (the full mesh of most solves) never needs them
        self._edge_data: _Edges | None = None

    @property
    def n_edges(self) -> int:
        return self._edges().n_edges

    def _edges(self) -> _Edges:
        """The mesh's edges grouped for the gradient (built once)."""
        edges = self._edge_data
        if edges is not None:
            return edges
        faces_t = np.ascontiguousarray(self.faces.T, dtype=np.intp)
        n, f = self.n_vertices, len(self.faces)
        # Half-edges j -> k of every face, and the vertex o opposite each one.
        src = faces_t.ravel()
        dst = faces_t[[1, 2, 0]].ravel()
        opp = faces_t[[2, 0, 1]].ravel()
        lo, hi = np.minimum(src, dst), np.maximum(src, dst)
        # Group the half-edges by undirected edge {lo, hi}; the edges come out sorted by
        # (lo, hi), so the gathers of each evaluation walk the vertex arrays forward.
        # Sorting one packed integer (lo, hi, o, direction) is several times faster than an
        # argsort followed by random gathers of each array.
        bits = max(int(n - 1).bit_length(), 1)
        if 3 * bits + 1 <= 63:
            packed = (lo << (2 * bits + 1)) | (hi << (bits + 1)) | (opp << 1) | (src > dst)
            packed.sort()
            mask = (1 << bits) - 1
            lo = packed >> (2 * bits + 1)
            hi = (packed >> (bits + 1)) & mask
            opp = (packed >> 1) & mask
            backwards = (packed & 1).astype(bool)
        else:  # more than 2**20 vertices
            order = np.argsort(lo * n + hi)
            lo, hi, opp, backwards = lo[order], hi[order], opp[order], (src > dst)[order]
        first = np.ones(len(lo), dtype=bool)
        first[1:] = (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])
        starts = np.flatnonzero(first)
        ej, ek = lo[starts], hi[starts]
        e = len(starts)
        # The scatter matrix, column by edge: its half-edges' opposite vertices with
        # +1/6 (P_j x P_k, j < k) or -1/6 (the half-edge runs k -> j).
        index = np.int32 if max(n, 3 * f) < 2**31 - 1 else np.int64
        scatter = sp.csc_matrix(
            (
                np.where(backwards, -1.0 / 6.0, 1.0 / 6.0),
                opp.astype(index),
                np.append(starts, 3 * f).astype(index),
            ),
            shape=(n, e),
        )
        ip, ind, dat = scatter.indptr, scatter.indices, scatter.data
        width = max(1, min(BLOCK, e))
        blocks = [
            (s, t, ip[s : t + 1] - ip[s], ind[ip[s] : ip[t]], dat[ip[s] : ip[t]])
            for s, t in ((s, min(s + width, e)) for s in range(0, e, width))
        ]
        self._edge_data = edges = _Edges(ej, ek, e, scatter, width, blocks)
        return edges

    def __call__(self, vertices: np.ndarray, center: np.ndarray | None = None) -> float:
        """Signed volume only."""
        if len(vertices) == self.n_vertices and kernels.active(len(self.faces)):
            # the faces in their own order: sorting them by their lowest vertex (for fewer
            # cache misses) gained nothing measurable on the 1.38M armadillo and cost the
            # first solve 1.7-2.3 s; the corners in int32 (12 bytes a triangle); a big
            # level numbers its vertices for locality (core.goal.constraints.Level)
            corners = self._faces_t
            fast = kernels.face_volume(corners, _coordinate_rows(vertices, None), center)
            if fast is not None:
                return fast
        return _triple_product_sum(_coordinate_rows(vertices, center), *self._corners) / 6.0

    def _fan(self):
        """The compiled kernels' fans of this mesh, made on first use (None: no kernels)."""
        if self._fans is None:
            self._fans = kernels.fans(self.faces, self.n_vertices)
        return self._fans

    def _compiled(self, vertices, center) -> tuple[float, np.ndarray] | None:
        """:meth:`value_and_gradient` by :mod:`core.kernels`; None where it is not ready."""
        if len(vertices) != self.n_vertices or not kernels.active(len(self.faces)):
            return None
        out = kernels.volume_gradient(self._fan(), _coordinate_rows(vertices, None), center)
        return None if out is None else (out[0], out[1].T)

    def node_gradient(
        self, basis, nodes: np.ndarray, center: np.ndarray | None = None
    ) -> tuple[float, np.ndarray]:
        """Signed volume of the vertices ``basis.apply(nodes)`` and its gradient with
        respect to the nodes, ``(l*m*n, 3)``: :meth:`value_and_gradient` then
        ``basis.apply_transpose``. With the compiled kernels and a Bernstein
        :class:`core.lattice.PointBasis` of these vertices, one pass over ranges of
        vertices (:mod:`core.kernels.fused`: the same numbers, without writing the points
        and the vertex gradient out and reading them back)."""
        nodes = np.asarray(nodes, dtype=np.float64)
        if (
            type(basis) is PointBasis
            and basis.n_points == self.n_vertices
            and kernels.active(len(self.faces))
        ):
            fans = self._fan()
            if self._plan is None and fans is not None:
                self._plan = kernels.evaluation_plan(fans)
            fast = kernels.evaluation(self._plan, basis.uvw, nodes, basis.shape, center)
            if fast is not None:
                return fast
        volume, grad = self.value_and_gradient(basis.apply(nodes), center)
        return volume, basis.apply_transpose(grad)

    def value_and_gradient(
        self, vertices: np.ndarray, center: np.ndarray | None = None
    ) -> tuple[float, np.ndarray]:
        """Signed volume and its gradient with respect to every vertex, ``(m, 3)``."""
        fast = self._compiled(vertices, center)
        if fast is not None:
            return fast
        edges = self._edges()
        n, e = self.n_vertices, edges.n_edges
        ej, ek = edges.ej, edges.ek
        grad = np.zeros((3, n))
        gx, gy, gz = grad
        if e <= 2 * SMALL and _csc_matvec is not None:
            v5 = _coordinate_rows(vertices, center)[_ROLL]
            a, b = v5.take(ej, axis=1), v5.take(ek, axis=1)
            c = a[1:4] * b[2:5]  # rows: (P_j x P_k) x, y, z
            c -= a[2:5] * b[1:4]
            s = edges.scatter
            for row, out in zip(c, grad):
                _csc_matvec(n, e, s.indptr, s.indices, s.data, row, out)
            return float(np.einsum("ij,ij->", v5[:3], grad)) / 3.0, grad.T
        vt = _coordinate_rows(vertices, center)
        x, y, z = vt
        width = edges.width
        buf = np.empty((10, width))
        for s, t, indptr, indices, data in edges.blocks:
            m = t - s
            if m != width:
                buf = buf[:, :m]
            xj, yj, zj, xk, yk, zk, cx, cy, cz, tmp = buf
            j, k = ej[s:t], ek[s:t]
            np.take(x, j, out=xj, mode="clip")
            np.take(y, j, out=yj, mode="clip")
            np.take(z, j, out=zj, mode="clip")
            np.take(x, k, out=xk, mode="clip")
            np.take(y, k, out=yk, mode="clip")
            np.take(z, k, out=zk, mode="clip")
            np.multiply(yj, zk, out=cx)
            np.multiply(zj, yk, out=tmp)
            cx -= tmp
            np.multiply(zj, xk, out=cy)
            np.multiply(xj, zk, out=tmp)
            cy -= tmp
            np.multiply(xj, yk, out=cz)
            np.multiply(yj, xk, out=tmp)
            cz -= tmp
            if _csc_matvec is not None:  # grad[c] += scatter[:, s:t] @ c_edge, in place
                _csc_matvec(n, m, indptr, indices, data, cx, gx)
                _csc_matvec(n, m, indptr, indices, data, cy, gy)
                _csc_matvec(n, m, indptr, indices, data, cz, gz)
            else:  # pragma: no cover
                block = sp.csc_matrix((data, indices, indptr), shape=(n, m))
                gx += block @ cx
                gy += block @ cy
                gz += block @ cz
        volume = float(np.einsum("ij,ij->", vt, grad)) / 3.0
        return volume, grad.T


class MomentOperator:
    """First moment of the solid, ``M = integral of x dV``, and its gradient, for a fixed
    face list (the centre of mass is ``M / V``).

    The divergence-theorem sum again: the tetrahedron a face ``(a, b, c)`` spans with the
    origin has volume ``det / 6`` (``det = a . (b x c)``) and centroid ``(a + b + c) / 4``,
    so ``M = sum det (a + b + c) / 24``, exact for the triangle mesh. Its derivative with
    respect to corner ``a`` is ``(s_i (b x c) + det e_i) / 24`` for component ``i``, with
    ``s = a + b + c`` (and cyclically for ``b`` and ``c``). The per-corner terms are
    gathered onto the vertices by one sparse matrix built once.
    """

    def __init__(self, faces: np.ndarray, n_vertices: int) -> None:
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        f = len(self.faces)
        self._gather = sp.csr_matrix(
            (np.ones(3 * f), (self.faces.T.ravel(), np.arange(3 * f))),
            shape=(int(n_vertices), 3 * f),
        )

    def value_and_gradient(
        self, vertices: np.ndarray, center: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """``M`` (3,) about ``center`` and its gradient ``(3, m, 3)``: ``[i, vertex, axis]``."""
        v = np.asarray(vertices, dtype=np.float64)
        if center is not None:
            v = v - np.asarray(center, dtype=np.float64)
        a, b, c = (v[self.faces[:, q]] for q in range(3))
        # d det / d corner, corner by corner (a, b, c), stacked corner-major like the gather
        w = np.concatenate([np.cross(b, c), np.cross(c, a), np.cross(a, b)])
        det = np.einsum("ij,ij->i", a, w[: len(a)])
        s = a + b + c
        moment = det @ s / 24.0
        s3, det3 = np.tile(s, (3, 1)), np.tile(det, 3)
        grad = np.empty((3, len(v), 3))
        for i in range(3):
            term = s3[:, i : i + 1] * w
            term[:, i] += det3
            grad[i] = self._gather @ term / 24.0
        return moment, grad
