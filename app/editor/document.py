"""The editor model: the document, its parts (the selection, the drag) and its events.

Qt-free, so every rule is tested headless (``tests/test_document.py``); the window and the
session controller only call these methods and draw what they return. The states it holds
are :mod:`isochor.app.editor.state`'s.

Undo works on :class:`StateCell` objects: mutable boxes around one ``DocState``. The current
cell is shared between the undo command that produced it (its ``after``) and the next command
(its ``before``). When a solve started from a cell ends, :meth:`Document.record_result` puts
the solved state into that cell, so undo and redo land on solved states without solving again.

Edits are the rules' (:mod:`~isochor.app.editor.noderules`,
:mod:`~isochor.app.editor.goalrules`, :mod:`~isochor.app.editor.handlerules`,
:mod:`~isochor.app.editor.timelinerules`, :mod:`~isochor.app.editor.latticerules`): functions
of :meth:`Document.base`, a snapshot of what an edit starts from. Edits start from the nodes
the user sees (:meth:`Document.base_nodes`): the newest intermediate nodes of a running
solve, or with "preserve volume" off the plain FFD (free nodes at rest).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...core.errors import IsochorError
from ...core.export import export_file
from ...core.io.formats import READ_FORMATS, SCENARIO_SUFFIXES, is_model, is_scenario, listing
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
from . import goalrules, handlerules
from .drag import DragSession
from .edit import Edit, EditBase
from .handlerules import HandleDrag
from .problems import ProblemCache
from .selection import Selection
from .state import DocState, SolveSummary, StateCell, describe_status, initial_state, plural
from .timeline import state_edit

__all__ = [
    "Document",
    "DocState",
    "DragSession",
    "Edit",
    "EditBase",
    "SolveSummary",
    "StateCell",
    "default_lattice_shape",
    "describe_status",
    "initial_state",
    "plural",
]


Listener = Callable[[str], None]


class Document:
    """What the editor edits: the current state cell, the selection, the drag, the file.

    Events (a listener gets the name): ``"state"`` the current cell changed (an edit, undo,
    redo, a loaded result), ``"scene"`` the lattice or model changed with it, ``"selection"``.

    Attributes
    ----------
    cell : the current :class:`StateCell`
    selection : the :class:`~isochor.app.editor.selection.Selection`: the selected node rows
        (``selection.rows``) and handle (``selection.handle``)
    drag : the running :class:`DragSession` (or handle drag), if any
    preserve : "preserve volume" is on (off: plain FFD, nothing is solved)
    live_nodes : the newest nodes of a running solve (None when idle): the base of edits
    problems : the problems built for this model, one per lattice
    path : the scenario file this document was read from or saved to, if any
    title : a short name for the window title
    """

    def __init__(self, problem: Problem, *, path: Path | None = None, title: str = "") -> None:
        self.cell = StateCell(initial_state(problem))
        self._listeners: list[Listener] = []
        self.selection = Selection(lambda: self.cell.state, lambda: self._emit("selection"))
        self.drag: DragSession | HandleDrag | None = None
        self._preserve = True
        self._live_nodes: np.ndarray | None = None
        self.problems = ProblemCache(problem)
        self.path = path
        self.title = title or _model_title(problem.scenario)

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
        self._live_nodes = None
        new_scene = cell.state.problem is not old
        self.selection.follow(cell.state, new_scene)
        if new_scene:
            self._emit("scene")
        self._emit("state")

    @property
    def preserve(self) -> bool:
        """Whether "preserve volume" is on (off: plain FFD, nothing is solved)."""
        return self._preserve

    def set_preserve(self, on: bool) -> None:
        self._preserve = bool(on)

    @property
    def live_nodes(self) -> np.ndarray | None:
        """The newest nodes of a running solve (None when idle): the base of edits."""
        return self._live_nodes

    def show_live(self, nodes: np.ndarray | None) -> None:
        """The newest nodes of the running solve (None: nothing runs); edits start there."""
        self._live_nodes = None if nodes is None else np.asarray(nodes)

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
            self._live_nodes = None
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

    def base(self) -> EditBase:
        """What an edit starts from now: the state, the nodes on screen, the selection and
        the problems built before (the first argument of every edit rule)."""
        return EditBase(
            self.state,
            self.base_nodes(),
            self.selection.rows,
            self.selection.handle,
            self.problems,
        )

    # -- what is on screen besides the nodes -----------------------------------------------
    def held(self) -> tuple[np.ndarray, str]:
        """The nodes the far-side anchor holds for what is on screen, and the face's name
        (see :func:`isochor.app.editor.goalrules.held`)."""
        return goalrules.held(self.state, preserve=self.preserve, drag=self.drag)

    def rest_point(self, face: int, weights) -> np.ndarray:
        """(3,) the model's rest point at barycentric ``weights`` of full-mesh triangle
        ``face`` (the triangle and weights of a hit on the mesh as drawn)."""
        return handlerules.rest_point(self.state, face, weights)

    def handle_points(self, nodes: np.ndarray | None = None, handles=None) -> np.ndarray:
        """(h, 3) where each handle's point is with ``nodes`` (default: on screen)."""
        nodes = self.base_nodes() if nodes is None else nodes
        return handlerules.handle_points(self.state, nodes, handles)

    def mirror_handles(self, handles=None) -> tuple:
        """The mirror images the solve adds with symmetry on (none with it off)."""
        return handlerules.mirror_handles(self.state, handles)

    # -- the drag --------------------------------------------------------------------------
    def begin_drag(self, verb: str = "Move") -> DragSession | None:
        """Start dragging the selection from the nodes on screen (``verb``: the undo step's
        first word)."""
        rows = self.selection.rows
        if len(rows) == 0:
            return None
        mirror = self.state.mirror
        drag = DragSession(self.cell, rows, self.base_nodes(), verb, mirror)
        self.drag = drag
        return drag

    def begin_handle_drag(self, index: int | None = None, at=None) -> HandleDrag | None:
        """Drag handle ``index``'s target, or a new handle on rest point ``at`` (placed where
        that point is on screen)."""
        st = self.state
        base = self.base_nodes()
        if index is None:
            if at is None:
                return None
            handles = (*st.handles, handlerules.new_handle(st, at, base))
            index, verb = len(st.handles), "Add handle"
        else:
            handles, verb = st.handles, "Move handle"
        drag = HandleDrag(self.cell, handles, index, base, verb)
        self.drag = drag
        return drag

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
            goal=st.goal,
            handles=st.handles,
            timeline=st.timeline.core(),
        )

    def save(self, path: str | Path) -> None:
        path = Path(path)
        self.scenario().write(path)
        self.path = Path(os.path.abspath(path))
        self.title = path.name

    def deformed_mesh(self, nodes: np.ndarray | None = None) -> TriMesh:
        """The full-resolution mesh deformed by ``nodes`` (default: the nodes on screen),
        with the caps over its holes, if any (``.own`` without them)."""
        nodes = self.base_nodes() if nodes is None else nodes
        return self.surface.full.moved(self.surface.deform(nodes))

    def export(self, path: str | Path, nodes: np.ndarray | None = None) -> list[str]:
        """Write the deformed model through the one export path (:mod:`isochor.core.export`):
        in the model's own format it keeps everything but the positions. Never over the
        model file it was made from. Returns the notes for the user."""
        nodes = self.base_nodes() if nodes is None else nodes
        return export_file(self.state.problem, nodes, path)


def _model_title(scenario: Scenario) -> str:
    if "builtin" in scenario.model:
        return f"built-in {scenario.model['builtin']}"
    return Path(scenario.model["path"]).name
