"""The Python API: Isochor from a script, on a mesh in memory or a file.

Two entry points, both re-exported by the package (``import isochor``):

- :func:`deform`: one call, one result. It takes ``(vertices, faces)`` arrays, a
  ``trimesh.Trimesh`` or a ``pyvista.PolyData`` and gives back the same type deformed
  (every vertex the input had, in its order, its other data kept), in a
  :class:`Deformed` that also holds the report;
- :class:`Session`: repeated edits of one model that reuse its level pyramid and caches:
  move, pin and unpin nodes, solve (to the end or step by step), export, save the
  scenario. :func:`load` opens a model or scenario file as a session.

The solver works on a welded, checked copy of the surface (:mod:`isochor.core.io.repair`);
the FFD, a map of space, then moves the caller's own vertices. No Qt or VTK is imported
here: a ``pyvista.PolyData`` is handled through its own methods.
"""

from __future__ import annotations

from collections.abc import Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from .adapters import CallerMesh
from .errors import IsochorError
from .estimate import screen
from .export import Exported, export_bytes, export_file
from .goal.handles import Handle
from .goal.spec import GOAL_FIELDS, Goal
from .io.atomic import atomic_write_bytes
from .io.formats import is_scenario
from .io.repair import clean_closed_surface
from .lattice import Lattice
from .mesh import TriMesh
from .report import make_report
from .scenario.document import VERSION, Move, Scenario
from .scenario.poses import Pose, Timeline
from .scenario.problem import (
    READ_SHARE,
    Model,
    Problem,
    ProgressCallback,
    build,
    default_lattice_shape,
    pyramid_of,
    scenario_model,
)
from .scenario.sequence import Sequence as Solved
from .scenario.sequence import solve_sequence
from .solve.generators import relay, run_to_end
from .solve.records import Progress, SolveResult

Node = tuple[int, int, int]

#: a Session solve after an edit that moved no node more than this share of the object
#: size from the last converged result (same pins, goal and handles) is solved as a drag's
#: release is (:meth:`Session._small_edit`)
SMALL_EDIT = 0.05


@dataclass(frozen=True)
class Deformed:
    """What :func:`deform` returns.

    Attributes
    ----------
    mesh : the input deformed, of the input's type: a ``(vertices, faces)`` tuple, a
        ``trimesh.Trimesh`` or a ``pyvista.PolyData`` (a new object; the input is unchanged)
    report : the solve's report, the same dict ``isochor solve --report`` writes
    result : the solver's :class:`~isochor.core.solve.records.SolveResult` (final lattice nodes,
        volumes, levels)
    """

    mesh: Any
    report: dict[str, Any]
    result: SolveResult

    @property
    def converged(self) -> bool:
        """True when the volume met its tolerance."""
        return bool(self.result.converged)


