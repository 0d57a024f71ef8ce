"""Scenarios on models read from files: the paper's cow bending (Plate 4) and two generic
edits (bend, squash) that the tests and the benchmark apply to any closed model.

The built-in examples (:mod:`core.scenario.examples`) use shapes that ship with the program; these
need a model file, such as the ones in ``../shared/models`` next to the repository:

- :func:`cow_bend_scenario`: the paper's Plate 4 / Table 1 "Cow Bending": the 5804-triangle
  cow in a 5x2x2 lattice along its length; the rear layer of nodes is pinned, the head
  layer is turned up by 40 degrees about the horizontal axis across the body, the three
  middle layers are free.
- :func:`bend_scenario`: the same edit for any model (lattice along x, turned about z).
- :func:`squash_scenario`: the top layer of a 4x3x3 lattice pushed down, the bottom layer
  pinned, the middle layer free (the torus compression of Plate 1, on any model).

Each returns an ordinary :class:`~core.scenario.document.Scenario` with ``by`` moves, so it can be
written to a file, solved by ``isochor solve``, opened in the window or timed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..defaults import PADDING, TOL_NODES, TOL_VOLUME
from ..io.meshio import load_mesh
from ..lattice import Lattice
from .document import Scenario

#: the file name of the paper's cow in the shared models folder
COW_FILE = "cow.obj"


def cow_bend_scenario(models_dir: str | Path) -> Scenario:
    """The paper's cow bending (Plate 4): ``models_dir/cow.obj`` in a 5x2x2 lattice, the
    head end (+x) turned up by 40 degrees, the rear end pinned."""
    return bend_scenario(Path(models_dir) / COW_FILE, angle_deg=40.0, nodes=(5, 2, 2))


def bend_scenario(
    model_path: str | Path, angle_deg: float = 40.0, nodes: tuple[int, int, int] = (5, 2, 2)
) -> Scenario:
    """Bend a model: an axis-aligned lattice around it; the i = 0 layer pinned, the last
    layer turned by ``angle_deg`` about the z axis through the centre of the layer before
    it (positive: the +x end goes up in y); all other nodes free.

    The model is read once to fit the lattice (the moves are offsets from its rest nodes).
    """
    path = Path(model_path).resolve()
    lattice = _rest_lattice(path, nodes)
    ni, nj, nk = lattice.shape
    rest = lattice.rest_nodes
    layer = [(j, k) for j in range(nj) for k in range(nk)]
    pivot = rest[[lattice.index(ni - 2, j, k) for j, k in layer]].mean(axis=0)
    t = np.radians(angle_deg)
    rot = np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0, 0, 1.0]])
    moves = []
    for j, k in layer:
        p = rest[lattice.index(ni - 1, j, k)]
        moves.append({"node": [ni - 1, j, k], "by": _offset(rot @ (p - pivot) + pivot - p)})
    pins = [[0, j, k] for j, k in layer]
    return _scenario(path, nodes, moves, pins)


def squash_scenario(
    model_path: str | Path, squash: float = 0.2, nodes: tuple[int, int, int] = (4, 3, 3)
) -> Scenario:
    """Squash a model along z: the top node layer (k = last) moved down by ``squash`` times
    the lattice height, the bottom layer (k = 0) pinned, the layers between free."""
    path = Path(model_path).resolve()
    lattice = _rest_lattice(path, nodes)
    ni, nj, nk = lattice.shape
    drop = _offset(np.array([0.0, 0.0, -squash * lattice.axes[2, 2]]))
    moves = [{"node": [i, j, nk - 1], "by": drop} for i in range(ni) for j in range(nj)]
    pins = [[i, j, 0] for i in range(ni) for j in range(nj)]
    return _scenario(path, nodes, moves, pins)


def _rest_lattice(path: Path, nodes: tuple[int, int, int]) -> Lattice:
    """The lattice :func:`core.scenario.document.build` will fit around the model."""
    return Lattice.around(load_mesh(path).mesh.vertices, nodes, PADDING)


def _offset(v: np.ndarray) -> list[float]:
    return [float(a) for a in v]


def _scenario(path: Path, nodes, moves: list[dict], pins: list[list[int]]) -> Scenario:
    doc = {
        "format": "isochor-scenario",
        "version": 1,
        "model": {"path": str(path)},
        "lattice": {"nodes": list(nodes), "padding": PADDING},
        "moves": moves,
        "pins": pins,
        "target_volume_ratio": 1.0,
        "tolerance": {"volume": TOL_VOLUME, "nodes": TOL_NODES},
    }
    return Scenario.from_dict(doc)
