"""What a mouse press in the 3D view started, as small typed records (no Qt widgets).

A press becomes one of :class:`NodePress` (a click on a node, a drag once the mouse travels),
:class:`HandlePress` (on a handle's marker), :class:`ModelPress` (on the model, with the
Handle tool or Ctrl: a new handle), :class:`BoxPress` (a rubber band), :class:`CameraPress`,
:class:`ContextPress` or :class:`IgnorePress`; a drag in progress (of nodes or of a
handle's target) is a :class:`NodeDrag`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from PySide6.QtCore import QPointF


@dataclass
class NodePress:
    """A press on a selected node: a click, or a drag once the mouse travels."""

    row: int
    pos: QPointF


@dataclass
class HandlePress:
    """A press on a handle's marker: a click selects it, a drag moves its target."""

    index: int
    pos: QPointF


@dataclass
class ModelPress:
    """A press on the model that places a handle: a click places it, a drag places it and
    moves its target at once. ``face`` and ``weights`` say where on the full mesh."""

    pos: QPointF
    face: int
    weights: np.ndarray
    point: np.ndarray  #: the world point as drawn


@dataclass
class BoxPress:
    pos: QPointF
    add: bool  #: Shift: add to the selection


@dataclass
class CameraPress:
    pos: QPointF


@dataclass
class ContextPress:
    pos: QPointF


class IgnorePress:
    """The rest of this press does nothing (Shift-click toggled a node, Esc cancelled)."""


@dataclass
class NodeDrag:
    """A running node drag: where it started and what constrains it."""

    press: QPointF
    anchor: np.ndarray  #: world position of the grabbed node at the start
    depth: float  #: its normalised device depth
    pos: QPointF  #: where the mouse is now
    axis: str | None = None
    plane: bool = False  #: True: move in the plane across ``axis``
    delta: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def lock_text(self) -> str:
        if self.axis is None:
            return ""
        return f"plane across {self.axis.upper()}" if self.plane else f"{self.axis.upper()} axis"


#: what a mouse press in the view started
Press = NodePress | HandlePress | ModelPress | BoxPress | CameraPress | ContextPress | IgnorePress
