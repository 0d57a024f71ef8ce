"""The scenario document: everything needed to reproduce a deformation, as one JSON file.

Version 1::

    {
      "format": "isochor-scenario",
      "version": 1,
      "model": {"path": "cow.obj"}            or {"builtin": "torus", ...shape parameters},
      "lattice": {"nodes": [5, 2, 2], "padding": 0.05}
                 or {"nodes": [...], "frame": {"origin": [x, y, z], "axes": [[..], [..], [..]]}},
      "moves": [{"node": [0, 0, 0], "by": [0.0, 1.5, 0.0]},
                {"node": [4, 1, 1], "to": [5.2, 3.1, 1.0]}],
      "pins": [[2, 0, 0]],
      "target_volume_ratio": 1.0,
      "tolerance": {"volume": 0.0005, "nodes": 0.001}
    }

A moved node is fixed at its new place, a pinned node where it rests; all others are free.
Relative model paths are relative to the scenario file. Unknown keys, wrong types,
out-of-range nodes and unsupported versions raise :class:`IsochorError` naming the field.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from core.errors import IsochorError
from core.lattice import MAX_NODES, MIN_NODES, Lattice
from core.mesh import TriMesh
from core.multilevel import EmbeddedSurface
from core.shapes import builtin_levels
from core.solver import SolverOptions

FORMAT = "isochor-scenario"
VERSION = 1


@dataclass(frozen=True)
class Move:
    """Node (i, j, k) moved ``by`` an offset or ``to`` a position (exactly one is set)."""

    node: tuple[int, int, int]
    by: tuple[float, float, float] | None = None
    to: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Scenario:
    model: dict[str, Any]
    lattice_nodes: tuple[int, int, int] = (3, 3, 3)
    padding: float = 0.05
    frame: tuple[tuple[float, ...], tuple[tuple[float, ...], ...]] | None = None
    moves: tuple[Move, ...] = ()
    pins: tuple[tuple[int, int, int], ...] = ()
    target_volume_ratio: float = 1.0
    tol_volume: float = 5e-4
    tol_nodes: float = 1e-3
    base_dir: Path | None = field(default=None, compare=False)

    # -- JSON ---------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, doc: Any, base_dir: str | Path | None = None) -> Scenario:
        _check_keys(doc, "scenario", {"format", "version", "model", "lattice", "moves", "pins",
                                      "target_volume_ratio", "tolerance"}, {"model"})
        if doc.get("format", FORMAT) != FORMAT:
            raise IsochorError(f"format: expected {FORMAT!r}, got {doc.get('format')!r}")
        version = doc.get("version", VERSION)
        if version != VERSION or isinstance(version, bool):
            raise IsochorError(f"version: this Isochor reads version {VERSION}, got {version!r}")
        model = doc["model"]
        _check_keys(model, "model", None, set())
        if ("path" in model) == ("builtin" in model):
            raise IsochorError("model: give exactly one of 'path' or 'builtin'")
        if "path" in model:
            _check_keys(model, "model", {"path"}, {"path"})
            if not isinstance(model["path"], str) or not model["path"]:
                raise IsochorError("model.path: must be a non-empty string")
        elif not isinstance(model["builtin"], str):
            raise IsochorError("model.builtin: must be a string")
        lat = doc.get("lattice", {})
        _check_keys(lat, "lattice", {"nodes", "padding", "frame"}, set())
        shape = _int_triple(lat.get("nodes", [3, 3, 3]), "lattice.nodes")
        if not all(MIN_NODES <= s <= MAX_NODES for s in shape):
            raise IsochorError(f"lattice.nodes: each axis needs {MIN_NODES} to {MAX_NODES} nodes")
        padding = _number(lat.get("padding", 0.05), "lattice.padding")
        if not 0 < padding <= 10:
            raise IsochorError("lattice.padding: must be positive (a fraction of the extent)")
        frame = None
        if "frame" in lat:
            fr = lat["frame"]
            _check_keys(fr, "lattice.frame", {"origin", "axes"}, {"origin", "axes"})
            axes = fr["axes"]
            if not isinstance(axes, list) or len(axes) != 3:
                raise IsochorError("lattice.frame.axes: must be three [x, y, z] edge vectors")
            frame = (_vec(fr["origin"], "lattice.frame.origin"),
                     tuple(_vec(a, f"lattice.frame.axes[{n}]") for n, a in enumerate(axes)))
        moves = []
        for n, mv in enumerate(_list(doc.get("moves", []), "moves")):
            where = f"moves[{n}]"
            _check_keys(mv, where, {"node", "by", "to"}, {"node"})
            if ("by" in mv) == ("to" in mv):
                raise IsochorError(f"{where}: give exactly one of 'by' or 'to'")
            node = _node(mv["node"], f"{where}.node", shape)
            if any(m.node == node for m in moves):
                raise IsochorError(f"{where}.node: node {list(node)} is already moved")
            if "by" in mv:
                moves.append(Move(node, by=_vec(mv["by"], f"{where}.by")))
            else:
                moves.append(Move(node, to=_vec(mv["to"], f"{where}.to")))
        pins = tuple(_node(p, f"pins[{n}]", shape)
                     for n, p in enumerate(_list(doc.get("pins", []), "pins")))
        ratio = _number(doc.get("target_volume_ratio", 1.0), "target_volume_ratio")
        if not ratio > 0:
            raise IsochorError("target_volume_ratio: must be positive")
        tol = doc.get("tolerance", {})
        _check_keys(tol, "tolerance", {"volume", "nodes"}, set())
        tv = _number(tol.get("volume", 5e-4), "tolerance.volume")
        tn = _number(tol.get("nodes", 1e-3), "tolerance.nodes")
        if not (0 < tv < 1 and 0 < tn < 1):
            raise IsochorError("tolerance: volume and nodes must be between 0 and 1")
        return cls(dict(model), shape, padding, frame, tuple(moves), pins, ratio, tv, tn,
                   Path(base_dir) if base_dir is not None else None)

    def to_dict(self) -> dict[str, Any]:
        lattice: dict[str, Any] = {"nodes": list(self.lattice_nodes)}
        if self.frame is None:
            lattice["padding"] = self.padding
        else:
            lattice["frame"] = {"origin": list(self.frame[0]),
                                "axes": [list(a) for a in self.frame[1]]}
        moves = []
        for mv in self.moves:
            d: dict[str, Any] = {"node": list(mv.node)}
            if mv.by is not None:
                d["by"] = list(mv.by)
            else:
                d["to"] = list(mv.to)
            moves.append(d)
        return {
            "format": FORMAT,
            "version": VERSION,
            "model": dict(self.model),
            "lattice": lattice,
            "moves": moves,
            "pins": [list(p) for p in self.pins],
            "target_volume_ratio": self.target_volume_ratio,
            "tolerance": {"volume": self.tol_volume, "nodes": self.tol_nodes},
        }

    # -- files --------------------------------------------------------------------------
    @classmethod
    def read(cls, path: str | Path) -> Scenario:
        path = Path(path)
        if path.suffix.lower() in {".obj", ".ply", ".stl", ".off"}:
            raise IsochorError(
                f"{path}: this is a model, not a scenario file; open it with `isochor edit`, "
                "or name it as model.path in a scenario"
            )
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise IsochorError(f"{path}: no such scenario file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise IsochorError(f"{path}: cannot read the scenario ({exc})") from None
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise IsochorError(f"{path}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
        except RecursionError:
            raise IsochorError(f"{path}: not a scenario (nested too deeply)") from None
        try:
            return cls.from_dict(doc, path.parent)
        except IsochorError as exc:
            raise IsochorError(f"{path}: {exc}") from None

    def write(self, path: str | Path) -> None:
        """Write atomically: a temporary file in the same folder, then a rename.

        A relative model path is rewritten relative to the new file's folder."""
        path = Path(path)
        doc = self.to_dict()
        if "path" in self.model:
            src = self.model_path()
            try:
                doc["model"]["path"] = os.path.relpath(src, path.parent.resolve())
            except ValueError:  # another drive on Windows
                doc["model"]["path"] = str(src)
        atomic_write_text(path, json.dumps(doc, indent=2) + "\n")

    def model_path(self) -> Path:
        p = Path(self.model["path"])
        if not p.is_absolute() and self.base_dir is not None:
            p = self.base_dir / p
        return p.resolve()

    def with_(self, **changes) -> Scenario:
        return replace(self, **changes)


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically; see :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename,
    so that a failure (or Ctrl-C) never leaves a half-written file.

    The new file gets the permissions of the file it replaces, or the usual ones for a new
    file (0666 less the umask), not the private mode of the temporary file."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _file_mode(path))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _file_mode(path: Path) -> int:
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


