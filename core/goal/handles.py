"""Surface handles: points of the model that must land where the user dropped them.

The paper's future work ("direct manipulation": linear constraints on the nodes). A handle
is a point ``at`` of the model at rest and the place ``to`` it must move to. The FFD maps
``at`` to ``p(X) = sum_j w_j X_j`` with the Bernstein weights ``w_j`` of ``at``'s lattice
coordinates, so a handle is three *linear* equality constraints on the nodes, the same on
every pyramid level (no discretisation error), and they join the goal's constraints in the
augmented Lagrangian (:mod:`isochor.core.goal.constraints`).

More handles than the lattice can meet (two handles on one point dragged apart, a dozen
handles on a 2x2x2 lattice, handles that would leave the volume no free node to use) must
not make the solver chase an impossible equality. :class:`HandleSystem` takes the singular
value decomposition of the handle rows over the solve's free coordinates and keeps only the
directions they can reach, at most ``free - goal constraints`` of them:

* the rows' targets are projected on the reachable directions, so a consistent set is met
  exactly and an inconsistent one is met in the least-squares sense (the residual that
  is left is orthogonal to everything the free nodes can do);
* the result says how far each handle ended from its target (:class:`HandleResult`); a
  handle that misses by more than :data:`HANDLE_MET` of the size is reported as fitted.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike

from ..errors import IsochorError
from ..lattice import Lattice, bernstein

#: a handle residual counts as met within this fraction of ``tol_volume`` of the size
#: (0.1 x 5e-4: a handle lands within 5e-5 of the model's size of its target)
HANDLE_SCALE = 0.1
#: a handle farther than this from its target, in model sizes, is "not met"
HANDLE_MET = 1e-3


def _point(value, where: str) -> tuple[float, float, float]:
    try:
        p = np.asarray(value, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise IsochorError(f"{where}: must be three numbers [x, y, z]") from None
    if not np.all(np.isfinite(p)):
        raise IsochorError(f"{where}: must be three finite numbers, got {list(p)}")
    return cast("tuple[float, float, float]", tuple(float(a) for a in p))  # p has 3 entries


@dataclass(frozen=True, init=False)
class Handle:
    """A point of the model at rest (``at``) and where it must be after the solve (``to``),
    both in world units."""

    at: tuple[float, float, float]
    to: tuple[float, float, float]

    def __init__(self, at: ArrayLike, to: ArrayLike) -> None:
        object.__setattr__(self, "at", _point(at, "handle.at"))
        object.__setattr__(self, "to", _point(to, "handle.to"))

    def moved_to(self, to) -> Handle:
        return Handle(self.at, to)

    @classmethod
    def of(cls, obj: Any) -> Handle:
        """A handle from a :class:`Handle`, ``{"at": .., "to": ..}`` or ``(at, to)``."""
        if isinstance(obj, Handle):
            return obj
        if isinstance(obj, Mapping) and set(obj) == {"at", "to"}:
            return cls(obj["at"], obj["to"])
        if isinstance(obj, Sequence) and not isinstance(obj, str) and len(obj) == 2:
            return cls(*obj)
        raise IsochorError(f'a handle is {{"at": [x, y, z], "to": [x, y, z]}}, got {obj!r:.60}')


@dataclass(frozen=True)
class HandleResult:
    """Where one handle's point ended: ``reached`` and its distance from ``to`` over the
    model's size (``miss``)."""

    at: tuple[float, float, float]
    to: tuple[float, float, float]
    reached: tuple[float, float, float]
    miss: float

    @property
    def met(self) -> bool:
        return self.miss <= HANDLE_MET


