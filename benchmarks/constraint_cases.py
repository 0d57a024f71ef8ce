"""The cases of the Constraints section (:mod:`benchmarks.constraints`), and running them.

``../shared/models`` cases are skipped with the reason when the file is absent:

* anchor: one corner node of the default lattice (``default_lattice_shape``) dragged
  outward along the diagonal by 0.3 of the lattice size, nothing pinned: far-side / none;
  on the cow and on the built-in torus;
* fold guard: on / off for the kitten bend (``bend_scenario``), the cow shrunk to a volume
  ratio of 0.2 with nothing pinned (default lattice), the cow bend (``cow_bend_scenario``);
* per body: two icospheres of radius 1 and 0.5 in one lattice, and
  ``multibody_inconsistent_winding.stl``, squashed (top layer down by 0.2 of the height,
  bottom pinned): per-body / total;
* centroid: the cow bend with keep_centroid on / off;
* axis pins: the cow squash with the bottom layer pinned on z only / on every axis.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from benchmarks.constraints import (
    DRAG,
    SHRINK,
    SQUASH,
    ConstraintRow,
    Pair,
    Variant,
    console_line,
    time_pair,
)
from isochor.core.goal.spec import Goal
from isochor.core.mesh import TriMesh
from isochor.core.scenario.document import Move, Scenario
from isochor.core.scenario.problem import Model, Problem, build, default_lattice_shape, load_model


def _problem(model: Model, name: str, **scenario) -> Problem:
    """A scenario on an in-memory model (``name`` only labels it)."""
    scenario.setdefault("lattice_nodes", default_lattice_shape(model.levels[-1]))
    return build(Scenario(model={"path": name}, **scenario), model=model)


def _goal_pair(p: Problem, constraint: str, key: str, case: str, field_: str, values, labels):
    """A pair that differs only in one field of the scenario's goal."""
    on, off = (
        Variant(lab, p.nodes, p.fixed, dataclasses.replace(p.scenario.goal, **{field_: val}))
        for val, lab in zip(values, labels)
    )
    return Pair(constraint, key, case, p, on, off)


def anchor_pair(model: Model, key: str, name: str) -> Pair:
    """Corner (0, 0, 0) of the default lattice dragged outward by :data:`DRAG` of the
    lattice size, nothing pinned: far-side against none."""
    p = _problem(model, name)
    lat = p.surface.lattice
    r = lat.index(0, 0, 0)
    out = lat.rest_nodes[r] - lat.rest_nodes.mean(axis=0)
    nodes, fixed = p.nodes.copy(), p.fixed.copy()
    nodes[r] += DRAG * lat.size * out / np.linalg.norm(out)
    fixed[r] = True
    on, off = (Variant(a, nodes, fixed, Goal(anchor=a)) for a in ("far-side", "none"))
    shape = "x".join(map(str, lat.shape))
    case = f"{name}, {shape} lattice, a corner dragged {DRAG:g} of the lattice size"
    return Pair("anchor", key, case, p, on, off)


def squash_problem(model: Model, name: str, shape=(4, 3, 3)) -> Problem:
    """``core.scenario.paper_models.squash_scenario`` on an in-memory model: the top node layer down
    by :data:`SQUASH` of the lattice height, the bottom layer pinned."""
    from isochor.core.defaults import PADDING
    from isochor.core.lattice import Lattice

    ni, nj, nk = shape
    lat = Lattice.around(model.levels[-1].vertices, shape, PADDING)
    drop = (0.0, 0.0, -SQUASH * float(lat.axes[2, 2]))
    moves = tuple(Move((i, j, nk - 1), by=drop) for i in range(ni) for j in range(nj))
    pins = tuple((i, j, 0) for i in range(ni) for j in range(nj))
    return _problem(model, name, lattice_nodes=shape, moves=moves, pins=pins)


def body_pair(model: Model, key: str, name: str) -> Pair:
    p = squash_problem(model, name)
    case = f"{name}, squashed by {SQUASH:g} of the height"
    return _goal_pair(
        p, "per body", key, case, "preserve", ("per-body", "total"), ("per-body", "total")
    )


def axis_pin_pair(model: Model, name: str) -> Pair:
    """The squash with the bottom layer pinned on z only, against pinned on every axis."""
    p = squash_problem(model, name)
    z_only = p.scenario.with_(pins=(), axis_pins=tuple((q, "z") for q in p.scenario.pins))
    loose = build(z_only, model=p.model)  # its nodes and fixed coordinates; p's surface
    goal = p.scenario.goal
    case = f"{name} squash, bottom layer pinned"
    return Pair(
        "axis pins",
        "cow-squash",
        case,
        p,
        Variant("z only", loose.nodes, loose.fixed, goal),
        Variant("x, y, z", p.nodes, p.fixed, goal),
    )


def two_spheres(subdivisions: int = 4) -> TriMesh:
    """An icosphere of radius 1 and one of radius 0.5 beside it, one mesh."""
    import trimesh

    a = trimesh.creation.icosphere(subdivisions, radius=1.0)
    b = trimesh.creation.icosphere(subdivisions, radius=0.5)
    b.apply_translation([1.8, 0.2, 0.1])
    both = trimesh.util.concatenate([a, b])
    return TriMesh(np.asarray(both.vertices), np.asarray(both.faces))


