"""From a scenario to a solvable problem: load the model's level pyramid, fit the lattice,
apply the moves and pins.

The scenario document (:mod:`isochor.core.scenario.document`) knows nothing of meshes; this module
brings the document, the model files (:mod:`isochor.core.io.meshio`), the level pyramid
(:mod:`isochor.core.solve.pyramid`), the built-in shapes and the embedded surface together.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from .. import forked, kernels
from ..errors import IsochorError
from ..goal.handles import Handle
from ..goal.spec import Goal
from ..goal.symmetry import Mirror
from ..io.meshio import load_mesh
from ..lattice import Lattice
from ..mesh import TriMesh
from ..solve import multilevel
from ..solve.multilevel import EmbeddedSurface
from ..solve.pyramid import build_pyramid
from ..solve.records import Progress, SolveResult
from ..solve.solver import SolverOptions
from .document import Scenario
from .shapes import builtin_levels


@dataclass(frozen=True)
class SourceFile:
    """The model file a problem was loaded from, as it was then: the export rewrites this
    very file (:mod:`isochor.core.export`), so it must not have changed since."""

    path: Path
    size: int
    mtime_ns: int

    @classmethod
    def of(cls, path: str | Path) -> SourceFile:
        info = Path(path).stat()
        return cls(Path(path), info.st_size, info.st_mtime_ns)

    def unchanged(self) -> bool:
        try:
            info = self.path.stat()
        except OSError:
            return False
        return (info.st_size, info.st_mtime_ns) == (self.size, self.mtime_ns)


@dataclass(frozen=True)
class Model:
    """A model made ready to embed: its level pyramid (coarse to fine, the last is the
    full mesh), what loading it said, and the file it came from (None for a built-in
    shape or a mesh given in memory)."""

    levels: tuple[TriMesh, ...]
    warnings: tuple[str, ...] = ()
    source: SourceFile | None = None
    #: how many separate bodies the full mesh has, when loading counted them (None: not
    #: known); a solve reuses it instead of labelling the faces again
    bodies: int | None = None


@dataclass
class Problem:
    """A scenario made ready to solve: the embedded surface, start nodes and pins."""

    scenario: Scenario
    surface: EmbeddedSurface
    nodes: np.ndarray  #: (n, 3) start positions: rest lattice with the moves applied
    fixed: np.ndarray  #: (n, 3) bool: the fixed coordinates (moved, pinned, axis-pinned)
    model: Model
    #: what the lattice's fit says (the part of the model outside an explicit frame)
    coverage: str | None = None

    @property
    def warnings(self) -> list[str]:
        """Everything the user should know: the model's load warnings and the coverage."""
        return [*self.model.warnings, *([self.coverage] if self.coverage else [])]

    @property
    def options(self) -> SolverOptions:
        return SolverOptions(tol_volume=self.scenario.tol_volume, tol_nodes=self.scenario.tol_nodes)

    def solve(
        self,
        nodes: np.ndarray | None = None,
        fixed: np.ndarray | None = None,
        *,
        goal: Goal | None = None,
        handles: Sequence[Handle] | None = None,
        options: SolverOptions | None = None,
        live: bool = False,
        near: bool = False,
        start_level: int | None = None,
    ) -> Generator[Progress, None, SolveResult]:
        """Start a solve of this problem: the one place every caller (the command line,
        the API's session, the window's worker, sequences, the benchmark) starts one.

        Each piece defaults to the problem's own: its start ``nodes`` and ``fixed``
        coordinates, the scenario's ``goal`` and ``handles``, the scenario's tolerances
        (``options``). A caller that edits (the window, a session, a frame of a sequence)
        gives its own. ``live``, ``near`` and ``start_level`` are
        :func:`isochor.core.solve.multilevel.solve`'s.

        Returns
        -------
        The progress generator of :func:`isochor.core.solve.multilevel.solve`: it yields
        :class:`~isochor.core.solve.records.Progress` records and returns the
        :class:`~isochor.core.solve.records.SolveResult`; closing it stops the solve.
        """
        sc = self.scenario
        return multilevel.solve(
            self.surface,
            self.nodes if nodes is None else nodes,
            self.fixed if fixed is None else fixed,
            goal=sc.goal if goal is None else goal,
            handles=sc.handles if handles is None else handles,
            options=self.options if options is None else options,
            start_level=start_level,
            near=near,
            live=live,
        )


#: ``path -> Model``: how a model file becomes a pyramid.
ModelLoader = Callable[[Path], Model]


#: ``callable(stage, fraction)``: how far loading (``"load"``) or a solve (``"solve"``) is,
#: the fraction from 0 to 1 (:class:`isochor.core.api.Session`'s ``progress``)
ProgressCallback = Callable[[str, float], None]
#: the share of loading a model file that reading and cleaning it take (the level pyramid
#: the rest; measured on the 1.38M armadillo: about a third)
READ_SHARE = 0.35
#: a model of this many triangles has its coarse levels made in a forked child, where the
#: process can fork (:func:`pyramid_of`)
APART_TRIANGLES = 100_000


def load_model(path: str | Path, progress: ProgressCallback | None = None) -> Model:
    """The level pyramid of a model file, the warnings of loading it and its fingerprint:
    the default :data:`ModelLoader`. ``progress`` hears ``("load", fraction)``."""
    source = SourceFile.of(path)
    kernels.start(auto=True)  # loads in the background meanwhile: the pyramid checks use them
    if progress is not None:
        progress("load", 0.0)
    loaded = load_mesh(path)
    levels = pyramid_of(loaded.mesh, loaded.bodies, progress, READ_SHARE)
    return Model(tuple(levels), tuple(loaded.warnings), source, loaded.bodies)