class Session:
    """Repeated edits of one model, reusing its level pyramid and caches.

    Parameters
    ----------
    source : a model or scenario file path, or a mesh in memory (see :func:`deform`)
    lattice : nodes per axis (2 to 10 each; 1 to 64 with a local basis); by default 4 along
        the longest extent and 3 along the others (a scenario file's own lattice when
        ``source`` is one)
    basis : ``"bernstein"`` (the paper's, the default), or Blender's lattice interpolation
        ``"bspline"``, ``"catmull-rom"``, ``"cardinal"``, ``"linear"``; one name or three
        (one per axis). :attr:`lattice` ``.basis`` gives the per-axis tuple
    outside : Blender's "Outside" option of a local basis (inner nodes follow the faces)
    padding : the lattice box around the model's bounding box, a fraction of its extent
    frame : ``(origin, axes)``: an explicit lattice box instead (rows of ``axes`` are its
        three edge vectors)
    progress : ``callable(stage, fraction)``, told how far the work is: ``("load", f)``
        while the model loads and its level pyramid is made (here), ``("solve", f)`` during
        every solve (f from 0 to 1, never decreasing within a stage; 1 at its end). It is
        called on the thread that does the work: keep it quick
    force : solve even when the estimate before each solve (:mod:`isochor.core.estimate`)
        says it takes longer than the time limit; a solve whose memory does not fit this
        machine is always refused (:class:`IsochorError`, one line with the largest
        lattice that fits)
    goal : what the solve holds, by the keywords of
        :data:`~isochor.core.goal.spec.GOAL_FIELDS` (each field's ``keyword``):

        - ``target``: the volume to reach, relative to the model's (1 keeps it)
        - ``preserve``: ``"total"`` (one volume, the default) or ``"per-body"`` (each
          closed body keeps its own)
        - ``keep_centroid``: also keep the solid's centre of mass where it was
        - ``anchor``: ``"far-side"`` (the default: the lattice face the edit pushes
          towards, or the farthest from it, stays put unless you fixed that side) or
          ``"none"`` (the paper's behaviour)
        - ``fold_guard``: penalise folding the model inside out (default True)
        - ``symmetry``: ``"x"``, ``"y"`` or ``"z"``: edits and results are mirror images
          across that mid-plane of the lattice; ``"none"`` (the default)

    ``source`` may also be a :class:`~isochor.core.scenario.document.Scenario` (the command
    line's: a file it read, with its options applied, or a built-in example).

    Handles (:meth:`add_handle`) are points of the model that the solve puts where they are
    told to go. A scenario's own settings are the defaults of a session on it. The goal's
    settings are attributes of the same names (``target`` for the ratio) and may change
    between solves; they are checked when a solve starts (:attr:`goal`).

    Examples
    --------
    >>> import isochor, trimesh
    >>> s = isochor.Session(trimesh.creation.icosphere(), lattice=(3, 3, 3))
    >>> s.move((2, 1, 1), by=(0.5, 0.0, 0.0))
    >>> s.pin((0, 1, 1))
    >>> s.solve().converged
    True
    """

    # The goal's attributes, by their API keywords: set in __init__ from the declarations of
    # isochor.core.goal.spec (defaults, checks); annotated here so that a caller's type
    # checker knows them (tests/test_api.py keeps the two lists equal).
    target: float
    preserve: str
    keep_centroid: bool
    anchor: str
    fold_guard: bool
    symmetry: str

    def __init__(
        self,
        source: Any,
        lattice: Sequence[int] | None = None,
        *,
        padding: float | None = None,
        frame: tuple[Sequence[float], Sequence[Sequence[float]]] | None = None,
        basis: str | Sequence[str] | None = None,
        outside: bool | None = None,
        progress: ProgressCallback | None = None,
        force: bool = False,
        **goal: Any,
    ) -> None:
        by_keyword = {f.keyword: f for f in GOAL_FIELDS}
        for name in goal:
            if name not in by_keyword:
                known = ", ".join(
                    [
                        "lattice",
                        "padding",
                        "frame",
                        "basis",
                        "outside",
                        "progress",
                        "force",
                        *by_keyword,
                    ]
                )
                raise IsochorError(f"unknown keyword {name!r}; the known ones are {known}")
        if progress is not None and not callable(progress):
            raise IsochorError("progress must be a callable(stage, fraction), or None")
        #: ``callable(stage, fraction)`` told how far loading and each solve are, or None
        self.progress = progress
        if not isinstance(force, bool):
            raise IsochorError(f"force must be True or False, got {force!r}")
        #: solve even when the estimate (:mod:`isochor.core.estimate`) says it takes longer
        #: than its time limit; a solve whose memory does not fit is always refused
        self.force = force
        self._mesh: CallerMesh | None = None
        if isinstance(source, Scenario):
            scenario, model = source, scenario_model(source, progress=progress)
        elif isinstance(source, (str, Path)):
            scenario, model = _open(Path(source), progress)
        else:
            self._mesh = CallerMesh(source)
            if progress is not None:
                progress("load", 0.0)
            clean, warns, count = clean_closed_surface(self._mesh.vertices, self._mesh.faces)
            levels = pyramid_of(clean, count, progress, READ_SHARE)
            model = Model(tuple(levels), tuple(warns), bodies=count)
            scenario = Scenario({"mesh": "in memory"})
        changes: dict[str, Any] = {}
        if lattice is not None:  # another lattice: a scenario's moves and pins name old nodes
            changes.update(lattice_nodes=tuple(lattice), moves=(), pins=())
        elif not isinstance(source, (str, Path, Scenario)) or not _names_scenario(source):
            changes["lattice_nodes"] = default_lattice_shape(model.levels[-1])
        if padding is not None:
            changes["padding"] = padding
        if frame is not None:
            changes["frame"] = (list(frame[0]), [list(a) for a in frame[1]])
        if basis is not None:
            changes["lattice_basis"] = basis if isinstance(basis, str) else list(basis)
        if outside is not None:
            changes["lattice_outside"] = outside
        # each goal keyword checked as its scenario key is (the same one-line errors)
        changes.update({by_keyword[k].key: v for k, v in goal.items() if v is not None})
        if changes:
            scenario = scenario.checked(changes)
        self.problem: Problem = build(scenario, model=model)
        self.nodes = self.problem.nodes.copy()
        #: (n, 3) bool: the fixed coordinates of every node
        self.fixed = self.problem.fixed.copy()
        # what the next solve holds: one attribute per goal field, by its keyword
        # (``target``, ``preserve``, ...); they may be changed between solves
        for f in GOAL_FIELDS:
            setattr(self, f.keyword, getattr(scenario.goal, f.name))
        #: the surface handles of the next solve (see :meth:`add_handle`)
        self.handles: list[Handle] = list(scenario.handles)
        #: keyed poses (see :meth:`key`) and how :meth:`frames` plays them
        self.poses: list[Pose] = list(scenario.timeline.poses) if scenario.timeline else []
        self.result: SolveResult | None = None
        #: what the last converged solve held (fixed coordinates, goal, handles), or None
        self._solved: tuple | None = None

    # -- the lattice ------------------------------------------------------------------------
    @property
    def lattice(self) -> Lattice:
        """The FFD lattice (its rest nodes are ``lattice.rest_nodes``)."""
        return self.problem.surface.lattice

    @property
    def warnings(self) -> list[str]:
        """What loading the model and fitting the lattice said, one sentence each."""
        return self.problem.warnings

    def _row(self, node: Node) -> int:
        try:
            return self.lattice.index(*(int(a) for a in node))
        except (IndexError, TypeError, ValueError):
            l, m, n = self.lattice.shape
            raise IsochorError(f"node {node!r} is not a node of the {l}x{m}x{n} lattice") from None

    def move(
        self, node: Node, by: Sequence[float] | None = None, to: Sequence[float] | None = None
    ) -> None:
        """Move a node ``by`` an offset from where it is, or ``to`` a position; it stays
        there (fixed) in the next solves."""
        if (by is None) == (to is None):
            raise IsochorError("move: give exactly one of by= or to=")
        r = self._row(node)
        given = _point(by if by is not None else to, f"move: node {tuple(node)}")
        new = self.nodes[r] + given if by is not None else given
        if not np.all(np.isfinite(new)):
            raise IsochorError(f"move: node {tuple(node)} needs three finite coordinates")
        self.nodes[r] = new
        self.fixed[r] = True

    def pin(self, *nodes: Node, axes: str = "xyz") -> None:
        """Keep these nodes where they are in the next solves; on some ``axes`` only
        (``"z"``: the node keeps its z and may slide in x and y)."""
        if not isinstance(axes, str) or not axes or set(axes) - set("xyz"):
            raise IsochorError(f'pin: axes must be some of "xyz", got {axes!r}')
        columns = ["xyz".index(a) for a in sorted(set(axes))]
        for node in nodes:
            self.fixed[self._row(node), columns] = True

    def unpin(self, *nodes: Node) -> None:
        """Free these nodes (moved or pinned): the next solve places them."""
        for node in nodes:
            self.fixed[self._row(node)] = False

    @property
    def goal(self) -> Goal:
        """What the next solve holds: the goal's attributes (``target``, ``preserve``,
        ``keep_centroid``, ``anchor``, ``fold_guard``, ``symmetry``), checked."""
        return Goal(**{f.name: getattr(self, f.keyword) for f in GOAL_FIELDS})

    def add_handle(self, at: Sequence[float], to: Sequence[float] | None = None) -> int:
        """Add a handle on the model's point ``at`` (rest coordinates) that the next solves
        put at ``to`` (by default where the current nodes put it: no change until moved).
        Returns its index in :attr:`handles`."""
        point = _point(at, "add_handle: at")
        end = self.lattice.deform(point[None], self._checked_nodes())[0] if to is None else to
        self.handles.append(Handle(point, _point(end, "add_handle: to")))
        return len(self.handles) - 1

    def key(self, frame: int, *, target: float | None = None) -> None:
        """Key the current edit (moved nodes, pins, handles; ``target``, or the session's
        target ratio) at ``frame``, replacing a key there."""
        if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or frame < 0:
            raise IsochorError(f"key: the frame must be a whole number >= 0, got {frame!r}")
        pose = Pose(int(frame), self.scenario().edit, target)
        self.poses = [p for p in self.poses if p.frame != pose.frame] + [pose]
        self.poses.sort(key=lambda p: p.frame)

    def timeline(self, start=None, end=None, *, rate=24.0, interpolation="linear") -> Timeline:
        """The keyed poses as a timeline (from the first key to the last by default)."""
        if not self.poses:
            raise IsochorError("no poses keyed: call key(frame) first")
        poses, _ = Timeline(tuple(self.poses), 0, 0).to_json()
        settings = {"rate": rate, "interpolation": interpolation}
        settings.update({k: v for k, v in (("start", start), ("end", end)) if v is not None})
        timeline = Timeline.from_json(poses, settings, self.lattice.shape, VERSION)
        assert timeline is not None  # poses were keyed
        return timeline

    def frames(self, start=None, end=None, *, rate=24.0, interpolation="linear") -> Solved:
        """Solve every frame of the keyed poses (each warm-started from the one before);
        returns the :class:`~isochor.core.scenario.sequence.Sequence` (``.frames``, each with its
        ``frame`` and ``result``)."""
        timeline = self.timeline(start, end, rate=rate, interpolation=interpolation)
        problem = replace(self.problem, scenario=self.scenario().with_(timeline=timeline))
        return run_to_end(solve_sequence(problem))

    def move_handle(self, index: int, to: Sequence[float]) -> None:
        """Send handle ``index`` to ``to``."""
        index = self._handle_index(index, "move_handle")
        self.handles[index] = self.handles[index].moved_to(_point(to, "move_handle: to"))

    def _handle_index(self, index: Any, what: str) -> int:
        """``index`` checked as a handle's (one sentence naming ``what`` otherwise)."""
        count = len(self.handles)
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise IsochorError(f"{what}: the index must be a whole number, got {index!r}")
        if not -count <= index < count:
            raise IsochorError(f"{what}: no handle {index}; there are {count} (see add_handle)")
        return int(index)

    def _checked_nodes(self) -> np.ndarray:
        """The session's nodes, checked: a caller may have assigned :attr:`nodes`."""
        shape = (self.lattice.n_nodes, 3)
        try:
            nodes = np.asarray(self.nodes, dtype=np.float64)
        except (TypeError, ValueError):
            nodes = None
        if nodes is None or nodes.shape != shape or not np.all(np.isfinite(nodes)):
            got = getattr(nodes, "shape", "not numbers")
            raise IsochorError(
                f"nodes: must be {shape[0]} x 3 finite numbers (the lattice's), got {got}"
            )
        return nodes

    def remove_handle(self, index: int) -> None:
        """Remove handle ``index``; the next solve gives what the remaining edit gives (the
        free coordinates start from rest again: started from the current nodes, the springs
        would keep the turn and shift the handle caused)."""
        del self.handles[self._handle_index(index, "remove_handle")]
        free = ~self.fixed
        self.nodes[free] = self.lattice.rest_nodes[free]

    # -- solving -----------------------------------------------------------------------------
    def steps(self) -> Generator[Progress, None, SolveResult]:
        """Solve step by step: yields a :class:`~isochor.core.solve.records.Progress` record per
        inner step and level, returns the result; the session's nodes become the result's.
        Closing the generator stops the solve and keeps the nodes as they were.

        A solve beyond this machine (:func:`isochor.core.estimate.screen`) raises
        :class:`IsochorError` with the estimate's line before any work: one whose memory
        does not fit always, one that takes longer than the time limit unless ``force``."""
        self._screen()
        nodes, goal = self._checked_nodes(), self.goal
        held = tuple((tuple(h.at), tuple(h.to)) for h in self.handles)
        edit = (self.fixed.tobytes(), goal, held)
        run = self._solving(nodes, goal, self._small_edit(nodes, edit))
        if self.progress is not None:
            run = _reporting(run, self.progress)
        result = yield from run
        self.nodes = np.array(result.nodes)
        self.result, self._solved = result, (edit if result.converged else None)
        return result

    def _screen(self) -> None:
        """Refuse a solve beyond this machine (see :meth:`steps`)."""
        estimate = screen(self.problem)
        if estimate is None or estimate.fits():
            return
        if not estimate.memory_fits():
            raise IsochorError(estimate.message())
        if not self.force:
            raise IsochorError(f"{estimate.message()} (force=True solves it anyway)")

    def _solving(self, nodes: np.ndarray, goal: Goal, near: bool):
        """The solve of the current edit: ``near`` the last result for a small edit, and a
        whole solve from the nodes where that one does not converge."""
        fixed, handles = self.fixed, self.handles
        result = yield from self.problem.solve(nodes, fixed, goal=goal, handles=handles, near=near)
        if near and not result.converged:
            result = yield from self.problem.solve(nodes, fixed, goal=goal, handles=handles)
        return result

    def _small_edit(self, nodes: np.ndarray, edit: tuple) -> bool:
        """Whether this solve is a small edit of the last one: that one converged with the
        same fixed coordinates, goal and handles, and no node moved more than
        :data:`SMALL_EDIT` of the object size since. It is then solved as a drag's release
        is (``near``: it starts on the coarsest level that agrees with the full mesh there,
        with the least-squares multiplier, and keeps the last solve's factored curvature
        while the nodes stay near it); any other solve starts afresh."""
        last = self.result
        if last is None or self._solved != edit:
            return False
        return float(np.abs(nodes - last.nodes).max()) <= SMALL_EDIT * self.problem.surface.size

    def solve(self) -> SolveResult:
        """Solve to the end from the current nodes; the nodes become the result's."""
        return run_to_end(self.steps())

    @property
    def report(self) -> dict[str, Any]:
        """The last solve's report (the command line's ``--report``)."""
        return self.report_for()

    def report_for(
        self, source: str = "isochor.Session", time_s: float | None = None
    ) -> dict[str, Any]:
        """The last solve's report, saying where the scenario came from (``source``, in
        words) and how long the whole run took (``time_s``; the solve's own by default)."""
        if self.result is None:
            raise IsochorError("nothing solved yet: call solve() first")
        return make_report(self.problem, self.result, source, time_s)

    # -- results -----------------------------------------------------------------------------
    def deformed_vertices(self) -> np.ndarray:
        """The model's vertices (the caller's own, for a mesh in memory; the welded ones
        for a file) moved by the current nodes."""
        full = self.problem.surface.full  # (its own vertices: never the caps over its holes)
        points = self._mesh.vertices if self._mesh is not None else full.own.vertices
        return self.lattice.deform(points, self._checked_nodes())

    @property
    def mesh(self) -> Any:
        """The deformed model: the caller's mesh type for a mesh in memory, a
        :class:`~isochor.core.mesh.TriMesh` for a file."""
        if self._mesh is not None:
            return self._mesh.like(self.deformed_vertices())
        return TriMesh(self.deformed_vertices(), self.problem.surface.full.own.faces)

    def export_bytes(
        self, path: str | Path, *, morph_target: bool = False, nodes: np.ndarray | None = None
    ) -> Exported:
        """The file :meth:`export` would write to ``path``, not written: for a caller that
        writes several outputs as one set (the command line's ``--out`` with its report).
        ``nodes``: other lattice nodes to deform by (a frame of a sequence); the session's
        by default."""
        nodes = self.nodes if nodes is None else nodes
        if self._mesh is not None:  # the caller's own mesh, by its own kind
            vertices = self.lattice.deform(self._mesh.vertices, nodes)
            return Exported(self._mesh.file_bytes(vertices, Path(path)))
        return export_bytes(self.problem, nodes, path, morph_target=morph_target)

    def export(self, path: str | Path, *, morph_target: bool = False) -> list[str]:
        """Write the deformed model through the one export path (the same as the command
        line's ``--out`` and the window's Export): in the model file's own format it keeps
        everything but the positions. Never over the model file. Returns the notes."""
        if self._mesh is not None:  # the caller's own mesh, written by its own kind
            atomic_write_bytes(path, self.export_bytes(path).data)
            return []
        return export_file(self.problem, self.nodes, path, morph_target=morph_target)

    def scenario(self) -> Scenario:
        """The current edit as a scenario: moved nodes as ``to`` moves, pins (on some axes
        where so pinned), the goal. A node pinned on some axes is saved as pinned at rest."""
        rest = self.lattice.rest_nodes
        whole = self.fixed.all(axis=1)
        moved = whole & np.any(self.nodes != rest, axis=1)
        lat = self.lattice
        moves = tuple(
            Move(
                lat.ijk(r), to=cast("tuple[float, float, float]", tuple(map(float, self.nodes[r])))
            )
            for r in np.flatnonzero(moved)
        )
        pins = tuple(lat.ijk(r) for r in np.flatnonzero(whole & ~moved))
        partial = self.fixed.any(axis=1) & ~whole
        axis_pins = tuple(
            (lat.ijk(r), "".join(a for a, f in zip("xyz", self.fixed[r]) if f))
            for r in np.flatnonzero(partial)
        )
        return self.problem.scenario.with_(
            moves=moves,
            pins=pins,
            axis_pins=axis_pins,
            goal=self.goal,
            handles=tuple(self.handles),
            timeline=self.timeline() if self.poses else None,
        )

    def save(self, path: str | Path) -> None:
        """Save the current edit as a scenario file (the model must be a file or a
        built-in shape: a mesh in memory has no name to write)."""
        if "mesh" in self.problem.scenario.model:
            raise IsochorError(
                "a mesh from memory has no file a scenario can name; export it first"
            )
        self.scenario().write(path)


