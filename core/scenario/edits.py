"""One edit of the lattice as a scenario (or one of its poses) states it: moved nodes,
pinned nodes (on all or some axes) and surface handles; reading it from JSON, writing it
back, and applying it to a lattice.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import IsochorError
from ..goal.handles import Handle
from ..lattice import Lattice
from ..validate import as_list, check_keys, node_index, vec3

#: a move may take a node at most this many lattice sizes away (a bigger one is a mistake
#: of units or of typing, and its numbers would overflow long before it meant anything)
MAX_MOVE = 1000.0

Node = tuple[int, int, int]


@dataclass(frozen=True)
class Move:
    """Node (i, j, k) moved ``by`` an offset or ``to`` a position (exactly one is set)."""

    node: Node
    by: tuple[float, float, float] | None = None
    to: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Edit:
    """Moves, pins (``pins`` on all axes, ``axis_pins`` on some) and handles."""

    moves: tuple[Move, ...] = ()
    pins: tuple[Node, ...] = ()
    axis_pins: tuple[tuple[Node, str], ...] = ()
    handles: tuple[Handle, ...] = ()

    @classmethod
    def from_json(cls, doc: dict, shape: Node, version: int, where: str = "") -> Edit:
        """The ``moves``, ``pins`` and ``handles`` of ``doc``; ``where`` prefixes the field
        names in messages (``"poses[1]."``)."""
        moves: list[Move] = []
        for n, mv in enumerate(as_list(doc.get("moves", []), f"{where}moves")):
            at = f"{where}moves[{n}]"
            check_keys(mv, at, {"node", "by", "to"}, {"node"})
            if ("by" in mv) == ("to" in mv):
                raise IsochorError(f"{at}: give exactly one of 'by' or 'to'")
            node = node_index(mv["node"], f"{at}.node", shape)
            if any(m.node == node for m in moves):
                raise IsochorError(f"{at}.node: node {list(node)} is already moved")
            if "by" in mv:
                moves.append(Move(node, by=vec3(mv["by"], f"{at}.by")))
            else:
                moves.append(Move(node, to=vec3(mv["to"], f"{at}.to")))
        pins, axis_pins = _pins(as_list(doc.get("pins", []), f"{where}pins"), shape, version, where)
        moved = {m.node for m in moves}
        for node in (*pins, *(p for p, _ in axis_pins)):
            if node in moved:
                raise IsochorError(
                    f"{where}pins: node {list(node)} is also moved; a moved node already "
                    "stays where it is moved to, so give it either the move or the pin"
                )
        handles = []
        for n, hd in enumerate(as_list(doc.get("handles", []), f"{where}handles")):
            at = f"{where}handles[{n}]"
            check_keys(hd, at, {"at", "to"}, {"at", "to"})
            handles.append(Handle(vec3(hd["at"], f"{at}.at"), vec3(hd["to"], f"{at}.to")))
        return cls(tuple(moves), pins, axis_pins, tuple(handles))

    def to_json(self) -> dict[str, Any]:
        """``moves`` and ``pins`` (and ``handles`` when there are any)."""
        moves = []
        for mv in self.moves:
            d: dict[str, Any] = {"node": list(mv.node)}
            if mv.by is not None:
                d["by"] = list(mv.by)
            elif mv.to is not None:  # a move has by or to
                d["to"] = list(mv.to)
            moves.append(d)
        pins: list[Any] = [list(p) for p in self.pins]
        pins += [{"node": list(p), "axes": axes} for p, axes in self.axis_pins]
        doc: dict[str, Any] = {"moves": moves, "pins": pins}
        if self.handles:
            doc["handles"] = [{"at": list(h.at), "to": list(h.to)} for h in self.handles]
        return doc

    def apply(self, lattice: Lattice, where: str = "") -> tuple[np.ndarray, np.ndarray]:
        """The rest lattice's nodes with the moves applied, and the fixed coordinates
        (n, 3) bool; a move or handle farther than :data:`MAX_MOVE` lattice sizes is an
        error naming it."""
        nodes = lattice.rest_nodes.copy()
        fixed = np.zeros((lattice.n_nodes, 3), dtype=bool)
        for n, mv in enumerate(self.moves):
            r = lattice.index(*mv.node)
            nodes[r] = (nodes[r] + mv.by) if mv.by is not None else mv.to
            fixed[r] = True
            _near(
                f"{where}moves[{n}]: moves node {list(mv.node)}",
                nodes[r],
                lattice.rest_nodes[r],
                lattice,
            )
        for p in self.pins:
            fixed[lattice.index(*p)] = True
        for p, axes in self.axis_pins:
            fixed[lattice.index(*p), ["xyz".index(a) for a in axes]] = True
        for n, h in enumerate(self.handles):
            _near(f"{where}handles[{n}]: moves its point", h.to, h.at, lattice)
        return nodes, fixed


def _near(what: str, to, start, lattice: Lattice) -> None:
    distance = float(np.linalg.norm(np.subtract(to, start)))
    if distance > MAX_MOVE * lattice.size:
        raise IsochorError(
            f"{what} by {distance:.3g}, more than {MAX_MOVE:g} times the lattice's size "
            f"({lattice.size:.3g}); a wrong unit?"
        )


def _pins(items: list, shape: Node, version: int, where: str) -> tuple[tuple, tuple]:
    """The plain pins (all axes) and the axis pins of a ``pins`` list."""
    pins, axis_pins, seen = [], [], set()
    for n, p in enumerate(items):
        at = f"{where}pins[{n}]"
        if isinstance(p, dict):
            if version == 1:
                raise IsochorError(f'{at}: a pin with axes needs "version": 2')
            check_keys(p, at, {"node", "axes"}, {"node", "axes"})
            node = node_index(p["node"], f"{at}.node", shape)
            axes = p["axes"]
            if not isinstance(axes, str) or not axes or set(axes) - set("xyz"):
                raise IsochorError(f'{at}.axes: must be some of "xyz", like "z" or "xy"')
            axes = "".join(a for a in "xyz" if a in axes)
        else:
            node, axes = node_index(p, at, shape), "xyz"
        if node in seen:
            raise IsochorError(f"{at}: node {list(node)} is already pinned")
        seen.add(node)
        if axes == "xyz":
            pins.append(node)
        else:
            axis_pins.append((node, axes))
    return tuple(pins), tuple(axis_pins)
