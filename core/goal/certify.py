"""A proof that a Bernstein FFD does not fold the solid, or a point where it does.

The fold check's samples (:mod:`.folds`) can miss a pocket between them. ``det J`` of a
Bernstein FFD is itself a polynomial: with ``(L, M, N) = (l-1, m-1, n-1)`` the lattice's
degrees, ``dX/du`` has degree ``(L-1, M, N)`` (and cyclically), so ``det [X_u X_v X_w]``
has degree ``(3L-1, 3M-1, 3N-1)`` in ``(u, v, w)``. Its Bernstein coefficients over a box
bound it there (the convex hull property), and the coefficients of the box's halves follow
by de Casteljau's algorithm. So :func:`certify`

1. computes the coefficients of ``det`` exactly (products of Bernstein polynomials are
   convolutions of their binomially scaled coefficients);
2. keeps a box when it may meet the solid (:class:`Occupancy`: the cells of a grid over
   the lattice that hold a triangle, or lie inside the model by a winding number);
3. on each kept box: every coefficient above the rounding bound proves ``det > 0`` there;
   ``det <= 0`` at a point of the box inside the model finds a fold; otherwise the box is
   split in two along its longest side, down to :data:`MIN_WIDTH`, within
   :data:`MAX_BOXES`.

The answer is one of three: **proven** fold-free over the solid, **folded** (with a
witness point inside it and its ``det J``), or **undecided** (``det J`` comes within
rounding of zero, or the budget ran out): never fold-free unless proven.

The lattice's own frame maps ``(u, v, w)`` to world space affinely, so the sign of det J
in world space is that of the parametric determinant times ``sign(det axes)``.

Local bases (B-spline, Catmull-Rom, ...) are piecewise polynomials, one piece per lattice
cell; :func:`certify` takes the Bernstein lattice as one piece, and
:func:`certify_pieces` any list of pieces given by their Bezier control points, so a
per-cell basis plugs in by converting each cell to its Bezier form.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from math import comb
from typing import cast

import numpy as np

from ..bodies import WINDING_INSIDE, winding_numbers
from ..lattice import Lattice

#: most boxes examined per certification (each a few hundred to a few thousand numbers)
MAX_BOXES = 3_000
#: most coefficients examined in all (bounds the time for a fine lattice's high degree)
MAX_NUMBERS = 40_000_000
#: boxes narrower than this (in lattice coordinates, on every side) are not split again
MIN_WIDTH = 2.0**-14
#: cells per axis of the occupancy grid over the lattice
OCCUPANCY_CELLS = 48


@dataclass(frozen=True)
class Certificate:
    """What :func:`certify` established about ``det J`` over the solid.

    Attributes
    ----------
    proven : det J > 0 at every point of the solid (within the lattice), proven
    witness : a point (world coordinates) inside the solid where det J <= 0, or None
    witness_det : det J there (nan when there is no witness)
    boxes : boxes examined
    lower : a lower bound of det J over the boxes that met the solid (world units)
    """

    proven: bool
    witness: np.ndarray | None
    witness_det: float
    boxes: int
    lower: float

    @property
    def folded(self) -> bool:
        return self.witness is not None

    @property
    def undecided(self) -> bool:
        return not self.proven and self.witness is None


# -- Bernstein polynomials in three variables ----------------------------------------------
def _binomials(degree: int) -> np.ndarray:
    return np.array([comb(degree, i) for i in range(degree + 1)], dtype=np.float64)


def _scale(c: np.ndarray, inverse: bool = False) -> np.ndarray:
    """Multiply (or divide) the coefficients by their binomials on the three axes."""
    out = c
    for axis in range(3):
        b = _binomials(c.shape[axis] - 1)
        shape = [1, 1, 1]
        shape[axis] = -1
        b = b.reshape(shape)
        out = out / b if inverse else out * b
    return out


def _convolve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The full 3D convolution of ``a`` and ``b`` (exact sums of products, no FFT)."""
    out = np.zeros(tuple(x + y - 1 for x, y in zip(a.shape, b.shape)))
    sa, sb = a.shape, b.shape
    if a.size > b.size:
        a, b, sa, sb = b, a, sb, sa
    for (i, j, k), value in np.ndenumerate(a):
        if value != 0.0:
            out[i : i + sb[0], j : j + sb[1], k : k + sb[2]] += value * b
    return out


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bernstein coefficients of the product of two polynomials given by theirs."""
    return _scale(_convolve(_scale(a), _scale(b)), inverse=True)


def determinant_coefficients(control: np.ndarray) -> np.ndarray:
    """Bernstein coefficients of ``det [X_u X_v X_w]`` on the unit box, for the Bezier
    volume with control points ``control`` (l, m, n, 3)."""
    control = np.asarray(control, dtype=np.float64)
    l, m, n, _ = control.shape
    du = (l - 1) * np.diff(control, axis=0)  # (l-1, m, n, 3)
    dv = (m - 1) * np.diff(control, axis=1)
    dw = (n - 1) * np.diff(control, axis=2)
    # cross product X_v x X_w, then the dot product with X_u
    cross = [
        _product(dv[..., 1], dw[..., 2]) - _product(dv[..., 2], dw[..., 1]),
        _product(dv[..., 2], dw[..., 0]) - _product(dv[..., 0], dw[..., 2]),
        _product(dv[..., 0], dw[..., 1]) - _product(dv[..., 1], dw[..., 0]),
    ]
    return cast(np.ndarray, sum(_product(du[..., a], cross[a]) for a in range(3)))


def rounding_bound(control: np.ndarray) -> float:
    """A bound on the rounding error of every coefficient of
    :func:`determinant_coefficients`: each is a convex combination (binomial weights) of
    six triple products of derivative coefficients, each at most the product of the
    largest lengths, computed in a few hundred operations at most."""
    control = np.asarray(control, dtype=np.float64)
    l, m, n, _ = control.shape
    big = [
        (d - 1) * float(np.abs(np.diff(control, axis=a)).max(initial=0.0))
        for a, d in enumerate((l, m, n))
    ]
    ops = 4 * (3 * (l + m + n))  # the sums in the products, with a margin
    return 6.0 * big[0] * big[1] * big[2] * ops * np.finfo(np.float64).eps


def _split(c: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """de Casteljau at 1/2 along ``axis``: the coefficients on the two halves."""
    c = np.moveaxis(c, axis, 0)
    d = c.shape[0] - 1
    left, right = [c[0]], [c[-1]]
    work = c
    for _ in range(d):
        work = 0.5 * (work[:-1] + work[1:])
        left.append(work[0])
        right.append(work[-1])
    lo = np.stack(left)
    hi = np.stack(right[::-1])
    return np.moveaxis(lo, 0, axis), np.moveaxis(hi, 0, axis)


def _value_at_centre(c: np.ndarray) -> float:
    """The polynomial's value at the centre of its box (de Casteljau at 1/2 on each axis)."""
    for _ in range(3):
        d = c.shape[0] - 1
        weights = _binomials(d) / 2.0**d
        c = np.tensordot(weights, c, axes=(0, 0))
    return float(c)