def _reporting(run, progress: ProgressCallback):
    """The solve ``run``, telling ``progress`` ``("solve", fraction)`` at every record
    (:attr:`~isochor.core.solve.records.Progress.fraction`) and 1 at its end."""

    high = 0.0  # (a small edit's whole solve after its near one starts again from 0)

    def tell(record: Progress) -> Progress:
        nonlocal high
        high = max(high, record.fraction)
        progress("solve", high)
        return record

    progress("solve", 0.0)
    result = yield from relay(run, tell)
    progress("solve", 1.0)
    return result


def _names_scenario(source: str | Path | Scenario) -> bool:
    """Whether ``source`` is a scenario (its lattice is the session's) or a model file."""
    return isinstance(source, Scenario) or is_scenario(Path(source))


def _open(path: Path, progress: ProgressCallback | None = None) -> tuple[Scenario, Model]:
    if is_scenario(path):
        scenario = Scenario.read(path)
        return scenario, scenario_model(scenario, progress=progress)
    scenario = Scenario.from_dict({"model": {"path": str(path.absolute())}})
    return scenario, scenario_model(scenario, progress=progress)


def load(path: str | Path, **options: Any) -> Session:
    """A :class:`Session` on a model (OBJ, PLY, STL, OFF, glTF) or a scenario file; the
    ``options`` are :class:`Session`'s."""
    if not isinstance(path, (str, Path)):
        raise IsochorError(f"load: give a file name (str or Path), got {type(path).__name__}")
    return Session(Path(path), **options)


