"""The editor model: the document, its edit rules, the selection and the drag session.

Qt-free, so every rule is tested headless (``tests/test_document.py``); the window and the
session controller only call these methods and draw what they return. The states it holds
are :mod:`isochor.app.editor.state`'s.

Undo works on :class:`StateCell` objects: mutable boxes around one ``DocState``. The current
cell is shared between the undo command that produced it (its ``after``) and the next command
(its ``before``). When a solve started from a cell ends, :meth:`Document.record_result` puts
the solved state into that cell, so undo and redo land on solved states without solving again.

Edits start from the nodes the user sees (:meth:`Document.base_nodes`): the newest
intermediate nodes of a running solve, or with "preserve volume" off the plain FFD (free nodes
at rest). The rules of the goal's settings and of pins on some axes are
:mod:`isochor.app.editor.goalrules`'.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...core.errors import IsochorError
from ...core.export import export_file
from ...core.goal.constraints import check_ratio
from ...core.io.formats import READ_FORMATS, SCENARIO_SUFFIXES, is_model, is_scenario, listing
from ...core.lattice import MAX_NODES, MIN_NODES
from ...core.mesh import TriMesh
from ...core.scenario.document import Scenario
from ...core.scenario.examples import example_scenario
from ...core.scenario.problem import (
    ModelLoader,
    Problem,
    build,
    default_lattice_shape,
    scenario_model,
)
from .drag import DragSession
from .goalrules import Edit, GoalRules
from .handlerules import HandleRules
from .selection import SelectionRules
from .state import DocState, SolveSummary, StateCell, describe_status, initial_state, plural
from .timeline import state_edit
from .timelinerules import TimelineRules

__all__ = [
    "Document",
    "DocState",
    "DragSession",
    "Edit",
    "SolveSummary",
    "StateCell",
    "default_lattice_shape",
    "describe_status",
    "initial_state",
    "plural",
]


Listener = Callable[[str], None]


class Document(GoalRules, HandleRules, SelectionRules, TimelineRules):
    """What the editor edits: the current state cell, the selection, the drag, the file.

    Events (a listener gets the name): ``"state"`` the current cell changed (an edit, undo,
    redo, a loaded result), ``"scene"`` the lattice or model changed with it, ``"selection"``.

    Attributes
    ----------
    cell : the current :class:`StateCell`
    selection : (k,) int, the selected node rows, sorted
    drag : the running :class:`DragSession`, if any
    preserve : "preserve volume" is on (off: plain FFD, nothing is solved)
    live_nodes : the newest nodes of a running solve (None when idle): the base of edits
    path : the scenario file this document was read from or saved to, if any
    title : a short name for the window title
    """

    def __init__(self, problem: Problem, *, path: Path | None = None, title: str = "") -> None:
        self.cell = StateCell(initial_state(problem))
        self.selection = np.zeros(0, dtype=int)
        self.handle: int | None = None  #: the selected handle, if any
        self.drag: DragSession | None = None
        self.preserve = True
        self.live_nodes: np.ndarray | None = None
        self.path = path
        self.title = title or _model_title(problem.scenario)
        self._listeners: list[Listener] = []
        self._problems: dict[tuple, Problem] = {_key(problem): problem}

    # -- constructors ----------------------------------------------------------------------
    @classmethod
    def example(cls, name: str = "torus-compression") -> Document:
        return cls(build(example_scenario(name)), title=f"example: {name}")

    @classmethod
    def open(
        cls,
        path: str | Path,
        *,
        template: bool = False,
        stage: Listener | None = None,
        loader: ModelLoader | None = None,
    ) -> Document:
        """A model (OBJ, PLY, STL, OFF) in a default lattice, or a scenario (.json).

        ``template``: open a scenario as a new, unsaved document (the shipped examples), so
        that Save asks where to write. ``stage`` is told the name of each stage as it starts
        and ``loader`` reads the model file (the loading thread's,
        :mod:`isochor.app.window.loading`).
        Raises :class:`IsochorError` with a message to show.
        """
        path = Path(path).expanduser()
        stage = stage or (lambda _text: None)
        stage(f"Reading {path.name}…")
        if is_scenario(path):
            scenario = Scenario.read(path)
            if "path" in scenario.model:
                stage(f"Reading {scenario.model_path().name}…")
            model = scenario_model(scenario, loader)
            stage("Fitting the lattice…")
            where = None if template else Path(os.path.abspath(path))
            return cls(build(scenario, model=model), path=where, title=path.name)
        if not is_model(path):
            raise IsochorError(
                f"{path.name}: unknown file type {path.suffix or '(none)'}; open a model "
                f"({listing(READ_FORMATS)}) or a scenario ({listing(SCENARIO_SUFFIXES)})."
            )
        if not path.is_file():
            raise IsochorError(f"{path}: no such file")
        scenario = Scenario.from_dict({"model": {"path": os.path.abspath(path)}})
        model = scenario_model(scenario, loader)
        stage("Fitting the lattice…")
        scenario = scenario.with_(lattice_nodes=default_lattice_shape(model.levels[-1]))
        return cls(build(scenario, model=model), title=path.name)

    # -- events ----------------------------------------------------------------------------
    def subscribe(self, listener: Listener) -> None:
        self._listeners.append(listener)

    def _emit(self, event: str) -> None:
        for listener in list(self._listeners):
            listener(event)

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

    def set_cell(self, cell: StateCell) -> None:
        """Make ``cell`` current (every edit, undo and redo comes through here)."""
        old = self.cell.state.problem
        self.cell = cell
        self.drag = None
        self.live_nodes = None
        if cell.state.problem is not old:
            self.selection = np.zeros(0, dtype=int)
            self._emit("scene")
        else:
            self.selection = self.selection[self.selection < cell.state.lattice.n_nodes]
        if self.handle is not None and self.handle >= len(cell.state.handles):
            self.handle = None
        self._emit("state")

    def needs_solve(self) -> bool:
        """The current state should be solved: preserve is on and it never was."""
        return self.preserve and not self.state.solved

    def record_result(self, cell: StateCell, nodes, summary: SolveSummary) -> None:
        """A solve started from ``cell`` ended: the cell holds the solved state from now
        on (also when it is not current: undo and redo then land on it solved)."""
        if nodes is None:
            nodes = cell.state.nodes
        cell.state = replace(cell.state, nodes=nodes, solved=True, result=summary)
        if cell is self.cell:
            self.live_nodes = None
            self._emit("state")

    def view_nodes(self, state: DocState | None = None) -> np.ndarray:
        """What the view shows for a state: with "preserve volume" off, plain FFD (the free
        nodes at rest, the fixed ones where the user put them)."""
        st = self.state if state is None else state
        if self.preserve:
            return np.array(st.nodes)
        return np.where(st.fixed_axes, st.nodes, st.lattice.rest_nodes)

    def base_nodes(self) -> np.ndarray:
        """The nodes on screen, the base of every new edit."""
        if self.live_nodes is not None and self.preserve:
            return np.array(self.live_nodes)
        return self.view_nodes()

    # -- selection -------------------------------------------------------------------------
    def select(self, rows, mode: str = "replace") -> bool:
        """Change the selection: ``replace``, ``add``, or ``toggle`` the given rows.
        Returns True when it changed."""
        rows = np.unique(np.asarray(list(rows), dtype=int))
        n = self.state.lattice.n_nodes
        if len(rows) and (rows.min() < 0 or rows.max() >= n):
            raise IndexError(f"node rows must lie in [0, {n})")
        if mode == "add":
            rows = np.union1d(self.selection, rows)
        elif mode == "toggle":
            rows = np.setxor1d(self.selection, rows)
        elif mode != "replace":
            raise ValueError(f"unknown selection mode {mode!r}")
        if np.array_equal(rows, self.selection):
            return False
        self.selection = rows.astype(int)
        if len(rows):
            self.handle = None  # a node selection replaces a handle's
        self._emit("selection")
        return True

    def select_all(self) -> bool:
        return self.select(range(self.state.lattice.n_nodes))

    # -- edit rules: each returns the Edit to commit, or None when nothing would change ----
    def edit_position(self, axis: int, value: float) -> Edit | None:
        """Type a coordinate: the selection (its centre, for several) goes to ``value``."""
        rows = self.selection
        if len(rows) == 0 or not np.isfinite(value):
            return None
        nodes = self.base_nodes()
        now = nodes[rows, axis].mean()
        if abs(value - now) <= 1e-12 * max(1.0, abs(value)):
            return None
        nodes[rows, axis] += value - now
        new = self.state.moved_to(nodes, rows).mirrored(rows)
        m = self.state.mirror
        mirrored = ", mirrored" if m is not None and (m.partner[rows] != rows).any() else ""
        return Edit(new, f"Move {plural(len(rows))}{mirrored}")

    def edit_pins(self, rows, pin: bool) -> Edit | None:
        """Pin (or unpin) ``rows``; None means every node."""
        st = self.state
        rows = np.arange(st.lattice.n_nodes) if rows is None else np.unique(np.asarray(rows, int))
        if len(rows) == 0:
            return None
        changes = (~st.pin_axes[rows].all(axis=1)).any() if pin else st.fixed[rows].any()
        if not changes:
            return None
        new = st.edited(nodes=self.base_nodes()).pinned_as(rows, pin).mirrored(rows)
        what = "all nodes" if len(rows) == st.lattice.n_nodes else plural(len(rows))
        return Edit(new, f"{'Pin' if pin else 'Unpin'} {what}")

    def edit_toggle_pin(self) -> Edit | None:
        """Pin the selection, or unpin it when all of it is fixed already."""
        rows = self.selection
        if len(rows) == 0:
            return None
        return self.edit_pins(rows, not bool(self.state.fixed[rows].all()))

    def edit_target(self, percent: float) -> Edit | None:
        """A new target volume, ``percent`` of the original (None: not a positive number
        or no change). Raises :class:`IsochorError` beyond what a lattice can reach."""
        ratio = float(percent) / 100.0
        if not (np.isfinite(ratio) and ratio > 0) or ratio == self.state.target_ratio:
            return None
        check_ratio(ratio, "target volume ratio")
        return Edit(
            self.state.edited(nodes=self.base_nodes(), target_ratio=ratio),
            f"Target volume {percent:g} %",
        )

    def edit_reset(self) -> Edit | None:
        """Every node back to rest, nothing pinned, no handle (at rest there is nothing to
        solve)."""
        st = self.state
        n = st.lattice.n_nodes
        rest = st.lattice.rest_nodes
        changed = st.pinned.any() or st.moved.any() or st.handles
        if not (changed or not np.array_equal(st.nodes, rest)):
            return None
        new = st.edited(
            nodes=rest,
            pin_axes=np.zeros((n, 3), bool),
            moved=np.zeros(n, bool),
            solved=st.target_ratio == 1.0,
            handles=(),
        )
        return Edit(new, "Reset nodes")

    def edit_lattice(self, shape) -> Edit | None:
        """A new lattice of ``shape`` nodes around the same model, at rest.

        Moves, pins and the timeline's keys are dropped (they name nodes of the old
        lattice); the model pyramid is reused, and so is a problem built before for the same
        shape, with its caches.
        """
        shape = tuple(int(s) for s in shape)
        if len(shape) != 3 or not all(MIN_NODES <= s <= MAX_NODES for s in shape):
            raise IsochorError(f"A lattice has {MIN_NODES} to {MAX_NODES} nodes per axis.")
        if shape == tuple(self.state.lattice.shape):
            return None
        old = self.problem
        scenario = old.scenario.with_(
            lattice_nodes=shape, moves=(), pins=(), axis_pins=(), timeline=None
        )
        problem = self._problems.get(_key_of(scenario))
        if problem is None:
            problem = build(scenario, model=old.model)
            self._problems[_key(problem)] = problem
        ratio = self.state.target_ratio
        n = problem.surface.lattice.n_nodes
        # at rest: a cached problem may come from the opened scenario, whose moves and pins
        # name the nodes of the lattice the user has just left
        state = DocState(
            problem,
            problem.surface.lattice.rest_nodes,
            np.zeros(n, bool),
            np.zeros(n, bool),
            ratio,
            solved=ratio == 1.0 and not self.state.handles,
            handles=self.state.handles,
            timeline=replace(self.state.timeline, keys=()),
            **self.state.settings(),
        )
        keys = len(self.state.timeline.keys)
        dropped = f", {plural(keys, 'key')} dropped" if keys else ""
        return Edit(state, "Rebuild lattice {}x{}x{}".format(*shape) + dropped)

    # -- the drag --------------------------------------------------------------------------
    def begin_drag(self, verb: str = "Move") -> DragSession | None:
        """Start dragging the selection from the nodes on screen (``verb``: the undo step's
        first word)."""
        if len(self.selection) == 0:
            return None
        mirror = self.state.mirror
        self.drag = DragSession(self.cell, self.selection, self.base_nodes(), verb, mirror)
        return self.drag

    def end_drag(self) -> Edit | None:
        """The edit of the drag (None when no drag runs); the drag is over."""
        drag, self.drag = self.drag, None
        if drag is None:
            return None
        live = self.live_nodes if self.preserve else None
        return drag.finish(live)

    def cancel_drag(self) -> None:
        self.drag = None

    # -- files -----------------------------------------------------------------------------
    def scenario(self) -> Scenario:
        """The current state as a scenario: moved nodes as ``to`` moves, pins (on all axes
        or on some), the target, the goal's settings and the timeline's keys (a scenario
        that uses none of them is written as version 1)."""
        st = self.state
        edit = state_edit(st)
        return st.problem.scenario.with_(
            moves=edit.moves,
            pins=edit.pins,
            axis_pins=edit.axis_pins,
            target_volume_ratio=float(st.target_ratio),
            handles=st.handles,
            timeline=st.timeline.core(),
            **st.settings(),
        )

    def save(self, path: str | Path) -> None:
        path = Path(path)
        self.scenario().write(path)
        self.path = Path(os.path.abspath(path))
        self.title = path.name

    def deformed_mesh(self, nodes: np.ndarray | None = None) -> TriMesh:
        """The full-resolution mesh deformed by ``nodes`` (default: the nodes on screen)."""
        nodes = self.base_nodes() if nodes is None else nodes
        return TriMesh(self.surface.deform(nodes), self.surface.full.faces)

    def export(self, path: str | Path, nodes: np.ndarray | None = None) -> list[str]:
        """Write the deformed model through the one export path (:mod:`isochor.core.export`):
        in the model's own format it keeps everything but the positions. Never over the
        model file it was made from. Returns the notes for the user."""
        nodes = self.base_nodes() if nodes is None else nodes
        return export_file(self.state.problem, nodes, path)


def _key_of(scenario: Scenario) -> tuple:
    return (tuple(scenario.lattice_nodes), scenario.padding, scenario.frame)


def _key(problem: Problem) -> tuple:
    return _key_of(problem.scenario)


def _model_title(scenario: Scenario) -> str:
    if "builtin" in scenario.model:
        return f"built-in {scenario.model['builtin']}"
    return Path(scenario.model["path"]).name