# -- where the solid is --------------------------------------------------------------------
class Occupancy:
    """A grid over the lattice's unit box: which cells may meet the solid.

    A cell that holds part of a triangle's bounding box may meet the surface; the other
    cells form connected regions, each wholly inside or wholly outside the model (no
    surface crosses them), told apart by the winding number at one cell of each.

    Parameters
    ----------
    lattice : the lattice (the grid lies over its unit box in lattice coordinates)
    vertices, faces : the solid's closed surface at rest (its caps included)
    cells : cells per axis
    """

    def __init__(
        self,
        lattice: Lattice,
        vertices: np.ndarray,
        faces: np.ndarray,
        cells: int = OCCUPANCY_CELLS,
    ) -> None:
        self.cells = int(cells)
        self._inputs: tuple | None = (lattice, vertices, faces)
        #: two solver threads may measure at once (a stopped drag's solve still ending
        #: beside the next one's): one builds, the other waits for the whole grid
        self._lock = threading.Lock()

    def _build(self) -> None:
        """The grid, built on first use (a certification proven on the whole lattice box
        at once never needs it). The inputs are dropped only once every table is made, so
        a thread that finds them gone finds the tables."""
        if self._inputs is None:
            return
        with self._lock:
            if self._inputs is not None:
                self._make(*self._inputs)
                self._inputs = None

    def _make(self, lattice: Lattice, vertices: np.ndarray, faces: np.ndarray) -> None:
        from scipy import ndimage

        g = self.cells
        uvw = lattice.to_parameters(np.asarray(vertices, dtype=np.float64))
        tri = uvw[np.asarray(faces, dtype=np.int64)]  # (f, 3, 3)
        lo = np.clip(np.floor(tri.min(axis=1) * g).astype(np.int64), 0, g - 1)
        hi = np.clip(np.floor(tri.max(axis=1) * g).astype(np.int64), 0, g - 1)
        surface = np.zeros((g, g, g), dtype=bool)
        span = (hi - lo).max(axis=1)
        small = span <= 3
        for di in range(4):
            for dj in range(4):
                for dk in range(4):
                    at = lo[small] + (di, dj, dk)
                    ok = np.all(at <= hi[small], axis=1)
                    surface[at[ok, 0], at[ok, 1], at[ok, 2]] = True
        for a, b in zip(lo[~small], hi[~small]):
            surface[a[0] : b[0] + 1, a[1] : b[1] + 1, a[2] : b[2] + 1] = True
        labels, count = ndimage.label(~surface)
        inside = np.zeros(count + 1, dtype=bool)
        if count:
            first = ndimage.minimum_position(
                np.arange(labels.size).reshape(labels.shape), labels, range(1, count + 1)
            )
            centres = (np.array(first, dtype=np.float64).reshape(-1, 3) + 0.5) / g
            world = lattice.origin + centres @ lattice.axes
            triangles = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
            inside[1:] = np.abs(winding_numbers(world, triangles)) > WINDING_INSIDE
        self.solid = surface | inside[labels]
        # prefix sums: how many solid (and surface) cells a block holds, in O(1)
        self._sum = _prefix(self.solid)
        self._surface_sum = _prefix(surface)
        self._surface = surface
        self._inside_label = inside
        self._labels = labels
        self._lattice = lattice
        self._triangles = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]

    def block(self, lo: np.ndarray, hi: np.ndarray) -> tuple[bool, bool]:
        """Whether the box ``lo..hi`` (lattice coordinates) may meet the solid, and whether
        it lies wholly inside it (no surface in its cells)."""
        self._build()
        g = self.cells
        a = np.clip(np.floor(np.asarray(lo) * g).astype(np.int64), 0, g - 1)
        b = np.clip(np.ceil(np.asarray(hi) * g).astype(np.int64), 1, g)
        b = np.maximum(b, a + 1)
        solid = _block_sum(self._sum, a, b)
        return solid > 0, solid == int(np.prod(b - a)) and _block_sum(self._surface_sum, a, b) == 0

    def inside(self, uvw: np.ndarray) -> np.ndarray:
        """(p,) bool: which points at lattice coordinates ``uvw`` (p, 3) are inside the
        solid (exactly, by their winding numbers where their cell holds the surface)."""
        self._build()
        uvw = np.asarray(uvw, dtype=np.float64).reshape(-1, 3)
        g = self.cells
        c = np.clip(np.floor(uvw * g).astype(np.int64), 0, g - 1)
        out = self._inside_label[self._labels[c[:, 0], c[:, 1], c[:, 2]]]
        near = self._surface[c[:, 0], c[:, 1], c[:, 2]]
        if near.any():
            world = self._lattice.origin + uvw[near] @ self._lattice.axes
            out[near] = np.abs(winding_numbers(world, self._triangles)) > WINDING_INSIDE
        return out


