"""The editable states and what a solve says about them (Qt-free).

A :class:`DocState` is one complete state the user edits: the problem (model pyramid +
lattice), the node positions, which node coordinates are pinned and which nodes were placed
by the user, what the solve must hold (its :class:`~isochor.core.goal.spec.Goal`: the
target volume and the rest), and, once a solve ended on exactly this state, its
:class:`SolveSummary`. A result's summary belongs to the state it solved: a state made by an
edit has none, so the statistics of another state can never stay on screen.
:class:`StateCell` is the mutable box undo works on; :func:`describe_status` is what the
status bar says about a state, the ``*_sentence`` functions what the Solve panel adds.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...core.goal.handles import Handle, handles_sentence
from ...core.goal.spec import Goal
from ...core.goal.symmetry import Mirror
from ...core.scenario.problem import Problem
from ...core.solve.records import BodyVolume
from .timeline import TimelineState

AXES = "xyz"


def _ro(a, dtype=None) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.flags.writeable = False
    return a


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` (a fresh array) made read-only: a view of a state is no way to edit it."""
    a.flags.writeable = False
    return a


def lead_rows(mirror: Mirror, rows) -> np.ndarray:
    """The ``rows`` whose places are mirrored onto their partners: all of them, but of a
    pair of partners both in ``rows`` only the first (the other follows it)."""
    rows = np.unique(np.asarray(rows, dtype=int))
    partner = np.asarray(mirror.partner)[rows]
    return rows[~np.isin(partner, rows) | (partner >= rows)]


def plural(n: int, word: str = "node") -> str:
    """``"1 node"``, ``"3 nodes"``."""
    return f"{n} {word}{'' if n == 1 else 's'}"


