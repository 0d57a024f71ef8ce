"""Trivariate free-form deformation lattice (paper Eq 2-5): Bernstein or Blender's bases.

A lattice has ``shape = (l, m, n)`` nodes along its three axes (2 to 10 each for the
paper's Bernstein basis, 1 to 64 for the local bases of Blender's lattice,
:mod:`core.localbasis`: ``basis`` names one per axis). Its frame is
an affine map: a point ``x`` has lattice coordinates ``(u, v, w) = (x - origin) @ inv(axes)``,
where the rows of ``axes`` are the three edge vectors of the lattice box (this is the paper's
4x3 matrix ``A`` of Eq 5, split into its linear part and its translation). The deformed point
is ``sum_ijk B_i(u) B_j(v) B_k(w) X_ijk`` (Eq 4).

Nodes are stored as an ``(l*m*n, 3)`` array in the paper's order (Eq 4): ``i`` slowest,
``k`` fastest, so node ``(i, j, k)`` is row ``(i*m + j)*n + k``.

The rest lattice is a regular grid, so the FFD with rest nodes is the identity (Bernstein
polynomials reproduce linear functions; the local bases blend displacements from the rest
grid). An axis with one node (local bases only) has it in the middle of the box.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb
from typing import cast

import numpy as np

from . import kernels
from . import localbasis as lb
from .errors import IsochorError

MIN_NODES, MAX_NODES = 2, 10

#: Above this many basis entries (points x nodes) a point basis keeps the factored
#: tensor-product form instead of one dense matrix (64 MB of float64).
DENSE_LIMIT = 8_000_000

#: Above this many entries the factored form is also faster than the dense matrix (measured:
#: docs/BENCHMARKS.md), so a basis between the two limits keeps the dense matrix for callers
#: that read it but evaluates in factored form.
DENSE_FASTER = 262_144

#: Points per block of the factored basis products (their temporaries stay in cache).
BASIS_BLOCK = 1 << 13


def bernstein(degree: int, t: np.ndarray) -> np.ndarray:
    """Bernstein polynomials ``B_i^degree(t)`` for i = 0..degree.

    Parameters
    ----------
    t : (p,) float64

    Returns
    -------
    (p, degree + 1) float64
    """
    t = np.asarray(t, dtype=np.float64)
    s = 1.0 - t
    # powers by repeated products (integer powers through np.power were most of a small
    # level's basis set-up): up[i] = t**i, down[i] = s**(degree - i)
    up = np.empty((degree + 1, len(t)))
    down = np.empty((degree + 1, len(t)))
    up[0] = 1.0
    down[degree] = 1.0
    for i in range(1, degree + 1):
        np.multiply(up[i - 1], t, out=up[i])
        np.multiply(down[degree - i + 1], s, out=down[degree - i])
    up *= down
    up *= np.array([comb(degree, k) for k in range(degree + 1)], dtype=np.float64)[:, None]
    return up.T


def bernstein_derivative(degree: int, t: np.ndarray) -> np.ndarray:
    """d/dt of :func:`bernstein`: ``degree * (B_{i-1}^{degree-1} - B_i^{degree-1})``,
    shape (p, degree + 1)."""
    t = np.asarray(t, dtype=np.float64)
    out = np.zeros((len(t), degree + 1))
    if degree > 0:
        low = bernstein(degree - 1, t)
        out[:, 1:] += low
        out[:, :-1] -= low
    return degree * out


class PointBasis:
    """The FFD basis of a fixed point set: maps node positions to point positions.

    The weight of node (i, j, k) on point p is ``Bu[p, i] * Bv[p, j] * Bw[p, k]``. The basis
    keeps the points' lattice coordinates ``uvw``; :meth:`apply` and :meth:`apply_transpose`
    run in :mod:`core.kernels` once its compiled kernels are ready, which evaluate the
    Bernstein polynomials per point (nothing else is stored). The NumPy path (until the
    kernels are ready, or without numba) builds its tables on first use and keeps them:
    small point sets the dense ``(p, nodes)`` matrix (``dense``: one matrix product per
    evaluation); large ones only the factored form ``Buv (p, l*m)`` and ``Bw (p, n)``:
    memory ``p*(l*m + n)`` instead of ``p*l*m*n``. Between ``DENSE_FASTER`` and
    ``DENSE_LIMIT`` entries both are kept and the faster factored form evaluates.

    The tables are stored point-minor (``dense``, ``buv`` and ``bw`` are transposed views of
    C-ordered ``(columns, p)`` arrays) and :meth:`apply` returns its ``(p, 3)`` result as a
    view of a coordinate-major ``(3, p)`` buffer (Fortran order): three contiguous rows x, y,
    z, the layout :class:`core.volume.VolumeOperator` works in; :meth:`apply_transpose`
    reads such a gradient without copying. The factored products run over blocks of
    ``BASIS_BLOCK`` points so that their temporaries stay in the CPU cache.
    """

    def __init__(self, uvw: np.ndarray, shape: tuple[int, int, int]) -> None:
        uvw = np.asarray(uvw, dtype=np.float64).reshape(-1, 3)
        self.shape = cast("tuple[int, int, int]", tuple(int(d) for d in shape))
        self.n_points = len(uvw)
        #: (3, p) lattice coordinates, what the compiled kernels read
        self.uvw = np.ascontiguousarray(uvw.T)
        size = self.n_points * int(np.prod(self.shape))
        self._dense, self._factored = size <= DENSE_LIMIT, size > min(DENSE_LIMIT, DENSE_FASTER)
        #: (dense_t, buv_t, bw_t), built on the NumPy path's first use (see the class)
        self._tables: tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None] | None
        self._tables = None

    def _built(self) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        tables = self._tables  # one tuple: another thread may build it too, never half
        if tables is None:
            l, m, n = self.shape
            p = self.n_points
            bu, bv, bw = (bernstein(d - 1, self.uvw[c]) for c, d in enumerate(self.shape))
            buv_t = (bu.T[:, None, :] * bv.T[None, :, :]).reshape(l * m, p)
            bw_t = np.ascontiguousarray(bw.T)
            dense_t = None
            if self._dense and not self._factored:  # (between the limits: on demand, below)
                dense_t = (buv_t[:, None, :] * bw_t[None, :, :]).reshape(l * m * n, p)
            factored = (buv_t, bw_t) if self._factored else (None, None)
            tables = self._tables = (dense_t, *factored)
        return tables

    @property
    def dense(self) -> np.ndarray | None:
        """(p, nodes) the dense basis matrix of a small point set, else None. Between
        ``DENSE_FASTER`` and ``DENSE_LIMIT`` entries it is made on the first ask (the
        evaluations use the factored form: a level that is only measured, such as the
        full mesh of most solves, never builds it)."""
        dense_t, buv_t, bw_t = self._built()
        if dense_t is None and self._dense:
            assert buv_t is not None and bw_t is not None  # factored when not dense
            l, m, n = self.shape
            dense_t = (buv_t[:, None, :] * bw_t[None, :, :]).reshape(l * m * n, self.n_points)
            self._tables = (dense_t, buv_t, bw_t)
        return None if dense_t is None else dense_t.T

    @property
    def buv(self) -> np.ndarray | None:
        """(p, l*m) the factored form's first factor of a large point set, else None."""
        buv_t = self._built()[1]
        return None if buv_t is None else buv_t.T

    @property
    def bw(self) -> np.ndarray | None:
        """(p, n) the factored form's second factor of a large point set, else None."""
        bw_t = self._built()[2]
        return None if bw_t is None else bw_t.T

    @property
    def nbytes(self) -> int:
        """Memory held by the basis, in bytes (the NumPy path's tables once built)."""
        held = [*(self._tables or ()), self.uvw]
        return int(sum(a.nbytes for a in held if a is not None))

    def apply(self, nodes: np.ndarray) -> np.ndarray:
        """Deformed points ``(p, 3)`` for node positions ``(l*m*n, 3)``.

        The result is a Fortran-ordered view of a ``(3, p)`` array (see the class notes)."""
        nodes = np.asarray(nodes, dtype=np.float64)
        out = kernels.apply(self.uvw, nodes, self.shape)
        if out is not None:
            return out.T
        dense_t, buv_t, bw_t = self._built()
        if buv_t is None:
            return (nodes.T @ dense_t).T
        assert bw_t is not None  # the factored form's two factors come together
        l, m, n = self.shape
        lm, p = l * m, self.n_points
        # x_t[(k, c), ij] = nodes[(ij, k), c]
        x_t = nodes.reshape(lm, n, 3).transpose(1, 2, 0).reshape(3 * n, lm)
        out = np.empty((3, p))
        width = max(1, min(BASIS_BLOCK, p))
        y = np.empty((n, 3, width))
        for s in range(0, p, width):
            t = min(s + width, p)
            yb = y if t - s == width else y[:, :, : t - s]
            np.matmul(x_t, buv_t[:, s:t], out=yb.reshape(3 * n, t - s))
            yb *= bw_t[:, None, s:t]
            yb.sum(axis=0, out=out[:, s:t])
        return out.T

    def apply_transpose(self, point_values: np.ndarray) -> np.ndarray:
        """Chain rule (paper Eq 11): per-point ``(p, 3)`` -> per-node ``(l*m*n, 3)``."""
        v = np.asarray(point_values, dtype=np.float64).T  # (3, p), contiguous if Fortran
        out = kernels.apply_transpose(self.uvw, v, self.shape)
        if out is not None:
            return out
        dense_t, buv_t, bw_t = self._built()
        if buv_t is None:
            assert dense_t is not None  # not factored: dense
            return np.ascontiguousarray((v @ dense_t.T).T)
        assert bw_t is not None  # the factored form's two factors come together
        l, m, n = self.shape
        lm, p = l * m, self.n_points
        acc = np.zeros((3 * n, lm))
        width = max(1, min(BASIS_BLOCK, p))
        z = np.empty((n, 3, width))
        for s in range(0, p, width):
            t = min(s + width, p)
            zb = z if t - s == width else z[:, :, : t - s]
            np.multiply(bw_t[:, None, s:t], v[None, :, s:t], out=zb)
            acc += zb.reshape(3 * n, t - s) @ buv_t[:, s:t].T
        # acc[(k, c), ij] -> out[(ij, k), c]
        return np.ascontiguousarray(acc.reshape(n, 3, lm).transpose(2, 0, 1)).reshape(lm * n, 3)


