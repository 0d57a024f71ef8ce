"""The scenario document: everything needed to reproduce a deformation, as one JSON file.

Version 1::

    {
      "format": "isochor-scenario",
      "version": 1,
      "model": {"path": "cow.obj"}            or {"builtin": "torus", ...shape parameters},
      "lattice": {"nodes": [5, 2, 2], "padding": 0.05}
                 or {"nodes": [...], "frame": {"origin": [x, y, z], "axes": [[..], [..], [..]]}},
                 optional "basis": "bernstein" (the default), "bspline", "catmull-rom",
                 "cardinal", "linear" or one per axis ["bspline", "linear", "bspline"]
                 (Blender's lattice, :mod:`isochor.core.localbasis`: 1 to 64 nodes per
                 axis), and "outside": true (Blender's option; local bases only)
      "moves": [{"node": [0, 0, 0], "by": [0.0, 1.5, 0.0]},
                {"node": [4, 1, 1], "to": [5.2, 3.1, 1.0]}],
      "pins": [[2, 0, 0]],
      "target_volume_ratio": 1.0,
      "tolerance": {"volume": 0.0005, "nodes": 0.001}
    }

Version 3 adds direct manipulation and symmetric editing::

      "handles": [{"at": [x, y, z], "to": [x, y, z]}],   a point of the model at rest (at)
                                       that must land at ``to`` (:mod:`isochor.core.goal.handles`)
      "symmetry": "x"                  or "y", "z", "none" (the default): the edit and the
                                       result are mirror images across the lattice's
                                       mid-plane (:mod:`isochor.core.goal.symmetry`)
      "poses": [{"frame": 12, "moves": [...], "pins": [...], "handles": [...],
                 "target_volume_ratio": 0.9}],   keyframed edits (scenario.poses)
      "timeline": {"start": 0, "end": 24, "rate": 24, "interpolation": "smooth"}

Version 2 adds what a solve holds besides the volume (:class:`isochor.core.goal.spec.Goal`);
a file that uses none of it is still written as version 1, and version 1 files read as
before::

      "pins": [[2, 0, 0], {"node": [0, 1, 1], "axes": "z"}],   a pin on some axes only
      "preserve": "per-body",          or "total" (the default): each body keeps its volume
      "keep_centroid": true,           keep the solid's centre of mass (default false)
      "anchor": "none",                or "far-side" (the default): hold the lattice face
                                       the edit pushes towards (or the farthest from it)
                                       unless the far side is fixed by the scenario
      "fold_guard": false              (default true) penalise folding the model

A moved node is fixed at its new place, a pinned node where it rests; all others are free.
Relative model paths are relative to the scenario file. Unknown keys, wrong types,
out-of-range nodes and unsupported versions raise :class:`IsochorError` naming the field.

This module is the document only: reading, checking and writing it. Turning a scenario
into something to solve (loading the model, fitting the lattice) is
:mod:`isochor.core.scenario.problem`.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..defaults import LATTICE_NODES, PADDING, TOL_NODES, TOL_VOLUME
from ..errors import IsochorError
from ..goal.handles import Handle
from ..goal.spec import GOAL_FIELDS, Goal
from ..io.atomic import atomic_write_text
from ..io.companions import model_inputs
from ..io.formats import is_model
from ..lattice import MAX_NODES, MIN_NODES, basis_names
from ..localbasis import BERNSTEIN, MAX_LOCAL, MIN_LOCAL
from ..validate import (
    check_keys,
    input_file,
    int_triple,
    number,
    parse_constant,
    parse_int,
    show,
    vec3,
)
from .edits import Edit, Move
from .poses import Timeline

FORMAT = "isochor-scenario"
VERSION = 3
VERSIONS = (1, 2, 3)
#: the keys version 2 added: the goal's (:data:`isochor.core.goal.spec.GOAL_FIELDS`)
V2_KEYS = tuple(f.key for f in GOAL_FIELDS if f.version == 2)
#: the keys version 3 added
V3_KEYS = ("handles", *(f.key for f in GOAL_FIELDS if f.version == 3), "poses", "timeline")

#: a scenario is a few kilobytes; anything larger than this is not one
MAX_SCENARIO_BYTES = 16 * 2**20
#: the tolerances: the range the solver is meant for (the volume ratio's is
#: :data:`isochor.core.goal.spec.RATIO_RANGE`)
TOLERANCE_RANGE = (1e-12, 0.5)


@dataclass(frozen=True)
class Scenario:
    model: dict[str, Any]
    lattice_nodes: tuple[int, int, int] = LATTICE_NODES
    padding: float = PADDING
    frame: tuple[tuple[float, ...], tuple[tuple[float, ...], ...]] | None = None
    moves: tuple[Move, ...] = ()
    pins: tuple[tuple[int, int, int], ...] = ()  #: pinned on all three axes
    #: pinned on some axes only: (node, axes) with axes a non-empty part of "xyz"
    axis_pins: tuple[tuple[tuple[int, int, int], str], ...] = ()
    #: what the solve must hold: the target ratio and the rest of the goal
    goal: Goal = Goal()
    tol_volume: float = TOL_VOLUME
    tol_nodes: float = TOL_NODES
    handles: tuple[Handle, ...] = ()
    #: keyframed poses and the frames to solve (:mod:`isochor.core.scenario.poses`), or None
    timeline: Timeline | None = None
    base_dir: Path | None = field(default=None, compare=False)
    #: the file it was read from, for messages (None when built in memory)
    source: Path | None = field(default=None, compare=False)
    #: the lattice's per-axis basis (:data:`isochor.core.localbasis.NAMES`)
    lattice_basis: tuple[str, str, str] = (BERNSTEIN,) * 3
    #: Blender's "Outside" option of a local basis
    lattice_outside: bool = False

    # -- JSON ---------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, doc: Any, base_dir: str | Path | None = None) -> Scenario:
        check_keys(
            doc,
            "scenario",
            {
                "format",
                "version",
                "model",
                "lattice",
                "moves",
                "pins",
                "tolerance",
                *(f.key for f in GOAL_FIELDS),
                *V3_KEYS,
            },
            {"model"},
        )
        if doc.get("format", FORMAT) != FORMAT:
            raise IsochorError(f"format: expected {FORMAT!r}, got {doc.get('format')!r}")
        version = doc.get("version", VERSION)
        if version not in VERSIONS or isinstance(version, bool):
            raise IsochorError(
                f"version: this Isochor reads versions 1 to {VERSION}, got {show(version)}"
            )
        for newer, keys in ((3, set(V3_KEYS)), (2, set(V2_KEYS))):
            if version < newer and set(doc) & keys:
                raise IsochorError(
                    f"{sorted(set(doc) & keys)[0]}: a version {newer} key in a version "
                    f'{version} scenario; set "version": {newer}'
                )
        model = doc["model"]
        check_keys(model, "model", None, set())
        if ("path" in model) == ("builtin" in model):
            raise IsochorError("model: give exactly one of 'path' or 'builtin'")
        if "path" in model:
            check_keys(model, "model", {"path"}, {"path"})
            if not isinstance(model["path"], str) or not model["path"]:
                raise IsochorError("model.path: must be a non-empty string")
            if "\0" in model["path"]:
                raise IsochorError("model.path: not a valid file name (it holds a NUL byte)")
        elif not isinstance(model["builtin"], str):
            raise IsochorError("model.builtin: must be a string")
        lat = doc.get("lattice", {})
        check_keys(lat, "lattice", {"nodes", "padding", "frame", "basis", "outside"}, set())
        try:
            basis = basis_names(lat.get("basis", BERNSTEIN))
        except IsochorError as exc:
            raise IsochorError(f"lattice.basis: {exc}") from None
        local = basis[0] != BERNSTEIN
        outside = lat.get("outside", False)
        if not isinstance(outside, bool):
            raise IsochorError("lattice.outside: must be true or false")
        if outside and not local:
            raise IsochorError("lattice.outside: needs a local basis (bspline, ...), not bernstein")
        low, high = (MIN_LOCAL, MAX_LOCAL) if local else (MIN_NODES, MAX_NODES)
        shape = int_triple(lat.get("nodes", list(LATTICE_NODES)), "lattice.nodes")
        if not all(low <= s <= high for s in shape):
            which = "" if local else " (the Bernstein basis; 1 to 64 with a local one)"
            raise IsochorError(f"lattice.nodes: each axis needs {low} to {high} nodes{which}")
        padding = number(lat.get("padding", PADDING), "lattice.padding")
        if not 0 < padding <= 10:
            raise IsochorError(
                "lattice.padding: must be more than 0 and at most 10 (a fraction of the extent)"
            )
        frame = None
        if "frame" in lat:
            fr = lat["frame"]
            check_keys(fr, "lattice.frame", {"origin", "axes"}, {"origin", "axes"})
            axes = fr["axes"]
            if not isinstance(axes, list) or len(axes) != 3:
                raise IsochorError("lattice.frame.axes: must be three [x, y, z] edge vectors")
            frame = (
                vec3(fr["origin"], "lattice.frame.origin"),
                tuple(vec3(a, f"lattice.frame.axes[{n}]") for n, a in enumerate(axes)),
            )
        edit = Edit.from_json(doc, shape, version)
        goal = Goal.from_json(doc)
        timeline = Timeline.from_json(doc.get("poses", []), doc.get("timeline"), shape, version)
        tol = doc.get("tolerance", {})
        check_keys(tol, "tolerance", {"volume", "nodes"}, set())
        tv = number(tol.get("volume", TOL_VOLUME), "tolerance.volume", TOLERANCE_RANGE)
        tn = number(tol.get("nodes", TOL_NODES), "tolerance.nodes", TOLERANCE_RANGE)
        return cls(
            dict(model),
            shape,
            padding,
            frame,
            edit.moves,
            edit.pins,
            edit.axis_pins,
            goal=goal,
            tol_volume=tv,
            tol_nodes=tn,
            handles=edit.handles,
            timeline=timeline,
            base_dir=Path(base_dir) if base_dir is not None else None,
            lattice_basis=basis,
            lattice_outside=outside,
        )

    @property
    def edit(self) -> Edit:
        """The moves, pins and handles."""
        return Edit(self.moves, self.pins, self.axis_pins, self.handles)

    @property
    def version(self) -> int:
        """The oldest version that can hold this scenario: 3 with handles, poses or
        symmetry, 2 when a version 2 key differs from its default (or an axis pin is
        used), else 1."""
        if self.handles or self.timeline is not None:
            return 3
        return max(self.goal.version, 2 if self.axis_pins else 1)

    def to_dict(self) -> dict[str, Any]:
        lattice: dict[str, Any] = {"nodes": list(self.lattice_nodes)}
        if self.lattice_basis != (BERNSTEIN,) * 3:
            one = len(set(self.lattice_basis)) == 1
            lattice["basis"] = self.lattice_basis[0] if one else list(self.lattice_basis)
        if self.lattice_outside:
            lattice["outside"] = True
        if self.frame is None:
            lattice["padding"] = self.padding
        else:
            lattice["frame"] = {
                "origin": list(self.frame[0]),
                "axes": [list(a) for a in self.frame[1]],
            }
        doc = {
            "format": FORMAT,
            "version": self.version,
            "model": dict(self.model),
            "lattice": lattice,
            **self.edit.to_json(),
            **self.goal.to_json({1}),
            "tolerance": {"volume": self.tol_volume, "nodes": self.tol_nodes},
            **self.goal.to_json(range(2, self.version + 1)),
        }
        if self.timeline is not None:
            doc["poses"], doc["timeline"] = self.timeline.to_json()
        return doc

    # -- files --------------------------------------------------------------------------
    @classmethod
    def read(cls, path: str | Path) -> Scenario:
        path = Path(path)
        if is_model(path):
            raise IsochorError(
                f"{path}: this is a model, not a scenario file; open it with `isochor edit`, "
                "or name it as model.path in a scenario"
            )
        try:
            input_file(path, "scenario", MAX_SCENARIO_BYTES)
            text = path.read_text(encoding="utf-8")
        except (OSError, ValueError) as exc:  # ValueError: a NUL byte, a bad encoding
            raise IsochorError(f"{path}: cannot read the scenario ({exc})") from None
        try:
            doc = json.loads(
                text,
                parse_int=parse_int,
                parse_constant=parse_constant,
                object_pairs_hook=_unique_keys,
            )
        except json.JSONDecodeError as exc:
            raise IsochorError(f"{path}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
        except RecursionError:
            raise IsochorError(f"{path}: not a scenario (nested too deeply)") from None
        except IsochorError as exc:
            raise IsochorError(f"{path}: not valid JSON ({exc})") from None
        try:
            return replace(cls.from_dict(doc, path.parent), source=path)
        except IsochorError as exc:
            raise IsochorError(f"{path}: {exc}") from None

    def write(self, path: str | Path) -> None:
        """Write atomically: a temporary file in the same folder, then a rename.

        The model path is written relative to the new file's folder, as the user sees the
        folders (symbolic links are not resolved), so a folder moved with its scenario and
        model still opens."""
        path = Path(path)
        doc = self.to_dict()
        if "path" in self.model:
            src = self.model_path()
            try:
                doc["model"]["path"] = os.path.relpath(src, os.path.abspath(path.parent))
            except ValueError:  # another drive on Windows
                doc["model"]["path"] = str(src)
        # never over the model or a file it reads (its material library, a buffer...)
        atomic_write_text(path, json.dumps(doc, indent=2) + "\n", self.inputs(scenario=False))

    def inputs(self, *, scenario: bool = True) -> list[tuple[Path, str]]:
        """``(path, role)`` of every file this scenario reads: the scenario file itself
        (with ``scenario``, when it was read from one), the model and the files the model
        reads (:func:`isochor.core.io.companions.model_inputs`). No output may name one
        (:func:`isochor.core.io.atomic.check_outputs`)."""
        found = [(self.source, "the scenario")] if scenario and self.source is not None else []
        if "path" in self.model:
            found += model_inputs(self.model_path())
        return found

    def model_path(self) -> Path:
        """The model file as an absolute path (relative paths are taken from the
        scenario's folder). Symbolic links are kept, not resolved."""
        p = Path(self.model["path"])
        if not p.is_absolute() and self.base_dir is not None:
            p = self.base_dir / p
        return Path(os.path.abspath(p))

    def checked(self, changes: dict[str, Any]) -> Scenario:
        """``scenario`` with ``changes``, each checked as the scenario file's field would be
        (the same one-line errors: ``lattice.nodes: each axis needs 2 to 10 nodes``).
        ``changes`` names ``lattice_nodes``, ``lattice_basis``, ``lattice_outside``,
        ``padding``, ``frame``, ``moves`` (a new
        lattice: the old edits go) and the goal's fields by their scenario keys."""
        doc = self.to_dict()
        doc["model"] = {"builtin": "sphere"}  # the model is not what is checked here
        lat = doc["lattice"]
        if "lattice_nodes" in changes:
            lat["nodes"] = [getattr(n, "item", lambda n=n: n)() for n in changes["lattice_nodes"]]
        if "lattice_basis" in changes:
            lat["basis"] = changes["lattice_basis"]
        if "lattice_outside" in changes:
            lat["outside"] = changes["lattice_outside"]
        if "padding" in changes:
            lat.pop("frame", None)
            lat["padding"] = changes["padding"]
        if "frame" in changes:
            lat.pop("padding", None)
            lat["frame"] = {"origin": changes["frame"][0], "axes": changes["frame"][1]}
        for f in GOAL_FIELDS:
            if f.key in changes:
                doc[f.key], doc["version"] = changes[f.key], VERSION
        if "moves" in changes:  # a new lattice: the old edits name nodes it may not have
            doc["moves"], doc["pins"] = [], []
            doc.pop("poses", None)
            doc.pop("timeline", None)
        checked = Scenario.from_dict(doc)
        return replace(checked, model=self.model, base_dir=self.base_dir, source=self.source)

    def with_(self, **changes) -> Scenario:
        """This scenario with some fields changed (the goal as a whole: ``goal=``)."""
        return replace(self, **changes)


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are all different: a key given twice (the second silently
    winning) is refused, naming it."""
    doc: dict[str, Any] = {}
    for key, value in pairs:
        if key in doc:
            shown = key if len(key) <= 60 else key[:57] + "..."
            raise IsochorError(f"the key {shown!r} is given twice in one object; give it once")
        doc[key] = value
    return doc
