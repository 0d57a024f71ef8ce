"""The editable document: a built problem plus the node state the user is working on.

Qt-free, so it can be tested and reasoned about without a window.

The state the user edits is a :class:`DocState`: the problem (model pyramid + lattice), the
node positions, which nodes are pinned and which were moved by the user, the target volume
and whether the solver already ran on exactly this state. A moved node counts as pinned
until it is unpinned (then both flags clear and the solver may move it again).

Undo works on :class:`StateCell` objects: mutable boxes around one ``DocState``. The
current cell is shared between the undo command that produced it (its ``after``) and the
next command (its ``before``). When a solve started from a cell finishes, the cell is
updated in place with the solved nodes, so undo and redo land on solved states without
solving again.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from core.errors import IsochorError
from core.examples import example_scenario
from core.mesh import TriMesh
from core.scenario import Move, Problem, Scenario, build, model_levels

#: File suffixes opened as models; everything else must be a scenario (.json).
MODEL_SUFFIXES = (".obj", ".ply", ".stl", ".off")
SCENARIO_SUFFIXES = (".json",)
#: Lattice resolution the editor offers per axis.
LATTICE_MIN, LATTICE_MAX = 2, 8


def _ro(a: np.ndarray, dtype=None) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class DocState:
    """One complete editable state. Arrays are read-only copies."""

    problem: Problem
    nodes: np.ndarray  #: (n, 3) node positions
    pinned: np.ndarray  #: (n,) bool, pinned by the user (at any position)
    moved: np.ndarray  #: (n,) bool, placed by the user; fixed until unpinned
    target_ratio: float = 1.0
    solved: bool = False  #: the solver ran to its end on exactly these nodes and flags
    converged: bool = True  #: when solved: whether it met the tolerances
    message: str = ""  #: when solved: the solver's note, if any

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

    def with_(self, **changes) -> DocState:
        changes.setdefault("solved", False)
        changes.setdefault("converged", True)
        changes.setdefault("message", "")
        return replace(self, **changes)

    def moved_to(self, nodes: np.ndarray, rows) -> DocState:
        """The user placed ``rows`` at ``nodes[rows]``: they become moved (fixed)."""
        moved = self.moved.copy()
        moved[np.asarray(rows, dtype=int)] = True
        return self.with_(nodes=nodes, moved=moved)

    def pinned_as(self, rows, pin: bool) -> DocState:
        """Pin ``rows``, or unpin them (which also clears their moved flag)."""
        rows = np.asarray(rows, dtype=int)
        pinned, moved = self.pinned.copy(), self.moved.copy()
        pinned[rows] = pin
        if not pin:
            moved[rows] = False
        return self.with_(pinned=pinned, moved=moved)

    def same_edit(self, other: DocState) -> bool:
        """True when both describe the same edit (nodes, flags, target, problem)."""
        return (self.problem is other.problem and self.target_ratio == other.target_ratio
                and np.array_equal(self.nodes, other.nodes)
                and np.array_equal(self.pinned, other.pinned)
                and np.array_equal(self.moved, other.moved))


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
    # Nothing fixed, nothing moved, volume kept: the rest lattice is already the answer.
    trivially_solved = not moved.any() and sc.target_volume_ratio == 1.0
    return DocState(problem, problem.nodes, pinned, moved, sc.target_volume_ratio,
                    solved=trivially_solved)


def default_lattice_shape(mesh: TriMesh) -> tuple[int, int, int]:
    """4 nodes along the model's longest extent, 3 along the others."""
    shape = [3, 3, 3]
    shape[int(np.argmax(mesh.extents))] = 4
    return tuple(shape)