def deform(
    mesh: Any,
    lattice: Sequence[int] | None = None,
    *,
    moves: Mapping[Node, Sequence[float]] | Iterable[Mapping[str, Any]] = (),
    pins: Iterable[Node | Mapping[str, Any]] = (),
    handles: Iterable[Handle | Mapping[str, Any]] = (),
    **options: Any,
) -> Deformed:
    """Deform a mesh in memory, keeping its volume (or reaching ``target`` times it).

    Parameters
    ----------
    mesh : ``(vertices, faces)`` arrays (``(n, 3)`` floats, ``(f, 3)`` ints), a
        ``trimesh.Trimesh`` or a ``pyvista.PolyData``: a closed surface
    lattice : nodes per axis, e.g. ``(5, 2, 2)``; see :class:`Session`
    moves : ``{(i, j, k): (dx, dy, dz)}`` offsets, or scenario-style dicts
        ``{"node": [i, j, k], "by": [...]}`` / ``{"node": ..., "to": [...]}``
    pins : nodes kept where they rest, or ``{"node": (i, j, k), "axes": "z"}`` for a node
        kept on some axes only
    handles : ``{"at": [x, y, z], "to": [x, y, z]}`` (or
        :class:`~isochor.core.goal.handles.Handle`): the mesh's point ``at`` must land at ``to``
    options : ``padding``, ``frame``, ``basis``, ``outside``, ``progress``, ``force``
        (``callable(stage, fraction)``: how far loading and the solve are) and the goal's
        keywords (``target``: the volume to reach relative to the mesh's, 1 by default;
        ``preserve``, ``keep_centroid``, ``anchor``, ``fold_guard``, ``symmetry``): see
        :class:`Session`

    Returns
    -------
    Deformed
        ``.mesh`` of the input's type with every input vertex moved, ``.report``,
        ``.result``, ``.converged``.
    """
    session = Session(mesh, lattice, **options)
    for name, given in (("moves", moves), ("pins", pins), ("handles", handles)):
        if isinstance(given, (str, bytes)) or not isinstance(given, (Iterable, Mapping)):
            raise IsochorError(f"deform: {name} must be a list (or a dict), got {given!r}")
    items = moves.items() if isinstance(moves, Mapping) else moves
    for item in items:
        if isinstance(item, Mapping):
            session.move(_node_of(item, "moves"), by=item.get("by"), to=item.get("to"))
        else:
            node, offset = _pair(item)
            session.move(node, by=offset)
    for pin in pins:
        if isinstance(pin, Mapping):
            session.pin(_node_of(pin, "pins"), axes=pin.get("axes", "xyz"))
        else:
            session.pin(pin)
    for h in handles:
        try:
            session.handles.append(Handle.of(h))
        except (KeyError, TypeError, ValueError) as exc:
            raise IsochorError(
                f'handles: each is {{"at": [x, y, z], "to": [x, y, z]}}, got {h!r} ({exc})'
            ) from None
    result = session.solve()
    return Deformed(session.mesh, session.report, result)


def _point(value: Any, what: str) -> np.ndarray:
    """``value`` as three floats, or one sentence saying what ``what`` needs."""
    try:
        point = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        point = None
    if point is None or point.shape != (3,):
        raise IsochorError(f"{what} needs three numbers (x, y, z), got {value!r}")
    return point


def _node_of(item: Mapping[str, Any], what: str) -> tuple:
    if "node" not in item:
        raise IsochorError(f'{what}: each needs "node": [i, j, k], got {dict(item)!r}')
    try:
        return tuple(item["node"])
    except TypeError:
        raise IsochorError(f'{what}: "node" must be [i, j, k], got {item["node"]!r}') from None


def _pair(item: Any) -> tuple:
    try:
        node, offset = item
    except (TypeError, ValueError):
        raise IsochorError(
            f"moves: each is ((i, j, k), (dx, dy, dz)) or a dict, got {item!r}"
        ) from None
    return node, offset