def basis_names(basis) -> tuple[str, str, str]:
    """The per-axis basis names of ``basis``: one name for all three axes or three names
    (:data:`core.localbasis.NAMES`); 'bernstein' cannot be mixed with the local ones."""
    names = (basis,) * 3 if isinstance(basis, str) else tuple(basis)
    if len(names) != 3 or not all(isinstance(b, str) for b in names):
        raise IsochorError(f"A lattice basis is one name or three (one per axis), got {basis!r}.")
    names = tuple(b.strip().lower().replace("_", "-") for b in names)
    names = tuple("bspline" if b == "b-spline" else b for b in names)
    for b in names:
        if b not in lb.NAMES:
            raise IsochorError(f"Unknown lattice basis {b!r}: use one of {', '.join(lb.NAMES)}.")
    if lb.BERNSTEIN in names and len(set(names)) > 1:
        raise IsochorError(
            f"The Bernstein basis cannot be mixed with the local bases, got {', '.join(names)}."
        )
    return cast("tuple[str, str, str]", names)  # three, checked above


@dataclass(frozen=True, eq=False)
class Lattice:
    """An FFD lattice: node counts per axis, the affine frame and the basis.

    Attributes
    ----------
    shape : (l, m, n) nodes per axis, each 2..10 (Bernstein) or 1..64 (local bases)
    origin : (3,) float64, the corner at (u, v, w) = (0, 0, 0)
    axes : (3, 3) float64, rows are the edge vectors along u, v and w
    basis : per-axis basis names (:data:`core.localbasis.NAMES`), "bernstein" by default;
        one name is taken for all three axes
    outside : Blender's "Outside": inner nodes follow the lattice's faces (local bases only)
    """

    shape: tuple[int, int, int]
    origin: np.ndarray
    axes: np.ndarray
    basis: tuple[str, str, str] = (lb.BERNSTEIN,) * 3
    outside: bool = False

    def __post_init__(self) -> None:
        shape = tuple(int(s) for s in self.shape)
        basis = basis_names(self.basis)
        local = basis[0] != lb.BERNSTEIN
        low, high = (lb.MIN_LOCAL, lb.MAX_LOCAL) if local else (MIN_NODES, MAX_NODES)
        if len(shape) != 3 or not all(low <= s <= high for s in shape):
            which = f"the {'/'.join(sorted(set(basis)))} basis" if local else "the Bernstein basis"
            raise IsochorError(
                f"A lattice with {which} needs {low} to {high} nodes per axis, got {self.shape}."
            )
        if self.outside and not local:
            raise IsochorError(
                "The lattice option 'outside' (Blender's) needs a local basis, not Bernstein."
            )
        origin = np.array(self.origin, dtype=np.float64).reshape(3)
        axes = np.array(self.axes, dtype=np.float64).reshape(3, 3)
        if not (np.all(np.isfinite(origin)) and np.all(np.isfinite(axes))):
            raise IsochorError("The lattice frame has a non-finite number in it.")
        det = np.linalg.det(axes)
        scale = np.prod(np.linalg.norm(axes, axis=1))
        if scale == 0 or abs(det) < 1e-9 * scale:
            raise IsochorError("The lattice frame is singular: its three edge vectors are flat.")
        origin.flags.writeable = False
        axes.flags.writeable = False
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "basis", basis)
        object.__setattr__(self, "outside", bool(self.outside))

    @property
    def local(self) -> bool:
        """Whether the basis is local (Blender's): each point moves with at most 4x4x4
        nodes, as displacements from the rest grid."""
        return self.basis[0] != lb.BERNSTEIN

    def like(self, shape=None, basis=None, outside=None) -> Lattice:
        """This lattice's frame with another node count, basis or "outside" option."""
        return Lattice(
            self.shape if shape is None else shape,
            self.origin,
            self.axes,
            self.basis if basis is None else basis,
            self.outside if outside is None else outside,
        )

    @classmethod
    def around(
        cls,
        points: np.ndarray,
        shape: tuple[int, int, int] = (3, 3, 3),
        padding: float = 0.05,
        basis=lb.BERNSTEIN,
        outside: bool = False,
    ) -> Lattice:
        """An axis-aligned lattice around the bounding box of ``points``.

        Each axis is padded on both sides by ``padding`` times its extent (at least
        ``padding`` times 1% of the largest extent, so a flat model still gets a box), which
        puts every point strictly inside.
        """
        points = np.asarray(points, dtype=np.float64)
        if padding <= 0:
            raise IsochorError(f"The lattice padding must be positive, got {padding}.")
        lo, hi = points.min(axis=0), points.max(axis=0)
        ext = hi - lo
        if not np.all(np.isfinite(ext)) or ext.max() <= 0:
            raise IsochorError("The model has no extent: all its vertices are at one point.")
        pad = padding * np.maximum(ext, 0.01 * ext.max())
        return cls(shape, lo - pad, np.diag(ext + 2 * pad), basis, outside)

    @property
    def n_nodes(self) -> int:
        l, m, n = self.shape
        return l * m * n

    @property
    def size(self) -> float:
        """Largest edge length of the lattice box."""
        return float(np.linalg.norm(self.axes, axis=1).max())

    def index(self, i: int, j: int, k: int) -> int:
        """Row of node (i, j, k) in the node array (Eq 4 order)."""
        l, m, n = self.shape
        if not (0 <= i < l and 0 <= j < m and 0 <= k < n):
            raise IndexError(f"node ({i}, {j}, {k}) is outside a {l}x{m}x{n} lattice")
        return (i * m + j) * n + k

    def ijk(self, index: int | np.integer) -> tuple[int, int, int]:
        """(i, j, k) of node row ``index``."""
        l, m, n = self.shape
        return cast(
            "tuple[int, int, int]", tuple(int(a) for a in np.unravel_index(index, (l, m, n)))
        )

    def grid_parameters(self) -> np.ndarray:
        """(nodes, 3) lattice coordinates (i/(l-1), j/(m-1), k/(n-1)) of every node (0.5 on
        an axis with one node, as Blender places it)."""
        g = np.meshgrid(
            *(np.linspace(0, 1, c) if c > 1 else np.array([0.5]) for c in self.shape),
            indexing="ij",
        )
        return np.stack([a.ravel() for a in g], axis=1)

    @property
    def rest_nodes(self) -> np.ndarray:
        """(nodes, 3) rest positions: the regular grid spanning the frame."""
        return self.origin + self.grid_parameters() @ self.axes

    def to_parameters(self, points: np.ndarray) -> np.ndarray:
        """(p, 3) lattice coordinates (u, v, w) of world points (Eq 5)."""
        return (np.asarray(points, dtype=np.float64) - self.origin) @ np.linalg.inv(self.axes)

    def contains(self, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """(p,) bool: which points lie inside the lattice box (within ``tol`` in u, v, w)."""
        uvw = self.to_parameters(points)
        return np.all((uvw >= -tol) & (uvw <= 1 + tol), axis=1)

    def point_basis(self, points: np.ndarray) -> PointBasis | lb.LocalPointBasis:
        """The basis of a fixed point set; compute once, apply to many node positions."""
        if self.local:
            points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
            return lb.LocalPointBasis(
                self.to_parameters(points),
                points,
                self.shape,
                self.basis,
                self.rest_nodes,
                self.outside_map,
            )
        return PointBasis(self.to_parameters(points), self.shape)

    def deform(self, points: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """(p, 3) points mapped by the FFD with node positions ``nodes`` (nodes, 3)."""
        return self.point_basis(points).apply(np.asarray(nodes, dtype=np.float64))

    @property
    def outside_map(self):
        """(nodes, nodes) sparse Blender's "Outside" map when the option is on, else None."""
        return lb.outside_matrix(self.shape) if self.outside else None

    def effective_nodes(self, nodes: np.ndarray) -> np.ndarray:
        """(nodes, 3) the nodes the deformation uses: with "outside" the inner ones follow
        the faces (Blender's ``outside_lattice``), else ``nodes`` themselves."""
        nodes = np.asarray(nodes, dtype=np.float64).reshape(self.n_nodes, 3)
        return nodes if not self.outside else np.asarray(self.outside_map @ nodes)

    def displacements(self, nodes: np.ndarray) -> np.ndarray:
        """(nodes, 3) what a local basis blends: effective nodes minus effective rest nodes."""
        return self.effective_nodes(nodes) - self.effective_nodes(self.rest_nodes)

    def weights(self, points: np.ndarray):
        """``(W, offset)``: the FFD at fixed rest points as ``W @ nodes + offset``; W (p, nodes)
        dense for Bernstein (offset 0), sparse for a local basis."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        uvw = self.to_parameters(points)
        if not self.local:
            l, m, n = self.shape
            bu, bv, bw = (bernstein(d - 1, uvw[:, a]) for a, d in enumerate(self.shape))
            w = np.einsum("pi,pj,pk->pijk", bu, bv, bw).reshape(len(uvw), l * m * n)
            return w, np.zeros_like(points)
        w = lb.weight_matrix(self.basis, self.shape, np.ascontiguousarray(uvw.T))
        if self.outside:
            w = w @ self.outside_map
        return w.tocsr(), points - w @ self.rest_nodes

    def jacobian(self, points: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """(p, 3, 3) derivative of the FFD at world points: ``J[p, a, b] = dX_a / dx_b``.

        It transforms tangents (``J t``) and, as its inverse transpose, normals; its
        determinant is the local change of volume (negative where the map folds space)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        l, m, n = self.shape
        to_world = np.linalg.inv(self.axes).T  # d(u, v, w) / dx, transposed
        out = np.empty((len(points), 3, 3))
        if self.local:
            uvw_t = np.ascontiguousarray(self.to_parameters(points).T)
            d = self.displacements(nodes)
            for s in range(0, len(points), BASIS_BLOCK):
                block = uvw_t[:, s : s + BASIS_BLOCK]
                out[s : s + BASIS_BLOCK] = lb.world_jacobians(
                    self.basis, self.shape, block, d, to_world
                )
            return out
        grid = np.asarray(nodes, dtype=np.float64).reshape(l, m, n, 3)
        for s in range(0, len(points), BASIS_BLOCK):
            uvw = self.to_parameters(points[s : s + BASIS_BLOCK])
            b = [bernstein(d - 1, uvw[:, c]) for c, d in enumerate(self.shape)]
            db = [bernstein_derivative(d - 1, uvw[:, c]) for c, d in enumerate(self.shape)]
            columns = [
                np.einsum("pi,pj,pk,ijka->pa", *(db[c] if c == e else b[c] for c in range(3)), grid)
                for e in range(3)
            ]
            out[s : s + BASIS_BLOCK] = np.stack(columns, axis=2) @ to_world
        return out
