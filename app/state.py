"""The editable states and what a solve says about them (Qt-free).

A :class:`DocState` is one complete state the user edits: the problem (model pyramid +
lattice), the node positions, which nodes are pinned and which were placed by the user, the
target volume, and, once a solve ended on exactly this state, its :class:`SolveSummary`. A
result's summary belongs to the state it solved: a state made by an edit has none, so the
statistics of another state can never stay on screen. :class:`StateCell` is the mutable box
undo works on; :func:`describe_status` is what the status bar says about a state.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..core.problem import Problem


def _ro(a, dtype=None) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.flags.writeable = False
    return a


def plural(n: int, word: str = "node") -> str:
    """``"1 node"``, ``"3 nodes"``."""
    return f"{n} {word}{'' if n == 1 else 's'}"


@dataclass(frozen=True)
class SolveSummary:
    """What a finished solve says about the state it solved (shown with that state only)."""

    converged: bool
    message: str = ""
    levels: tuple[int, ...] = ()  #: the pyramid levels solved, 0 = coarsest
    n_levels: int = 0
    rel_volume_error: float = 0.0  #: on the full-resolution mesh
    free_nodes: int = 0
    sigma: float = 0.0
    lam: float = 0.0
    elapsed: float = 0.0

    @classmethod
    def of(cls, result, n_levels: int) -> SolveSummary:
        """The summary of a :class:`isochor.core.multilevel.SolveResult`."""
        return cls(
            bool(result.converged),
            result.message,
            tuple(s.level for s in result.levels),
            n_levels,
            float(result.rel_volume_error),
            int(result.free_nodes),
            float(result.sigma),
            float(result.lam),
            float(result.elapsed),
        )

    @classmethod
    def failed(cls, message: str) -> SolveSummary:
        return cls(False, message)

    def span(self) -> str:
        """``"Solved levels 4-5 of 7"`` (levels counted from 1, coarsest first)."""
        if not self.levels:
            return "Solved no level"
        first, last = self.levels[0] + 1, self.levels[-1] + 1
        what = f"level {first}" if first == last else f"levels {first}–{last}"
        return f"Solved {what} of {self.n_levels}"


@dataclass(frozen=True, eq=False)
class DocState:
    """One complete editable state. Arrays are read-only copies."""

    problem: Problem
    nodes: np.ndarray  #: (n, 3) node positions
    pinned: np.ndarray  #: (n,) bool, pinned by the user (at any position)
    moved: np.ndarray  #: (n,) bool, placed by the user; fixed until unpinned
    target_ratio: float = 1.0
    solved: bool = False  #: the solver ran to its end on exactly these nodes and flags
    result: SolveSummary | None = None  #: the summary of that solve (None: at rest)

    def __post_init__(self) -> None:
        n = self.problem.surface.lattice.n_nodes
        object.__setattr__(self, "nodes", _ro(np.reshape(self.nodes, (n, 3)), np.float64))
        object.__setattr__(self, "pinned", _ro(np.reshape(self.pinned, n), bool))
        object.__setattr__(self, "moved", _ro(np.reshape(self.moved, n), bool))

    @property
    def fixed(self) -> np.ndarray:
        """(n,) bool: nodes the solver may not move (pinned or moved)."""
        return self.pinned | self.moved

    @property
    def surface(self):
        return self.problem.surface

    @property
    def lattice(self):
        return self.problem.surface.lattice

    @property
    def converged(self) -> bool:
        """Solved and within the tolerances (a state at rest counts as converged)."""
        return self.solved and (self.result is None or self.result.converged)

    def edited(self, **changes) -> DocState:
        """A new state made by an edit: not solved, no result."""
        changes.setdefault("solved", False)
        changes.setdefault("result", None)
        return replace(self, **changes)

    def moved_to(self, nodes: np.ndarray, rows) -> DocState:
        """The user placed ``rows`` at ``nodes[rows]``: they become moved (fixed)."""
        moved = self.moved.copy()
        moved[np.asarray(rows, dtype=int)] = True
        return self.edited(nodes=nodes, moved=moved)

    def pinned_as(self, rows, pin: bool) -> DocState:
        """Pin ``rows``, or unpin them (which also clears their moved flag)."""
        rows = np.asarray(rows, dtype=int)
        pinned, moved = self.pinned.copy(), self.moved.copy()
        pinned[rows] = pin
        if not pin:
            moved[rows] = False
        return self.edited(pinned=pinned, moved=moved)

    def same_edit(self, other: DocState) -> bool:
        """True when both describe the same edit (nodes, flags, target, problem)."""
        return (
            self.problem is other.problem
            and self.target_ratio == other.target_ratio
            and np.array_equal(self.nodes, other.nodes)
            and np.array_equal(self.pinned, other.pinned)
            and np.array_equal(self.moved, other.moved)
        )


class StateCell:
    """A mutable box around one :class:`DocState` (see the module notes on undo)."""

    __slots__ = ("state",)

    def __init__(self, state: DocState) -> None:
        self.state = state

    def __repr__(self) -> str:
        return f"StateCell(solved={self.state.solved})"


def initial_state(problem: Problem) -> DocState:
    """The state a freshly built problem starts in: its moves applied, its pins set."""
    sc = problem.scenario
    lat = problem.surface.lattice
    moved = np.zeros(lat.n_nodes, dtype=bool)
    pinned = np.zeros(lat.n_nodes, dtype=bool)
    for mv in sc.moves:
        moved[lat.index(*mv.node)] = True
    for p in sc.pins:
        pinned[lat.index(*p)] = True
    # Nothing moved and the volume kept: the rest lattice is already the answer.
    at_rest = not moved.any() and sc.target_volume_ratio == 1.0
    return DocState(problem, problem.nodes, pinned, moved, sc.target_volume_ratio, solved=at_rest)


def describe_status(state: DocState, *, preserve: bool, activity: str) -> tuple[str, str, str]:
    """What the status chip and the Solve panel say: ``(chip, tone, sentence)``.

    ``activity`` is what the session is doing: ``"idle"``, ``"solving"``, ``"dragging"``,
    ``"stopped"`` (the user stopped the solve) or ``"failed"``. ``tone`` is one of
    ``"neutral"``, ``"busy"``, ``"good"`` and ``"bad"``.
    """
    if not preserve:
        return ("Plain FFD", "neutral", "Volume constraint off: plain free-form deformation.")
    if activity == "dragging":
        return "Dragging", "busy", "Release to solve."
    if activity == "solving":
        return "Solving…", "busy", "Solving…"
    r = state.result
    if activity == "failed" or (state.solved and r is not None and not r.converged):
        return (
            "Not converged" if activity != "failed" else "Solver failed",
            "bad",
            (r.message if r is not None and r.message else "The solve did not converge."),
        )
    if activity == "stopped" and not state.solved:
        return "Stopped", "neutral", "Stopped before converging: Solve again to finish."
    if not state.solved:
        return "Edited", "neutral", "Not solved yet."
    if r is None:
        return "At rest", "good", "At rest: nothing to solve."
    return (
        "Converged",
        "good",
        f"Converged: |dV|/V0 = {abs(r.rel_volume_error):.1e} on the full mesh, "
        f"{plural(r.free_nodes, 'free node')}.",
    )
