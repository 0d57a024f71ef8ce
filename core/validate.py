"""Checks of values that come from the user's files (scenario fields, model coordinates),
each failing with one sentence that names the field (``moves[2].by: must be a finite
number, got 'x'``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, cast

from .errors import IsochorError

#: no coordinate (of a model's vertex, a move, a frame) may be larger than this in magnitude:
#: far beyond any real model, and far enough from overflow that volumes (cubes of lengths)
#: stay finite
MAX_COORDINATE = 1e15
#: longest integer literal read (Python refuses more than 4300 digits, and no field needs 20)
MAX_DIGITS = 100


def show(obj: Any) -> str:
    """A value for a message: its JSON-like text, cut short."""
    text = repr(obj)
    return text if len(text) <= 40 else text[:37] + "..."


def number(obj: Any, where: str, bounds: tuple[float, float] | None = None) -> float:
    """``obj`` as a finite float (within ``bounds``, if given), or a one-line error naming
    the field ``where``."""
    if isinstance(obj, bool) or not isinstance(obj, (int, float)):
        raise IsochorError(f"{where}: must be a number, got {show(obj)}")
    try:
        value = float(obj)
    except OverflowError:
        value = math.inf
    if not math.isfinite(value):
        raise IsochorError(f"{where}: must be a finite number, got {show(obj)}")
    if bounds is not None and not bounds[0] <= value <= bounds[1]:
        raise IsochorError(f"{where}: must be from {bounds[0]:g} to {bounds[1]:g}, got {value:g}")
    return value


def input_file(path: Path, what: str, limit: int) -> int:
    """Check that ``path`` (a ``what``: "model", "scenario") is an existing regular file of
    at most ``limit`` bytes, before anything reads it; returns its size.

    A huge or sparse file fails here at once, instead of filling the memory."""
    if not path.exists():
        why = "a loop of symbolic links" if path.is_symlink() else f"no such {what} file"
        raise IsochorError(f"{path}: {why}")
    if not path.is_file():
        raise IsochorError(f"{path}: not a file")
    size = path.stat().st_size
    if size > limit:
        raise IsochorError(
            f"{path}: {_amount(size)} is more than Isochor reads as a {what} ({_amount(limit)})"
        )
    return size


def _amount(size: int) -> str:
    return f"{size / 2**30:.1f} GB" if size >= 2**30 else f"{size / 2**20:.1f} MB"


def check_keys(obj: Any, where: str, allowed: set[str] | None, required: set[str]) -> None:
    if not isinstance(obj, dict):
        raise IsochorError(f"{where}: must be a JSON object")
    if allowed is not None:
        unknown = sorted(set(obj) - allowed)
        if unknown:
            raise IsochorError(f"{where}: unknown key {unknown[0]!r}")
    missing = sorted(required - set(obj))
    if missing:
        raise IsochorError(f"{where}: missing key {missing[0]!r}")


def as_list(obj: Any, where: str) -> list:
    if not isinstance(obj, list):
        raise IsochorError(f"{where}: must be a list")
    return obj


def parse_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_DIGITS:
        raise IsochorError(f"a number has {len(text.lstrip('-'))} digits")
    return int(text)


def parse_constant(name: str) -> float:
    raise IsochorError(f"{name} is not a JSON number")


def vec3(obj: Any, where: str) -> tuple[float, float, float]:
    if not isinstance(obj, list) or len(obj) != 3:
        raise IsochorError(f"{where}: must be a list of three numbers")
    limit = (-MAX_COORDINATE, MAX_COORDINATE)
    return cast("tuple[float, float, float]", tuple(number(x, where, limit) for x in obj))  # len 3


def int_triple(obj: Any, where: str) -> tuple[int, int, int]:
    if (
        not isinstance(obj, list)
        or len(obj) != 3
        or not all(isinstance(x, int) and not isinstance(x, bool) for x in obj)
    ):
        raise IsochorError(f"{where}: must be a list of three whole numbers")
    return tuple(obj)


def word(obj: Any, where: str, words: tuple[str, ...]) -> str:
    if obj not in words:
        raise IsochorError(
            f"{where}: must be one of {', '.join(map(repr, words))}, got {show(obj)}"
        )
    return obj


def flag(obj: Any, where: str) -> bool:
    if not isinstance(obj, bool):
        raise IsochorError(f"{where}: must be true or false, got {show(obj)}")
    return obj


def node_index(obj: Any, where: str, shape: tuple[int, int, int]) -> tuple[int, int, int]:
    ijk = int_triple(obj, where)
    if not all(0 <= a < s for a, s in zip(ijk, shape)):
        raise IsochorError(
            f"{where}: node {list(ijk)} is outside the {shape[0]}x{shape[1]}x{shape[2]} lattice"
        )
    return ijk
