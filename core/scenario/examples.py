"""The paper's examples (Sec 5) as built-in scenarios.

- torus-compression (Plate 1, Table 2): 3x3x3 lattice; the top and bottom 3x3 layers moved
  toward the centre by a quarter of the lattice height each and fixed; the middle layer free.
- torus-stretch (Plate 2): 5x2x2 lattice along x; the two outer layers at each end
  (2x2x2 nodes per end) pulled apart and fixed; the 2x2 centre layer free.
- club-compression (Plate 3): the rounded club in a 5x2x2 lattice; its left end pushed in.
  Nothing holds its right end, which swells, as in the plate: the scenario asks for the
  paper's behaviour (``"anchor": "none"``), where the editor's default would hold it.
- club-bend (Plate 7): the club bent along an arc of 160 degrees, almost a U; all layers
  but the middle one are moved onto the arc and fixed, the middle 2x2 layer is free.
- cup-squeeze (Sec 1's container "whose capacity is given a priori"): the open cup in a
  3x3x3 lattice, its waist pinched along x by a fifth of its width on each side; the rest
  is free, and the capacity (the volume under the capped rim) is kept.

Each is an ordinary :class:`~core.scenario.document.Scenario`, so the window, the command line, the
benchmark and the tests all run exactly the same document.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from ..defaults import PADDING, TOL_NODES, TOL_VOLUME
from ..errors import IsochorError
from ..lattice import Lattice
from .document import Scenario
from .shapes import builtin_levels

EXAMPLES: dict[str, str] = {
    "torus-compression": "Torus squashed to half its height in a 3x3x3 lattice (Plate 1)",
    "torus-stretch": "Torus pulled at both ends of a 5x2x2 lattice (Plate 2)",
    "club-compression": "Rounded club pushed in at its thin end, 5x2x2 lattice (Plate 3)",
    "club-bend": "Rounded club bent along a 160-degree arc, 5x2x2 lattice (Plate 7)",
    "cup-squeeze": "Open cup pinched at its waist, its capacity kept, 3x3x3 lattice",
}


@cache
def _rest_lattice(shape_name: str, nodes: tuple[int, int, int]) -> Lattice:
    return Lattice.around(builtin_levels(shape_name)[-1].vertices, nodes, PADDING)


def _moves(lattice: Lattice, select, offset) -> list[dict]:
    """``by`` moves for every node (i, j, k) with ``select(i, j, k)``."""
    rest = lattice.rest_nodes
    out = []
    for r in range(lattice.n_nodes):
        ijk = lattice.ijk(r)
        if select(*ijk):
            by = np.round(offset(ijk, rest[r]), 12)
            out.append({"node": list(ijk), "by": [float(a) for a in by]})
    return out


def example_scenario(name: str) -> Scenario:
    """The built-in scenario ``name`` (see :data:`EXAMPLES`)."""
    if name not in EXAMPLES:
        raise IsochorError(f"Unknown example {name!r}; the examples are {', '.join(EXAMPLES)}.")
    goal: dict = {}
    if name == "torus-compression":
        lat = _rest_lattice("torus", (3, 3, 3))
        q = lat.axes[2, 2] / 4
        moves = _moves(
            lat, lambda i, j, k: k != 1, lambda ijk, p: (0.0, 0.0, q if ijk[2] == 0 else -q)
        )
        model = {"builtin": "torus"}
    elif name == "torus-stretch":
        lat = _rest_lattice("torus", (5, 2, 2))
        d = 0.2 * lat.axes[0, 0]
        moves = _moves(
            lat, lambda i, j, k: i != 2, lambda ijk, p: (-d if ijk[0] < 2 else d, 0.0, 0.0)
        )
        model = {"builtin": "torus"}
    elif name == "club-compression":
        lat = _rest_lattice("club", (5, 2, 2))
        d = 0.25 * lat.axes[0, 0] / 4  # the first cell shrinks to a quarter... of its length
        moves = _moves(
            lat, lambda i, j, k: i <= 1, lambda ijk, p: (3 * d if ijk[0] == 0 else d, 0.0, 0.0)
        )
        model = {"builtin": "club"}
        goal = {"anchor": "none"}  # the plate: the free right end swells
    elif name == "cup-squeeze":
        lat = _rest_lattice("cup", (3, 3, 3))
        d = 0.2 * lat.axes[0, 0] / 2
        moves = _moves(
            lat, lambda i, j, k: k == 1 and i != 1, lambda ijk, p: (d if ijk[0] == 0 else -d, 0, 0)
        )
        model = {"builtin": "cup"}
    else:  # club-bend
        lat = _rest_lattice("club", (5, 2, 2))
        length = lat.axes[0, 0]
        center = lat.origin + 0.5 * lat.axes.sum(axis=0)
        radius = length / np.radians(160.0)  # the centre line keeps its length

        def bend(ijk, p):
            x, z = p[0] - center[0], p[2] - center[2]
            theta = x / radius
            bent = (
                np.array(
                    [
                        (radius - z) * np.sin(theta),
                        p[1] - center[1],
                        radius - (radius - z) * np.cos(theta),
                    ]
                )
                + center
            )
            return bent - p

        moves = _moves(lat, lambda i, j, k: i != 2, bend)
        model = {"builtin": "club"}
    doc = {
        "format": "isochor-scenario",
        "version": 2 if goal else 1,
        "model": model,
        "lattice": {"nodes": list(lat.shape), "padding": PADDING},
        "moves": moves,
        "pins": [],
        "target_volume_ratio": 1.0,
        "tolerance": {"volume": TOL_VOLUME, "nodes": TOL_NODES},
        **goal,
    }
    return Scenario.from_dict(doc)