class Document:
    """What the window edits: the current state cell, and where it came from.

    Attributes
    ----------
    cell : the current :class:`StateCell`
    path : the scenario file this document was read from or saved to, if any
    title : a short name for the window title
    """

    def __init__(self, problem: Problem, *, path: Path | None = None, title: str = "") -> None:
        self.cell = StateCell(initial_state(problem))
        self.path = path
        self.title = title or _model_title(problem.scenario)
        self._surfaces: dict[tuple, object] = {}
        prepare_surface(problem)

    # -- constructors ----------------------------------------------------------------------
    @classmethod
    def example(cls, name: str = "torus-compression") -> Document:
        return cls(build(example_scenario(name)), title=f"example: {name}")

    @classmethod
    def open(cls, path: str | Path) -> Document:
        """A model (OBJ, PLY, STL, OFF) in a default lattice, or a scenario (.json).

        Raises :class:`IsochorError` with a message to show as is."""
        path = Path(path).expanduser()
        suffix = path.suffix.lower()
        if suffix in SCENARIO_SUFFIXES:
            scenario = Scenario.read(path)
            return cls(build(scenario), path=path.resolve(), title=path.name)
        if suffix not in MODEL_SUFFIXES:
            raise IsochorError(
                f"{path.name}: unknown file type {path.suffix or '(none)'}; open a model "
                f"({', '.join(s[1:].upper() for s in MODEL_SUFFIXES)}) or a scenario (.json)."
            )
        if not path.is_file():
            raise IsochorError(f"{path}: no such file")
        scenario = Scenario.from_dict({"model": {"path": str(path.resolve())}})
        levels, warnings = model_levels(scenario)
        scenario = scenario.with_(lattice_nodes=default_lattice_shape(levels[-1]))
        problem = build(scenario, levels=levels, warnings=warnings)
        return cls(problem, title=path.name)

    # -- state -----------------------------------------------------------------------------
    @property
    def state(self) -> DocState:
        return self.cell.state

    @property
    def problem(self) -> Problem:
        return self.cell.state.problem

    @property
    def surface(self):
        return self.cell.state.problem.surface

    def rebuilt(self, shape: tuple[int, int, int]) -> DocState:
        """A state on a new lattice of ``shape`` nodes around the same model, at rest.

        Moves and pins are dropped (they name nodes of the old lattice); the model pyramid
        is reused, and a surface built before for the same shape is reused with its caches.
        """
        shape = tuple(int(s) for s in shape)
        if not all(LATTICE_MIN <= s <= LATTICE_MAX for s in shape):
            raise IsochorError(
                f"The editor offers {LATTICE_MIN} to {LATTICE_MAX} lattice nodes per axis."
            )
        old = self.problem
        scenario = old.scenario.with_(lattice_nodes=shape, moves=(), pins=())
        key = (shape, scenario.padding, scenario.frame)
        problem = self._surfaces.get(key)
        if problem is None:
            problem = build(scenario, levels=list(old.surface.levels), warnings=old.warnings)
            prepare_surface(problem)
        self._surfaces[_key(old)] = old
        state = initial_state(problem)
        return state.with_(target_ratio=self.state.target_ratio,
                           solved=self.state.target_ratio == 1.0)

    def scenario(self) -> Scenario:
        """The current state as a scenario: moved nodes as ``to`` moves, pins, target."""
        st = self.state
        lat = st.lattice
        moves = tuple(Move(lat.ijk(r), to=tuple(float(x) for x in st.nodes[r]))
                      for r in np.flatnonzero(st.moved))
        pins = tuple(lat.ijk(r) for r in np.flatnonzero(st.pinned & ~st.moved))
        return st.problem.scenario.with_(moves=moves, pins=pins,
                                         target_volume_ratio=float(st.target_ratio))

    def save(self, path: str | Path) -> None:
        path = Path(path)
        self.scenario().write(path)
        self.path = path.resolve()
        self.title = path.name

    def deformed_mesh(self, nodes: np.ndarray | None = None) -> TriMesh:
        """The full-resolution mesh deformed by ``nodes`` (default: the current nodes)."""
        surface = self.surface
        nodes = self.state.nodes if nodes is None else nodes
        return TriMesh(surface.deform(nodes), surface.full.faces)

    def export(self, path: str | Path, nodes: np.ndarray | None = None) -> None:
        try:
            from core.meshio import save_mesh  # noqa: PLC0415
        except ImportError as exc:
            raise IsochorError(f"Mesh export is not available yet ({exc}).") from None
        save_mesh(str(path), self.deformed_mesh(nodes))


def _key(problem: Problem) -> tuple:
    sc = problem.scenario
    return (tuple(sc.lattice_nodes), sc.padding, sc.frame)


def prepare_surface(problem: Problem) -> None:
    """Compute on the calling (GUI) thread what the display needs: the full level's basis
    and the spring network. The solver thread computes the other levels lazily."""
    surface = problem.surface
    surface.level(-1)
    _ = surface.springs


def _model_title(scenario: Scenario) -> str:
    if "builtin" in scenario.model:
        return f"built-in {scenario.model['builtin']}"
    return Path(scenario.model["path"]).name