@dataclass
class Models:
    """The shared model files, each loaded (and its pyramid built) once per run;
    ``max_triangles`` cuts every pyramid there (tiny runs for the tests)."""

    folder: Path
    max_triangles: int | None = None
    _loaded: dict = field(default_factory=dict)

    def get(self, name: str) -> Model:
        if name not in self._loaded:
            m = load_model(self.folder / name)
            if self.max_triangles:
                cut = [lv for lv in m.levels if lv.n_faces <= self.max_triangles] or [m.levels[0]]
                m = dataclasses.replace(m, levels=tuple(cut))
            self._loaded[name] = m
        return self._loaded[name]


def _bend(model: Model) -> Problem:
    """``core.scenario.paper_models.bend_scenario`` (5x2x2 lattice along x, the +x layer turned 40
    degrees about z, the -x layer pinned; the cow's is ``cow_bend_scenario``) on a loaded
    model file."""
    from isochor.core.scenario.paper_models import bend_scenario

    return build(bend_scenario(model.source.path), model=model)


def _two_sphere_model(subdivisions: int) -> Model:
    from isochor.core.solve.pyramid import build_pyramid

    return Model(tuple(build_pyramid(two_spheres(subdivisions))))


FOLD_CASES = {
    "kitten-bend": "kitten bend (5x2x2, 40 degrees)",
    "cow-shrink": f"cow shrunk to {SHRINK:g} of its volume, nothing pinned",
    "cow-bend": "cow bend (5x2x2, 40 degrees)",
}
COW, KITTEN, MULTI = "cow.obj", "kitten.obj", "multibody_inconsistent_winding.stl"
#: the cases ``--quick`` leaves out (the two slowest fold-guard ones)
SLOW = ("fold guard: kitten bend", "fold guard: cow shrink")


def _fold(p: Problem, key: str) -> Pair:
    return _goal_pair(
        p, "fold guard", key, FOLD_CASES[key], "fold_guard", (True, False), ("on", "off")
    )


def _centroid(m: Model) -> Pair:
    return _goal_pair(
        _bend(m), "centroid", "cow-bend", FOLD_CASES["cow-bend"], "keep_centroid",
        (True, False), ("kept", "free"),
    )  # fmt: skip


def pairs(
    models: Path, quick: bool = False, tiny: bool = False
) -> list[tuple[str, Callable[[], Pair] | None, str]]:
    """The cases in table order: (name, a function that builds the pair, or None and why
    not). ``quick`` leaves out :data:`SLOW` and makes the spheres smaller; ``tiny`` (tests)
    makes the built-in shapes smaller still and cuts every pyramid at 400 triangles."""
    from isochor.core.scenario.shapes import torus_levels

    shared = Models(models, 400 if tiny else None)
    spheres = 2 if tiny else (3 if quick else 4)
    cases: list[tuple[str, str | None, Callable[[Model | None], Pair]]] = [
        ("anchor: torus", None, lambda _: anchor_pair(
            Model(tuple(torus_levels(4 if tiny else 6))), "torus-drag", "torus")),
        ("anchor: cow", COW, lambda m: anchor_pair(m, "cow-drag", "cow")),
        ("fold guard: kitten bend", KITTEN, lambda m: _fold(_bend(m), "kitten-bend")),
        ("fold guard: cow shrink", COW, lambda m: _fold(
            _problem(m, "cow", goal=Goal(target_ratio=SHRINK)), "cow-shrink")),
        ("fold guard: cow bend", COW, lambda m: _fold(_bend(m), "cow-bend")),
        ("per body: two spheres", None, lambda _: body_pair(
            _two_sphere_model(spheres), "two-spheres", "two spheres")),
        ("per body: multibody STL", MULTI, lambda m: body_pair(m, "multibody", MULTI)),
        ("centroid: cow bend", COW, _centroid),
        ("axis pins: cow squash", COW, lambda m: axis_pin_pair(m, "cow")),
    ]  # fmt: skip
    out: list[tuple[str, Callable[[], Pair] | None, str]] = []
    for name, file, make in cases:
        if quick and name in SLOW:
            continue
        if file is not None and not (models / file).is_file():
            out.append((name, None, f"{name} skipped: {models / file} not found"))
            continue
        out.append((name, lambda make=make, file=file: make(file and shared.get(file)), ""))
    return out


def run_constraints(
    models: Path,
    repeats: int,
    quick: bool = False,
    tiny: bool = False,
    log: Callable[[str], None] = print,
) -> tuple[list[ConstraintRow], list[str]]:
    """Every case of the section: the rows, and a note for every case skipped."""
    rows, notes = [], []
    for _, make, why in pairs(models, quick, tiny):
        if make is None:
            notes.append(why)
            log("  " + why)
            continue
        row = time_pair(make(), repeats)
        rows.append(row)
        log(console_line(row))
    return rows, notes