def _prefix(cells: np.ndarray) -> np.ndarray:
    return np.pad(cells.astype(np.int64).cumsum(0).cumsum(1).cumsum(2), ((1, 0),) * 3)


def _block_sum(s: np.ndarray, a: np.ndarray, b: np.ndarray) -> int:
    return int(
        s[b[0], b[1], b[2]]
        - s[a[0], b[1], b[2]]
        - s[b[0], a[1], b[2]]
        - s[b[0], b[1], a[2]]
        + s[a[0], a[1], b[2]]
        + s[a[0], b[1], a[2]]
        + s[b[0], a[1], a[2]]
        - s[a[0], a[1], a[2]]
    )


# -- the certification ---------------------------------------------------------------------
def supported(lattice: Lattice) -> bool:
    """Whether :func:`certify` applies: a Bernstein lattice (the paper's). A lattice with
    Blender's local bases (``lattice.local``) is left to the fold check's samples (its
    det J is piecewise polynomial: :func:`certify_pieces` takes such pieces once they are
    converted to Bezier form)."""
    return not lattice.local


def certify(
    lattice: Lattice,
    nodes: np.ndarray,
    occupancy: Occupancy | None,
    *,
    max_boxes: int = MAX_BOXES,
) -> Certificate:
    """Prove ``det J > 0`` over the solid for the Bernstein FFD with node positions
    ``nodes``, or find a point inside it where ``det J <= 0`` (see the module's text).

    ``occupancy`` None: the whole lattice box counts as the solid (a stronger claim, and
    no grid to build)."""
    l, m, n = lattice.shape
    control = np.asarray(nodes, dtype=np.float64).reshape(l, m, n, 3)
    return certify_pieces(lattice, [(control, np.zeros(3), np.ones(3))], occupancy, max_boxes)


