"""The grab, rotate and scale gestures on the node selection, Blender-like (Qt-free).

A :class:`Transform` is one modal gesture: its mode (``"grab"``, ``"rotate"``, ``"scale"``),
the selection's centre, an optional world-axis lock (``X``/``Y``/``Z``: along that axis;
``Shift`` + the key: the plane across it), the value the mouse gives and the text the user
types, which overrides the mouse (``S Z 0.5 Enter`` scales by 0.5 along z about the centre,
``R X 90 Enter`` rotates 90 degrees about the x axis through it, ``G Y 0.2 Enter`` moves by
0.2 along y). It is an affine map of world points, :meth:`Transform.matrix` (4, 4); the
view (:mod:`isochor.app.view.transformtool`) turns mouse positions into :attr:`Transform.mouse` and
the drag session applies the map to the rows it moves.

What a typed number means:

- grab: the distance along the locked axis (unlocked: along x; a plane lock: along the
  plane's first axis);
- rotate: degrees about the locked axis (unlocked: about the line of sight, counter-clockwise
  as seen), right-handed about the world axis;
- scale: the factor, uniform when unlocked, along the locked axis, or across the plane.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

AXES = "xyz"
MODES = ("grab", "rotate", "scale")
#: the words of each mode in the status line and the undo step
VERBS = {"grab": "Move", "rotate": "Rotate", "scale": "Scale"}
HINT = "type a value, X/Y/Z lock, Enter confirms, Esc cancels"
#: the characters a typed value is made of
TYPED = "0123456789."


def unit(axis: str) -> np.ndarray:
    """(3,) the world axis ``"x"``, ``"y"`` or ``"z"``."""
    v = np.zeros(3)
    v[AXES.index(axis)] = 1.0
    return v


def rotation(axis, angle: float) -> np.ndarray:
    """(3, 3) right-handed rotation by ``angle`` radians about the unit vector ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def about(linear: np.ndarray, centre, shift=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(4, 4) ``x -> centre + linear (x - centre) + shift``."""
    c = np.asarray(centre, dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] = linear
    m[:3, 3] = c - linear @ c + np.asarray(shift, dtype=np.float64)
    return m


def apply(matrix: np.ndarray, points) -> np.ndarray:
    """(p, 3) ``points`` mapped by the (4, 4) affine ``matrix``."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    m = np.asarray(matrix, dtype=np.float64)
    return p @ m[:3, :3].T + m[:3, 3]


def _num(v: float) -> str:
    """A short number for the status line: ``0.5``, ``-12.3``, ``0.00123``."""
    v = float(v)
    if v == 0:
        return "0"
    return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.3e}"