def pyramid_of(
    mesh: TriMesh, bodies: int | None, progress: ProgressCallback | None, done: float = 0.0
) -> list[TriMesh]:
    """:func:`build_pyramid`, telling ``progress`` the share of loading done: ``done``
    before, 1 at the end. From :data:`APART_TRIANGLES` triangles on, the coarse levels are
    made in a forked child (:mod:`isochor.core.forked`): fast-simplification never frees
    its working copy of the finest level (about 300 bytes a triangle)."""
    if progress is not None:
        progress("load", done)
    share = None if progress is None else (lambda f: progress("load", done + (1 - done) * f))
    if mesh.n_faces < APART_TRIANGLES:
        levels = build_pyramid(mesh, bodies=bodies, progress=share)
    else:
        coarse = forked.call(_coarse_levels, mesh, bodies, progress=share)
        levels = [TriMesh(v, f, cv, cf) for v, f, cv, cf in coarse] + [mesh]
    if progress is not None:
        progress("load", 1.0)
    return levels


def _coarse_levels(mesh: TriMesh, bodies: int | None, progress=None) -> list[tuple]:
    """The arrays of the pyramid's levels but the finest (``mesh`` itself), to be pickled."""
    levels = build_pyramid(mesh, bodies=bodies, progress=progress)
    return [(m.vertices, m.faces, m.cap_vertices, m.cap_faces) for m in levels[:-1]]


def scenario_model(
    scenario: Scenario, loader: ModelLoader | None = None, progress: ProgressCallback | None = None
) -> Model:
    """The scenario's model: a built-in shape's levels, or its file loaded (``progress``
    hears how far loading the file is, unless a ``loader`` of its own loads it)."""
    if "builtin" in scenario.model:
        params = {k: v for k, v in scenario.model.items() if k != "builtin"}
        return Model(tuple(builtin_levels(scenario.model["builtin"], **params)), bodies=1)
    path = scenario.model_path()
    if not path.exists():
        what = "a loop of symbolic links" if path.is_symlink() else "no such file"
        where = f"{scenario.source}: " if scenario.source is not None else ""
        raise IsochorError(
            f"{where}model.path {scenario.model['path']!r}: {what} (looked for {path})"
        )
    if loader is not None:
        return loader(path)
    return load_model(path, progress)


def default_lattice_shape(mesh: TriMesh) -> tuple[int, int, int]:
    """The lattice a model opens in: 4 nodes along its longest extent, 3 along the others."""
    shape = [3, 3, 3]
    shape[int(np.argmax(mesh.extents))] = 4
    return cast("tuple[int, int, int]", tuple(shape))


def coverage(lattice: Lattice, points: np.ndarray) -> str | None:
    """A sentence when part of the model lies outside the lattice box, where the FFD is a
    polynomial extrapolation rather than the lattice's own deformation; None when all of
    it is inside."""
    uvw = lattice.to_parameters(points)
    beyond = np.maximum(-uvw, uvw - 1).max(axis=1)  # > 0 outside, in box sizes
    outside = int(np.sum(beyond > 1e-9))
    if not outside:
        return None
    return (
        f"{100 * outside / len(points):.3g}% of the model's vertices ({outside} of "
        f"{len(points)}) lie outside the lattice frame, up to {beyond.max():.3g} of its "
        + (
            "size: there it follows the nearest face of the lattice (as in Blender)."
            if lattice.local
            else "size: the deformation there is extrapolated, not controlled by the lattice."
        )
    )


def build(
    scenario: Scenario, loader: ModelLoader | None = None, model: Model | None = None
) -> Problem:
    """Load the model (unless given), fit the lattice, apply moves and pins."""
    if model is None:
        model = scenario_model(scenario, loader)
    levels = model.levels
    basis, outside = scenario.lattice_basis, scenario.lattice_outside
    if scenario.frame is None:
        lattice = Lattice.around(
            levels[-1].vertices, scenario.lattice_nodes, scenario.padding, basis, outside
        )
    else:
        lattice = Lattice(
            scenario.lattice_nodes,
            np.asarray(scenario.frame[0]),
            np.asarray(scenario.frame[1]),
            basis,
            outside,
        )
    nodes, fixed = scenario.edit.apply(lattice)
    Mirror.of(lattice, scenario.goal.symmetry)  # a frame the mirror cannot use fails here
    _check_digits(lattice, levels[-1], scenario.tol_volume)
    surface = EmbeddedSurface(lattice, levels, n_bodies=model.bodies)
    fit = coverage(lattice, surface.full.vertices)
    return Problem(scenario, surface, nodes, fixed, model, fit)


def _check_digits(lattice: Lattice, mesh, tolerance: float) -> None:
    """Refuse a model too far from the origin for its size: its points (and the lattice's
    nodes) are stored as doubles, ``ulp`` apart at their distance, so each may sit up to
    about one ``ulp`` from where it belongs, and the volume by up to ``ulp x area``. Where
    that exceeds the volume tolerance no result could be measured within it (a box 64
    across is fine at 1e13 and not at 3e14; one 1 across not beyond about 1e10)."""
    from ..volume import signed_volume

    far = max(float(np.abs(lattice.rest_nodes).max()), float(np.abs(mesh.vertices).max()))
    ulp = float(np.spacing(far))
    tri = mesh.vertices[mesh.faces]
    area = 0.5 * float(
        np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )
    volume = abs(signed_volume(mesh.vertices, mesh.faces))
    if volume > 0 and ulp * area > tolerance * volume:
        raise IsochorError(
            f"the model lies too far from the origin for its size: at {far:.3g} doubles are "
            f"{ulp:.3g} apart, which can move its volume by {ulp * area / volume:.2e} of "
            f"itself, more than the tolerance {tolerance:g}; move it nearer the origin (or "
            "raise tolerance.volume)"
        )
