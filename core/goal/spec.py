"""The goal: what a solve holds besides the pinned nodes, each of its fields declared once.

:class:`Goal` declares every field with its default, the values it takes and how each public
surface spells it: the scenario file's key, the Python API's keyword (and
:class:`isochor.core.api.Session` attribute), the command-line option.
:data:`GOAL_FIELDS` reads the declarations back as :class:`GoalField` records; the scenario
document, the API, the report and the command line derive their spellings from it, so a
field is added or renamed in one place. Inside the code each field has one name, its
``Goal`` attribute (``target_ratio``, spelled ``target_volume_ratio`` in files, ``target``
in the API, ``--target`` on the command line).

Light on purpose (no numpy): the command line builds its options from it before it
imports anything heavy.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from ..errors import IsochorError
from ..validate import flag, number, word

PRESERVE = ("total", "per-body")
ANCHORS = ("far-side", "none")
SYMMETRIES = ("none", "x", "y", "z")
#: the volume ratios a lattice deformation reaches without folding the model: measured on
#: the shared models (docs/CONSTRAINTS.md), beyond these the solve folds or fails
RATIO_RANGE = (0.05, 20.0)


def _declare(
    default: Any,
    *,
    help: str,
    version: int = 1,
    choices: tuple[str, ...] = (),
    key: str | None = None,
    keyword: str | None = None,
    option: str | None = None,
    metavar: str | None = None,
) -> Any:
    """A field of :class:`Goal` with everything the public surfaces need to know of it
    (read back as a :class:`GoalField`); the spellings default to the field's own name."""
    spelling = {"help": help, "version": version, "choices": choices, "key": key}
    spelling.update(keyword=keyword, option=option, metavar=metavar)
    return field(default=default, metadata={"goal": spelling})


@dataclass(frozen=True)
class Goal:
    """What the solve must hold. Each field is declared here once: its default, the values
    it takes, and how the public surfaces spell it (:data:`GOAL_FIELDS`): the scenario
    file's key, the Python API's keyword and attribute, the command-line option.

    Attributes
    ----------
    target_ratio : final volume over the rest volume (of every body with ``per-body``);
        ``target_volume_ratio`` in a scenario file, ``target`` in the API, ``--target``
    preserve : ``"total"`` (the paper: one volume) or ``"per-body"``
    keep_centroid : also keep the solid's centre of mass where it was
    anchor : ``"far-side"``: one lattice face away from the edit is held too (the face a
        push goes towards, else the farthest; :mod:`isochor.core.goal.anchor`), unless the
        user fixed the far side; ``"none"``: the paper's behaviour
    fold_guard : penalise a nearly inverted deformation (det J near zero) so that the solver
        does not meet the volume by turning part of the model inside out
    symmetry : ``"x"``, ``"y"`` or ``"z"``: the edit and the result are mirror images across
        that mid-plane of the lattice (:mod:`isochor.core.goal.symmetry`); ``"none"``
    """

    target_ratio: float = _declare(
        1.0,
        key="target_volume_ratio",
        keyword="target",
        option="--target",
        metavar="RATIO",
        help="the volume to reach, / the model's",
    )
    preserve: str = _declare(
        "total",
        version=2,
        choices=PRESERVE,
        help="one total volume, or each closed body's own",
    )
    keep_centroid: bool = _declare(
        False, version=2, help="keep the solid's centre of mass where it was"
    )
    anchor: str = _declare(
        "far-side",
        version=2,
        choices=ANCHORS,
        help="far-side: hold the lattice face the edit pushes towards (or the farthest) "
        "unless you fixed that side; none: nothing added (the paper)",
    )
    fold_guard: bool = _declare(
        True, version=2, help="penalise folding the model inside out (on by default)"
    )
    symmetry: str = _declare(
        "none",
        version=3,
        choices=SYMMETRIES,
        help="keep the edit and the result mirror images across that mid-plane of the lattice",
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "target_ratio", check_ratio(self.target_ratio))
        for f in GOAL_FIELDS:
            if f.choices and getattr(self, f.name) not in f.choices:
                raise IsochorError(f"{f.name}: must be one of {', '.join(f.choices)}")

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Goal:
        """The goal of a scenario document (a missing key: the default), each value
        checked with a one-line error naming its key."""
        return cls(**{f.name: f.read(doc) for f in GOAL_FIELDS})

    def to_json(self, versions: Collection[int] | None = None) -> dict[str, Any]:
        """The fields by their scenario keys (those added in ``versions``; all by
        default), in declaration order."""
        return {
            f.key: getattr(self, f.name)
            for f in GOAL_FIELDS
            if versions is None or f.version in versions
        }

    @property
    def version(self) -> int:
        """The oldest scenario version that holds this goal: the newest version among the
        fields that differ from their defaults (1 when none does)."""
        return max(
            (f.version for f in GOAL_FIELDS if getattr(self, f.name) != f.default), default=1
        )

    def with_(self, **changes: Any) -> Goal:
        """This goal with some fields (by their names) changed, checked."""
        return replace(self, **changes)


