"""From a scenario to a solvable problem: load the model's level pyramid, fit the lattice,
apply the moves and pins.

The scenario document (:mod:`isochor.core.scenario`) knows nothing of meshes; this module
brings the document, the model files (:mod:`isochor.core.meshio`), the level pyramid
(:mod:`isochor.core.pyramid`), the built-in shapes and the embedded surface together.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import IsochorError
from .lattice import Lattice
from .mesh import TriMesh
from .meshio import load_mesh
from .multilevel import EmbeddedSurface
from .pyramid import build_pyramid
from .scenario import Scenario
from .shapes import builtin_levels
from .solver import SolverOptions


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
        return SolverOptions(tol_volume=self.scenario.tol_volume, tol_nodes=self.scenario.tol_nodes)


#: ``path -> (levels coarse to fine, warnings)``: how a model file becomes a pyramid.
LevelLoader = Callable[[Path], tuple[list[TriMesh], list[str]]]


def load_levels(path: str | Path) -> tuple[list[TriMesh], list[str]]:
    """The level pyramid of a model file (coarse to fine, the last is the full mesh) and
    the warnings of loading it: the default :data:`LevelLoader`."""
    loaded = load_mesh(path)
    return build_pyramid(loaded.mesh), list(loaded.warnings)


#: a move may take a node at most this many lattice sizes away (a bigger one is a mistake
#: of units or of typing, and its numbers would overflow long before it meant anything)
MAX_MOVE = 1000.0


def model_levels(scenario: Scenario, loader: LevelLoader | None = None):
    """The level pyramid and load warnings of the scenario's model."""
    if "builtin" in scenario.model:
        params = {k: v for k, v in scenario.model.items() if k != "builtin"}
        return builtin_levels(scenario.model["builtin"], **params), []
    path = scenario.model_path()
    if not path.exists():
        what = "a loop of symbolic links" if path.is_symlink() else "no such file"
        where = f"{scenario.source}: " if scenario.source is not None else ""
        raise IsochorError(
            f"{where}model.path {scenario.model['path']!r}: {what} (looked for {path})"
        )
    return (loader or load_levels)(path)


def build(
    scenario: Scenario,
    loader: LevelLoader | None = None,
    levels: list[TriMesh] | None = None,
    warnings: list[str] | None = None,
) -> Problem:
    """Load the model (unless ``levels`` are given), fit the lattice, apply moves and pins."""
    if levels is None:
        levels, warnings = model_levels(scenario, loader)
    if scenario.frame is None:
        lattice = Lattice.around(levels[-1].vertices, scenario.lattice_nodes, scenario.padding)
    else:
        lattice = Lattice(scenario.lattice_nodes, scenario.frame[0], scenario.frame[1])
    nodes = lattice.rest_nodes.copy()
    fixed = np.zeros(lattice.n_nodes, dtype=bool)
    for n, mv in enumerate(scenario.moves):
        r = lattice.index(*mv.node)
        nodes[r] = (nodes[r] + mv.by) if mv.by is not None else mv.to
        fixed[r] = True
        distance = float(np.linalg.norm(nodes[r] - lattice.rest_nodes[r]))
        if distance > MAX_MOVE * lattice.size:
            raise IsochorError(
                f"moves[{n}]: moves node {list(mv.node)} by {distance:.3g}, more than "
                f"{MAX_MOVE:g} times the lattice's size ({lattice.size:.3g}); a wrong unit?"
            )
    for p in scenario.pins:
        fixed[lattice.index(*p)] = True
    return Problem(scenario, EmbeddedSurface(lattice, levels), nodes, fixed, list(warnings or []))