@dataclass
class Transform:
    """One grab, rotate or scale gesture (see the module notes).

    ``mouse`` is what the mouse says: a (3,) translation (grab), an angle in radians about
    :meth:`rotation_axis` (rotate) or a factor (scale). ``view`` is the unit vector from the
    centre towards the viewer: the axis of an unlocked rotation.
    """

    mode: str
    centre: np.ndarray
    view: np.ndarray = field(default_factory=lambda: unit("z"))
    axis: str | None = None
    plane: bool = False
    typed: str = ""
    mouse: object = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown transform {self.mode!r}")
        self.centre = np.array(self.centre, dtype=np.float64).reshape(3)
        v = np.array(self.view, dtype=np.float64).reshape(3)
        self.view = v / np.linalg.norm(v)
        if self.mouse is None:
            self.mouse = self.identity()

    def follow(self, value) -> None:
        """What the mouse says now (the mode's kind of value, see :attr:`mouse`)."""
        self.mouse = value

    def identity(self):
        """The mouse value that changes nothing."""
        return {"grab": np.zeros(3), "rotate": 0.0, "scale": 1.0}[self.mode]

    # -- what the keys do ------------------------------------------------------------------
    def set_mode(self, mode: str) -> None:
        """Switch to another mode (G, R or S again during a gesture): no lock, no value."""
        if mode not in MODES:
            raise ValueError(f"unknown transform {mode!r}")
        self.mode, self.axis, self.plane, self.typed = mode, None, False, ""
        self.mouse = self.identity()

    def lock(self, axis: str | None, plane: bool = False) -> None:
        """Lock to ``axis`` (``plane``: the plane across it; a rotation turns about the axis
        either way); the same lock again unlocks."""
        if axis is not None and axis not in AXES:
            raise ValueError(f"unknown axis {axis!r}")
        plane = bool(plane and axis is not None and self.mode != "rotate")  # a turn has an axis
        if self.axis == axis and self.plane == plane:
            axis, plane = None, False
        self.axis, self.plane = axis, plane

    def type_key(self, key: str) -> bool:
        """A typed character: a digit, ``.``, ``-`` (flips the sign) or ``"\\b"`` (erases
        the last one). Returns True when the key was one of them."""
        if key == "\b":
            self.typed = self.typed[:-1]
        elif key == "-":
            self.typed = self.typed[1:] if self.typed.startswith("-") else "-" + self.typed
        elif len(key) == 1 and key in TYPED:
            if key == "." and "." in self.typed:
                return True
            self.typed += key
        else:
            return False
        return True

    @property
    def typing(self) -> bool:
        """A typed value overrides the mouse."""
        return self.typed not in ("", "-")

    def typed_value(self) -> float | None:
        """The typed number (``"."`` and ``"-."`` count as 0), or None when nothing is typed."""
        if not self.typing:
            return None
        digits = self.typed.lstrip("-")
        value = float(digits) if digits not in ("", ".") else 0.0
        return -value if self.typed.startswith("-") else value

    # -- the map -----------------------------------------------------------------------------
    def rotation_axis(self) -> np.ndarray:
        """(3,) the unit axis a rotation turns about: the locked axis, or the line of sight."""
        return unit(self.axis) if self.axis is not None else self.view

    def _typed_direction(self) -> np.ndarray:
        if self.axis is None:
            return unit("x")
        if self.plane:
            return unit(next(a for a in AXES if a != self.axis))
        return unit(self.axis)

    def _scaled_axes(self) -> np.ndarray:
        """(3,) bool: the world axes a scale changes."""
        if self.axis is None:
            return np.ones(3, bool)
        on = np.array([a == self.axis for a in AXES])
        return ~on if self.plane else on

    def value(self):
        """The gesture's value now: typed, else the mouse's."""
        typed = self.typed_value()
        if typed is None:
            return self.mouse
        if self.mode == "grab":
            return typed * self._typed_direction()
        if self.mode == "rotate":
            return np.radians(typed)
        return typed

    def matrix(self) -> np.ndarray:
        """(4, 4) the affine map of world points the gesture makes now."""
        v = self.value()
        if self.mode == "grab":
            shift = np.asarray(v, dtype=np.float64)
            if self.axis is not None and not self.typing:
                a = unit(self.axis)
                shift = shift - (shift @ a) * a if self.plane else (shift @ a) * a
            return about(np.eye(3), self.centre, shift)
        if self.mode == "rotate":
            return about(rotation(self.rotation_axis(), float(v)), self.centre)
        factors = np.where(self._scaled_axes(), float(v), 1.0)
        return about(np.diag(factors), self.centre)

    def guide_axis(self) -> str | None:
        """The axis whose guide line is drawn (an axis lock; none for a plane)."""
        return None if self.plane else self.axis

    # -- words -------------------------------------------------------------------------------
    def where(self) -> str:
        if self.axis is None:
            return {"grab": "", "rotate": " about the line of sight", "scale": ""}[self.mode]
        if self.plane:
            return f" across {self.axis}"
        return {"grab": " along ", "rotate": " about ", "scale": " along "}[self.mode] + self.axis

    def amount(self) -> str:
        """The value as the status line shows it (what is typed, as typed)."""
        if self.typing:
            text = self.typed
            if self.mode == "rotate":
                text += "°"
            if self.mode == "grab" and (self.axis is None or self.plane):
                text += f" along {'xyz'[int(np.argmax(self._typed_direction()))]}"
            return text
        v = self.value()
        if self.mode == "rotate":
            return _num(np.degrees(float(v))) + "°"
        if self.mode == "scale":
            return _num(v)
        shift = self.matrix()[:3, 3]
        if self.axis is not None and not self.plane:
            return _num(shift[AXES.index(self.axis)])
        return "by (" + ", ".join(_num(s) for s in shift) + ")"

    def text(self) -> str:
        """The status line: ``"Scale 0.5 along z — type a value, X/Y/Z lock, ..."``."""
        where = "" if self.typing and self.mode == "grab" and self.axis is None else self.where()
        if self.typing and self.mode == "grab" and self.plane:
            where = ""
        return f"{VERBS[self.mode]} {self.amount()}{where} — {HINT}"