@dataclass(frozen=True)
class GoalField:
    """One field of :class:`Goal` as the public surfaces see it.

    Attributes
    ----------
    name : the field's name in the code (``target_ratio``)
    default : its value when nothing says otherwise
    kind : ``float``, ``str`` (one of ``choices``) or ``bool``
    choices : the words a ``str`` field takes
    key : the scenario file's key (and the report's): ``target_volume_ratio``
    keyword : the Python API's keyword and :class:`isochor.core.api.Session` attribute:
        ``target``
    option : the command-line option: ``--target`` (``--no-...`` too for a ``bool``)
    version : the scenario version that added the key
    help : what it does, in a few words (the option's help)
    metavar : the option's value in the usage text, if not its choices
    """

    name: str
    default: Any
    kind: type
    choices: tuple[str, ...]
    key: str
    keyword: str
    option: str
    version: int
    help: str
    metavar: str | None

    @classmethod
    def of(cls, declared) -> GoalField:
        s = declared.metadata["goal"]
        name, default = declared.name, declared.default
        option = s["option"] or "--" + name.replace("_", "-")
        return cls(
            name,
            default,
            type(default),
            s["choices"],
            s["key"] or name,
            s["keyword"] or name,
            option,
            s["version"],
            s["help"],
            s["metavar"],
        )

    def check(self, value: Any, where: str) -> Any:
        """``value`` if the field takes it, else a one-line error naming ``where`` (the
        spelling the user wrote: a key, a keyword, an option)."""
        if self.kind is float:
            return check_ratio(value, where)
        if self.choices:
            return word(value, where, self.choices)
        return flag(value, where)

    def read(self, doc: Mapping[str, Any]) -> Any:
        """The field's value in a scenario document, checked; the default when absent."""
        value = doc.get(self.key, self.default)
        if self.kind is float:
            value = number(value, self.key)
        return self.check(value, self.key)


#: the fields of :class:`Goal`, in declaration order: the one table every spelling of the
#: goal (scenario keys, API keywords, command-line options, the report) is derived from
GOAL_FIELDS: tuple[GoalField, ...] = tuple(GoalField.of(f) for f in fields(Goal))


def goal_field(name: str) -> GoalField:
    """The :class:`GoalField` called ``name`` (its name in the code)."""
    return next(f for f in GOAL_FIELDS if f.name == name)


def check_ratio(ratio: float, where: str = "target volume ratio") -> float:
    """``ratio`` if the method can reach it, else an error that says what it can reach."""
    lo, hi = RATIO_RANGE
    try:
        value = float(ratio)
    except (TypeError, ValueError):
        value = float("nan")
    if isinstance(ratio, bool) or not lo <= value <= hi:
        raise IsochorError(
            f"{where} {ratio!r} is outside {lo:g}..{hi:g}: a lattice deformation cannot "
            "squash or inflate a model further without turning it inside out"
        )
    return value