def certify_pieces(
    lattice: Lattice,
    pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    occupancy: Occupancy | None,
    max_boxes: int = MAX_BOXES,
) -> Certificate:
    """:func:`certify` for a piecewise polynomial FFD: ``pieces`` are ``(control, lo, hi)``,
    the Bezier control points (a, b, c, 3) of the map on the lattice-coordinate box
    ``lo..hi``.

    Depth first, the half with the smaller coefficients first (a fold is found early),
    so at most a few dozen boxes are held at once; at most ``max_boxes`` boxes (and
    :data:`MAX_NUMBERS` coefficients in all) are examined."""
    sign = float(np.sign(np.linalg.det(lattice.axes)))
    to_world = abs(1.0 / np.linalg.det(lattice.axes))
    stack: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    bound = 0.0
    for control, lo, hi in pieces:
        width = np.asarray(hi, float) - np.asarray(lo, float)
        # the piece's det is per its own unit box: d(piece)/d(lattice) scales it
        scale = 1.0 / float(np.prod(width))
        coeffs = determinant_coefficients(control) * (sign * scale)
        bound = max(bound, rounding_bound(control) * scale)
        stack.append((np.asarray(lo, float), width, coeffs))
    budget = min(max_boxes, max(64, MAX_NUMBERS // max(c.size for _, _, c in stack)))
    cell = 1.0 / occupancy.cells if occupancy is not None else MIN_WIDTH
    boxes, lower, undecided = 0, np.inf, False
    while stack:
        lo, width, coeffs = stack.pop()
        low = float(coeffs.min())
        if low > bound:  # proven positive on this box, wherever the solid lies in it
            boxes += 1
            lower = min(lower, low)
            continue
        # not proven: only the part of the box the solid meets matters (the occupancy
        # grid is built on this first need)
        meets, within = (True, True) if occupancy is None else occupancy.block(lo, lo + width)
        if not meets:
            continue
        boxes += 1
        # a fold may be here: det J at a few points of the box, checked inside the solid
        # (at once where the box is wholly inside; by winding numbers where it holds the
        # surface, on its last split)
        last = boxes >= budget or width.max() <= (cell if not within else MIN_WIDTH)
        if low <= 0 and (within or last):
            found = _fold_in(coeffs, lo, width, occupancy, within, 4 if last else 1)
            if found is not None:
                point, value = found
                world = lattice.origin + point @ lattice.axes
                det = value * to_world
                return Certificate(False, world, det, boxes, min(lower, low) * to_world)
        if last:
            undecided = True
            lower = min(lower, low)
            continue
        axis = int(np.argmax(width))
        half = width.copy()
        half[axis] *= 0.5
        first, second = _split(coeffs, axis)
        lo_second = lo.copy()
        lo_second[axis] += half[axis]
        parts = [(lo, half, first), (lo_second, half, second)]
        parts.sort(key=lambda p: -float(p[2].min()))  # the smaller minimum is popped first
        stack.extend(parts)
    lower = lower if np.isfinite(lower) else 1.0 / to_world
    return Certificate(not undecided, None, float("nan"), boxes, float(lower) * to_world)


def _fold_in(coeffs, lo, width, occupancy, within: bool, per_axis: int):
    """A (lattice point, det) in the box, inside the solid, where det <= 0; or None. The
    points: the corners (their coefficients are the values there) and a grid of
    ``per_axis**3`` points at the centres of the box's parts."""
    from ..lattice import bernstein

    t = (np.arange(per_axis) + 0.5) / per_axis
    grid = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    bases = [bernstein(coeffs.shape[a] - 1, grid[:, a]) for a in range(3)]
    values = np.einsum("ijk,pi,pj,pk->p", coeffs, *bases)
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    corner_values = coeffs[np.ix_((0, -1), (0, -1), (0, -1))].reshape(-1)
    points = lo + width * np.concatenate([grid, corners])
    values = np.concatenate([values, corner_values])
    low = values <= 0
    if not low.any():
        return None
    candidates = np.flatnonzero(low)
    if not within:
        candidates = candidates[occupancy.inside(points[candidates])]
    if not len(candidates):
        return None
    best = candidates[np.argmin(values[candidates])]
    return points[best], float(values[best])
