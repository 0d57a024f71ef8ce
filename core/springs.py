"""The spring network between lattice nodes (paper Eq 14).

``E = sum_j k/2 (|X_e - X_s| - L_j)^2`` (the square is lost in the paper's typesetting).
Every node is linked to up to 14 neighbours: its 6 axis neighbours and its 8 body-diagonal
neighbours. That set is mirror-symmetric, so a symmetric squash stays symmetric; the other
reading of "14 neighbours" (the edges of a 6-tetrahedra split of each cell) is not, and
twists the lattice under a symmetric squash. Rest lengths come from the rest lattice, so the
energy is zero for the rest lattice and for any rigid motion of it.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .kernels import step as stepkernels

#: Undirected neighbour offsets: 3 axis directions and 4 body diagonals. Each node meets
#: each offset forwards and backwards, hence 6 + 8 = 14 neighbours.
OFFSETS = np.array(
    [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)]
)


def lattice_springs(shape: tuple[int, int, int]) -> np.ndarray:
    """(s, 2) node-row pairs of every spring of a lattice of ``shape`` nodes."""
    l, m, n = shape
    idx = np.arange(l * m * n).reshape(l, m, n)
    pairs = []
    for di, dj, dk in OFFSETS:
        src = idx[
            max(0, -di) : l - max(0, di), max(0, -dj) : m - max(0, dj), max(0, -dk) : n - max(0, dk)
        ]
        dst = idx[
            max(0, di) : l + min(0, di), max(0, dj) : m + min(0, dj), max(0, dk) : n + min(0, dk)
        ]
        pairs.append(np.stack([src.ravel(), dst.ravel()], axis=1))
    return np.concatenate(pairs)


#: node x spring entries up to which the incidence product is dense (about 1 MB of float64)
DENSE_INCIDENCE = 150_000

#: above this many node coordinates the solver's curvature matrices are sparse (the
#: springs' Hessian, the fold guard's Gauss-Newton term, their factorisation in
#: :mod:`core.solve.precondition`); the Bernstein basis's largest lattice (10x10x10, 3000)
#: stays dense as before, the local bases' dense lattices (16x16x16: 12288) go sparse
SPARSE_VARIABLES = 3000


def sparse_hessian(n_nodes: int) -> bool:
    """Whether a lattice of ``n_nodes`` nodes takes the sparse curvature matrices."""
    return 3 * int(n_nodes) > SPARSE_VARIABLES


class SpringNetwork:
    """Spring energy and gradient over node positions.

    Parameters
    ----------
    edges : (s, 2) int, node rows of each spring
    rest_nodes : (nodes, 3) float64, positions that define the natural lengths
    stiffness : the spring constant k, the same for every spring
    """

    def __init__(self, edges: np.ndarray, rest_nodes: np.ndarray, stiffness: float = 1.0) -> None:
        self.edges = np.asarray(edges, dtype=np.int64)
        self._starts = np.ascontiguousarray(self.edges[:, 0])
        self._ends = np.ascontiguousarray(self.edges[:, 1])
        self.stiffness = float(stiffness)
        self.rest_lengths = self.lengths(rest_nodes)
        self.n_nodes = len(rest_nodes)
        # (nodes, springs): +1 at a spring's end node, -1 at its start node; gathers the
        # spring forces onto the nodes in one product. Dense up to DENSE_INCIDENCE entries:
        # there it costs a few microseconds where scipy's sparse product costs ten in call
        # overhead alone (small lattices, every step).
        s = len(self.edges)
        self._gather = sp.csr_matrix(
            (
                np.r_[np.ones(s), -np.ones(s)],
                (np.r_[self.edges[:, 1], self.edges[:, 0]], np.r_[np.arange(s), np.arange(s)]),
            ),
            shape=(self.n_nodes, s),
        )
        if self.n_nodes * s <= DENSE_INCIDENCE:
            self._gather = self._gather.toarray()

    @classmethod
    def for_lattice(cls, shape: tuple[int, int, int], rest_nodes: np.ndarray) -> SpringNetwork:
        return cls(lattice_springs(shape), rest_nodes)

    def _vectors(self, nodes: np.ndarray) -> np.ndarray:
        """(s, 3) each spring's end minus its start."""
        nodes = np.asarray(nodes, dtype=np.float64)
        return nodes.take(self._ends, axis=0) - nodes.take(self._starts, axis=0)

    def lengths(self, nodes: np.ndarray) -> np.ndarray:
        """(s,) current spring lengths."""
        d = self._vectors(nodes)
        return np.sqrt(np.einsum("ij,ij->i", d, d))

    def energy(self, nodes: np.ndarray) -> float:
        stretch = self.lengths(nodes) - self.rest_lengths
        return 0.5 * self.stiffness * float(stretch @ stretch)

    def energy_and_gradient(self, nodes: np.ndarray) -> tuple[float, np.ndarray]:
        """Energy and its gradient ``(nodes, 3)``."""
        nodes = np.ascontiguousarray(nodes, dtype=np.float64)
        out = stepkernels.springs(nodes, *self._compiled)
        if out is not None:
            return out
        d = self._vectors(nodes)
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        stretch = length - self.rest_lengths
        energy = 0.5 * self.stiffness * float(np.einsum("i,i->", stretch, stretch))
        # d|d|/d(end) = d/|d|; a zero-length spring pulls in no defined direction.
        safe = np.where(length > 0, length, 1.0)
        force = (self.stiffness * stretch / safe)[:, None] * d
        return energy, self._gather @ force

    def hessian(self, nodes: np.ndarray):
        """A positive semi-definite approximation of the energy's Hessian at ``nodes``:
        ``(3 nodes, 3 nodes)``, rows and columns ordered as ``nodes.ravel()``: dense, or a
        sparse CSR matrix above :data:`SPARSE_VARIABLES` coordinates.

        Per spring the exact block is ``k (u u^T + (1 - L/l) (I - u u^T))`` on the
        difference of its ends (``u`` the unit direction, ``l`` the length, ``L`` the rest
        length); the second term is dropped where it is negative (a compressed spring), so
        the matrix stays a valid preconditioner. Exact for every stretched spring."""
        nodes = np.ascontiguousarray(nodes, dtype=np.float64)
        big = sparse_hessian(self.n_nodes)
        out = None if big else stepkernels.spring_hessian(nodes, *self._compiled)
        if out is not None:
            return out
        d = self._vectors(nodes)
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        safe = np.where(length > 0, length, 1.0)
        u = d / safe[:, None]
        bend = np.clip(1.0 - self.rest_lengths / safe, 0.0, None)
        outer = u[:, :, None] * u[:, None, :]
        block = self.stiffness * (outer + bend[:, None, None] * (np.eye(3) - outer))  # (s,3,3)
        n = 3 * self.n_nodes
        weights = np.repeat(np.concatenate([block, -block]).ravel(), 2)
        if big:
            indptr, indices, inverse = self._sparse_pattern
            data = np.bincount(inverse, weights, len(indices))
            return sp.csr_matrix((data, indices, indptr), shape=(n, n))
        flat = np.bincount(self._hessian_cells, weights, n * n)
        return flat.reshape(n, n)

    @property
    def _compiled(self) -> tuple:
        """The springs as the compiled kernels take them (:func:`core.kernels.step.springs`)."""
        return self._starts, self._ends, self.rest_lengths, self.stiffness

    @cached_property
    def _sparse_pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The sparse Hessian's CSR pattern (indptr, indices) and, for each entry of
        :attr:`_hessian_cells`, the place of its cell among the pattern's: the pattern is
        the same at every call, so a call only sums the weights into it."""
        n = 3 * self.n_nodes
        cells, inverse = np.unique(self._hessian_cells, return_inverse=True)
        rows, cols = np.divmod(cells, n)
        indptr = np.searchsorted(rows, np.arange(n + 1)).astype(np.int64)
        return indptr, cols.astype(np.int64), inverse.ravel()

    @cached_property
    def _hessian_cells(self) -> np.ndarray:
        """Flat (row, column) cells of the dense Hessian that each spring's block adds to:
        the block at (a, a) and (b, b), minus it at (a, b) and (b, a); as
        ``[aa, bb of each block entry | ab, ba of each]``: each entry of ``block`` and then
        of ``-block`` twice in a row."""
        n = 3 * self.n_nodes
        a, b = 3 * self.edges[:, 0], 3 * self.edges[:, 1]
        r3, c3 = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")

        def cells(p, q):
            return ((p[:, None, None] + r3) * n + (q[:, None, None] + c3)).ravel()

        same = np.stack([cells(a, a), cells(b, b)], axis=1)  # (9 s, 2)
        cross = np.stack([cells(a, b), cells(b, a)], axis=1)
        return np.concatenate([same, cross]).ravel()
