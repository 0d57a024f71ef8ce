"""Checks of values that come from the user's files, each failing with one sentence that
names the field (``moves[2].by: must be a finite number, got 'x'``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .errors import IsochorError

#: no coordinate (of a model's vertex, a move, a frame) may be larger than this in magnitude:
#: far beyond any real model, and far enough from overflow that volumes (cubes of lengths)
#: stay finite
MAX_COORDINATE = 1e15


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