def axes_words(mask) -> str:
    """``"z"``, ``"x and y"``, ``"x, y and z"`` for a (3,) bool mask of axes."""
    names = [a for a, on in zip(AXES, mask) if on]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def percent(fraction: float) -> str:
    """``"3.2%"``, ``"51%"``, ``"0.18%"``: two significant digits, never an exponent."""
    p = 100.0 * float(fraction)
    return f"{p:.0f}%" if p >= 10 else f"{p:.2g}%"


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
    held: tuple[int, ...] = ()  #: node rows the far-side anchor held
    held_face: str = ""  #: which lattice face they are ("x max", ...), "" for none
    #: :class:`isochor.core.goal.folds.Folds` of the result (its ``vertices`` mask is over the
    #: full mesh's vertices), None when unknown
    folds: object | None = field(default=None, compare=False, repr=False)
    bodies: tuple[BodyVolume, ...] = ()  #: per body, when the model has several
    centroid_shift: float | None = None  #: |C - C0| / size, with keep_centroid
    #: where each handle's point ended (:class:`isochor.core.goal.handles.HandleResult`)
    handles: tuple = ()

    @classmethod
    def of(cls, result, n_levels: int) -> SolveSummary:
        """The summary of a :class:`isochor.core.solve.multilevel.SolveResult`."""
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
            tuple(int(r) for r in result.held),
            result.held_face,
            result.folds,
            tuple(result.bodies),
            result.centroid_shift,
            tuple(getattr(result, "handles", ())),
        )

    @property
    def handles_sentence(self) -> str:
        """ "" when every handle was met, else how far they were fitted."""
        return handles_sentence(self.handles)

    @property
    def folded(self) -> bool:
        """Part of the model is turned inside out."""
        return self.folds is not None and bool(self.folds.folded)

    @property
    def folded_vertices(self) -> np.ndarray | None:
        """(m,) bool over the full mesh's vertices: the folded ones (None: not folded)."""
        return np.asarray(self.folds.vertices, dtype=bool) if self.folded else None

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
    """One complete editable state. Arrays are read-only copies.

    ``pin_axes`` says which coordinates of each node the user pinned (at any position): a
    node pinned on z keeps its z and the solver moves it in x and y. Given an (n,) mask, a
    node is pinned on all three axes. A moved node is fixed on all three.

    ``goal`` is what the solve of this state must hold (the target volume and the rest of
    the :class:`~isochor.core.goal.spec.Goal`); its ``preserve`` is "total" or "per-body",
    not the window's "Preserve volume" switch (``Document.preserve``).
    ``handles`` are the user's surface handles (their mirror images under symmetry are
    added by the solve).
    """

    problem: Problem
    nodes: np.ndarray  #: (n, 3) node positions
    pin_axes: np.ndarray  #: (n, 3) bool, the coordinates pinned by the user
    moved: np.ndarray  #: (n,) bool, placed by the user; fixed until unpinned
    goal: Goal = Goal()  #: what the solve of this state must hold
    solved: bool = False  #: the solver ran to its end on exactly these nodes and flags
    result: SolveSummary | None = None  #: the summary of that solve (None: at rest)
    handles: tuple[Handle, ...] = ()
    timeline: TimelineState = TimelineState()  #: the keys and the timeline's settings

    def __post_init__(self) -> None:
        n = self.problem.surface.lattice.n_nodes
        object.__setattr__(self, "nodes", _ro(np.reshape(self.nodes, (n, 3)), np.float64))
        pins = np.asarray(self.pin_axes, dtype=bool)
        pins = np.repeat(pins.reshape(n, 1), 3, axis=1) if pins.size == n else pins
        object.__setattr__(self, "pin_axes", _ro(np.reshape(pins, (n, 3)), bool))
        object.__setattr__(self, "moved", _ro(np.reshape(self.moved, n), bool))
        object.__setattr__(self, "handles", tuple(Handle.of(h) for h in self.handles))

    @property
    def pinned(self) -> np.ndarray:
        """(n,) bool: pinned on at least one axis."""
        return _frozen(self.pin_axes.any(axis=1))

    @property
    def axis_pinned(self) -> np.ndarray:
        """(n,) bool: pinned on some axes but not all, and not moved (free on the others)."""
        return _frozen(self.pinned & ~self.pin_axes.all(axis=1) & ~self.moved)

    @property
    def fixed(self) -> np.ndarray:
        """(n,) bool: nodes the solver may not move freely (pinned on any axis, or moved)."""
        return _frozen(self.pinned | self.moved)

    @property
    def fixed_axes(self) -> np.ndarray:
        """(n, 3) bool: the coordinates the solver may not move (pinned, or moved)."""
        return _frozen(self.pin_axes | self.moved[:, None])

    @property
    def mirror(self) -> Mirror | None:
        """The symmetry's mirror (None with symmetry off)."""
        return Mirror.of(self.lattice, self.goal.symmetry)

    def mirrored(self, rows) -> DocState:
        """With symmetry on: the positions, pins and moved flags of ``rows`` copied onto
        their mirror partners (nodes on the mirror plane put on it); else ``self``."""
        m = self.mirror
        rows = np.asarray(rows, dtype=int)
        if m is None or len(rows) == 0:
            return self
        rows = lead_rows(m, rows)
        nodes, pins = m.mirror_rows(self.nodes, self.pin_axes, rows)
        moved = self.moved.copy()
        moved[m.partner[rows]] = moved[rows]
        return replace(self, nodes=nodes, pin_axes=pins, moved=moved)

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
        """Pin ``rows`` on every axis, or unpin them (which also clears their moved flag)."""
        rows = np.asarray(rows, dtype=int)
        pins, moved = self.pin_axes.copy(), self.moved.copy()
        pins[rows] = pin
        if not pin:
            moved[rows] = False
        return self.edited(pin_axes=pins, moved=moved)

    def pinned_on(self, rows, axes) -> DocState:
        """Pin ``rows`` on exactly ``axes`` ((3,) or (k, 3) bool): a moved node restricted
        to fewer than three axes is moved no more (the solver moves it on the others)."""
        rows = np.asarray(rows, dtype=int)
        axes = np.broadcast_to(np.asarray(axes, dtype=bool), (len(rows), 3))
        pins, moved = self.pin_axes.copy(), self.moved.copy()
        pins[rows] = axes
        moved[rows] &= axes.all(axis=1)
        return self.edited(pin_axes=pins, moved=moved)

    def same_edit(self, other: DocState) -> bool:
        """True when both describe the same edit (nodes, flags, goal, problem)."""
        return (
            self.problem is other.problem
            and self.goal == other.goal
            and self.handles == other.handles
            and np.array_equal(self.nodes, other.nodes)
            and np.array_equal(self.pin_axes, other.pin_axes)
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
    pins = np.zeros((lat.n_nodes, 3), dtype=bool)
    for mv in sc.moves:
        moved[lat.index(*mv.node)] = True
    for p in sc.pins:
        pins[lat.index(*p)] = True
    for p, axes in sc.axis_pins:
        pins[lat.index(*p), [AXES.index(a) for a in axes]] = True
    # Nothing moved, no handle and the volume kept: the rest lattice is already the answer.
    at_rest = not moved.any() and not sc.handles and sc.goal.target_ratio == 1.0
    return DocState(
        problem,
        problem.nodes,
        pins,
        moved,
        goal=sc.goal,
        solved=at_rest,
        handles=sc.handles,
        timeline=TimelineState.of(sc),
    )


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
    if activity != "failed" and state.solved and r is not None and r.folded:
        return "Folded", "bad", fold_sentence(r.folds.fraction)
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
        f"{plural(r.free_nodes, 'free node')}.{handles_note(r)}",
    )


def handles_note(r: SolveSummary) -> str:
    """What a result says about its handles: ``" 2 handles met."`` or the fit (" 2 handles
    cannot all be met: fitted by least squares, ..."); "" without handles."""
    if not r.handles:
        return ""
    fitted = r.handles_sentence
    if fitted:
        return f" {fitted[0].upper()}{fitted[1:]}."
    return " The handle is met." if len(r.handles) == 1 else f" All {len(r.handles)} handles met."


def fold_sentence(fraction: float) -> str:
    """What a folded result means and what to do about it."""
    return (
        f"Folded: {percent(fraction)} of the model is inside out — undo, pin fewer nodes "
        "or move less."
    )


def held_sentence(count: int, face: str) -> str:
    """What the far-side anchor holds ("" when nothing)."""
    if not count or not face:
        return ""
    return (
        f"Holding the {face} face ({plural(count)}) so the model does not drift — "
        "untick Hold far side to let it move."
    )


def bodies_sentence(bodies) -> str:
    """Each body's final volume over its original, when there are several ("" else)."""
    if len(bodies) < 2:
        return ""
    parts = [f"body {n} {100 * b.final / b.original:.2f} %" for n, b in enumerate(bodies, 1)]
    return "Volume of each body: " + " · ".join(parts)


def centroid_sentence(shift: float | None) -> str:
    """How far the centre of mass moved ("" when it was not kept)."""
    if shift is None:
        return ""
    pct = 100 * float(shift)
    amount = "less than 0.001 %" if pct < 0.001 else f"{pct:.3f} %"
    return f"Centre of mass moved {amount} of the model's size."