@dataclass
class Problem:
    """A scenario made ready to solve: the embedded surface, start nodes and pins."""

    scenario: Scenario
    surface: EmbeddedSurface
    nodes: np.ndarray  #: (n, 3) start positions: rest lattice with the moves applied
    fixed: np.ndarray  #: (n,) bool: moved or pinned
    warnings: list[str] = field(default_factory=list)

    @property
    def options(self) -> SolverOptions:
        return SolverOptions(tol_volume=self.scenario.tol_volume,
                             tol_nodes=self.scenario.tol_nodes)


#: ``path -> (levels coarse to fine, warnings)``; set by :mod:`core.meshio` for files.
LevelLoader = Callable[[Path], tuple[list[TriMesh], list[str]]]


def model_levels(scenario: Scenario, loader: LevelLoader | None = None):
    """The level pyramid and load warnings of the scenario's model."""
    if "builtin" in scenario.model:
        params = {k: v for k, v in scenario.model.items() if k != "builtin"}
        return builtin_levels(scenario.model["builtin"], **params), []
    if loader is None:
        from core.meshio import load_levels as loader  # noqa: PLC0415 (optional heavy import)
    return loader(scenario.model_path())


def build(scenario: Scenario, loader: LevelLoader | None = None,
          levels: list[TriMesh] | None = None, warnings: list[str] | None = None) -> Problem:
    """Load the model (unless ``levels`` are given), fit the lattice, apply moves and pins."""
    if levels is None:
        levels, warnings = model_levels(scenario, loader)
    if scenario.frame is None:
        lattice = Lattice.around(levels[-1].vertices, scenario.lattice_nodes, scenario.padding)
    else:
        lattice = Lattice(scenario.lattice_nodes, scenario.frame[0], scenario.frame[1])
    nodes = lattice.rest_nodes.copy()
    fixed = np.zeros(lattice.n_nodes, dtype=bool)
    for mv in scenario.moves:
        r = lattice.index(*mv.node)
        nodes[r] = (nodes[r] + mv.by) if mv.by is not None else mv.to
        fixed[r] = True
    for p in scenario.pins:
        fixed[lattice.index(*p)] = True
    return Problem(scenario, EmbeddedSurface(lattice, levels), nodes, fixed, list(warnings or []))