def weights(lattice: Lattice, points: np.ndarray) -> np.ndarray:
    """(p, nodes) FFD weights of rest points (Eq 4's node order): ``deformed = W @ nodes``
    for the Bernstein basis; a local basis (:mod:`isochor.core.localbasis`) adds a per-point
    offset (:meth:`isochor.core.lattice.Lattice.weights`)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if lattice.local:
        return lattice.weights(points)[0].toarray()
    uvw = lattice.to_parameters(points)
    l, m, n = lattice.shape
    bu, bv, bw = (bernstein(d - 1, uvw[:, a]) for a, d in enumerate((l, m, n)))
    return np.einsum("pi,pj,pk->pijk", bu, bv, bw).reshape(len(uvw), l * m * n)


def handle_rows(lattice: Lattice, handles: Sequence[Handle]) -> tuple[np.ndarray, np.ndarray]:
    """The handles as linear equations ``rows . X = b``: rows (3h, nodes, 3), b (3h,)."""
    h, n = len(handles), lattice.n_nodes
    at = np.array([hd.at for hd in handles], dtype=np.float64).reshape(h, 3)
    w = weights(lattice, at)
    rows = np.zeros((h, 3, n, 3))
    for a in range(3):
        rows[:, a, :, a] = w
    b = np.array([hd.to for hd in handles], dtype=np.float64).reshape(h, 3)
    if lattice.local:  # a local basis: deformed = W X + offset
        b = b - lattice.weights(at)[1]
    return rows.reshape(3 * h, n, 3), b.reshape(3 * h)


class HandleSystem:
    """The handles of one solve as linear constraints ``c(X) (k,)`` with a constant Jacobian
    ``(k, nodes, 3)``, reduced to the directions the free coordinates can reach.

    Parameters
    ----------
    lattice : the solve's lattice
    handles : the handles (mirrored ones included, under symmetry)
    nodes : (n, 3) the start nodes (their fixed coordinates stay)
    reduce : ``(m, n, 3) -> (m, free)``: a Jacobian over the free coordinates
    spare : free coordinates to leave to the goal's own constraints (volume, centroid)
    size : object size
    equations : :func:`handle_rows` of ``handles``, when the caller has them already
    """

    def __init__(
        self,
        lattice: Lattice,
        handles: Sequence[Handle],
        nodes: np.ndarray,
        reduce: Callable[[np.ndarray], np.ndarray],
        spare: int,
        size: float,
        equations: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        self.handles = tuple(handles)
        self.lattice, self.size = lattice, float(size)
        h = len(self.handles)
        rows, b = equations if equations is not None else handle_rows(lattice, self.handles)
        reduced = reduce(rows)
        free = reduced.shape[1]
        if reduced.size and np.abs(reduced).max() > 0:
            u, s, _ = np.linalg.svd(reduced, full_matrices=False)
            rank = int(np.sum(s > 1e-9 * s[0]))
        else:
            u, rank = np.zeros((3 * h, 0)), 0
        self.rank = rank
        self.count = max(0, min(rank, free - spare))
        keep = u[:, : self.count].T  # (k, 3h): orthonormal reachable directions
        self.scale = HANDLE_SCALE * self.size
        self.rows = np.tensordot(keep, rows, axes=1)  # (k, n, 3)
        self.target = keep @ b
        self.jacobian = self.rows / self.scale
        #: the least-squares residual no free node can remove, before any solve
        residual = rows.reshape(3 * h, -1) @ np.asarray(nodes, dtype=np.float64).ravel() - b
        self.unreachable = float(
            np.linalg.norm(residual - u[:, :rank] @ (u[:, :rank].T @ residual)) / self.size
        )

    def values(self, nodes: np.ndarray) -> np.ndarray:
        flat = self.rows.reshape(self.count, -1)
        return (flat @ np.asarray(nodes).ravel() - self.target) / self.scale

    def results(self, nodes: np.ndarray, count: int | None = None) -> tuple[HandleResult, ...]:
        """Where the first ``count`` handles (the user's, without their mirrors) ended."""
        hs = self.handles[: len(self.handles) if count is None else count]
        if not hs:
            return ()
        at = np.array([hd.at for hd in hs])
        reached = self.lattice.deform(at, nodes)
        miss = np.linalg.norm(reached - np.array([hd.to for hd in hs]), axis=1) / self.size
        return tuple(
            HandleResult(
                hd.at,
                hd.to,
                cast("tuple[float, float, float]", tuple(float(a) for a in r)),
                float(m),
            )
            for hd, r, m in zip(hs, reached, miss)
        )


def handles_sentence(results: Sequence[HandleResult]) -> str:
    """'' when every handle is met, else one sentence saying how far they were fitted."""
    missed = [r for r in results if not r.met]
    if not missed:
        return ""
    worst = max(r.miss for r in results)
    n = len(results)
    return (
        f"{'the handle' if n == 1 else f'{n} handles'} cannot {'be' if n == 1 else 'all be'} "
        f"met: fitted by least squares, largest miss {100 * worst:.3g}% of the size"
    )