# -- validation helpers ---------------------------------------------------------------------
def _check_keys(obj: Any, where: str, allowed: set[str] | None, required: set[str]) -> None:
    if not isinstance(obj, dict):
        raise IsochorError(f"{where}: must be a JSON object")
    if allowed is not None:
        unknown = sorted(set(obj) - allowed)
        if unknown:
            raise IsochorError(f"{where}: unknown key {unknown[0]!r}")
    missing = sorted(required - set(obj))
    if missing:
        raise IsochorError(f"{where}: missing key {missing[0]!r}")


def _list(obj: Any, where: str) -> list:
    if not isinstance(obj, list):
        raise IsochorError(f"{where}: must be a list")
    return obj


def _number(obj: Any, where: str) -> float:
    if isinstance(obj, bool) or not isinstance(obj, (int, float)) or not np.isfinite(obj):
        raise IsochorError(f"{where}: must be a finite number, got {obj!r}")
    return float(obj)


def _vec(obj: Any, where: str) -> tuple[float, float, float]:
    if not isinstance(obj, list) or len(obj) != 3:
        raise IsochorError(f"{where}: must be a list of three numbers")
    return tuple(_number(x, where) for x in obj)


def _int_triple(obj: Any, where: str) -> tuple[int, int, int]:
    if not isinstance(obj, list) or len(obj) != 3 or not all(
        isinstance(x, int) and not isinstance(x, bool) for x in obj
    ):
        raise IsochorError(f"{where}: must be a list of three whole numbers")
    return tuple(obj)


def _node(obj: Any, where: str, shape: tuple[int, int, int]) -> tuple[int, int, int]:
    ijk = _int_triple(obj, where)
    if not all(0 <= a < s for a, s in zip(ijk, shape)):
        raise IsochorError(
            f"{where}: node {list(ijk)} is outside the {shape[0]}x{shape[1]}x{shape[2]} lattice"
        )
    return ijk
