"""Helpers for the progress generators every solve is written as.

A solve yields progress records and *returns* its result (``StopIteration.value``). These
two helpers replace the hand-written ``while True: next(...)`` loops: :func:`run_to_end`
for a consumer that wants the result, :func:`relay` for a generator that passes another
generator's records on, changed.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import Any, TypeVar

R = TypeVar("R")  # record
T = TypeVar("T")  # what the generator returns
S = TypeVar("S")  # relayed record


def run_to_end(gen: Generator[R, Any, T], on_record: Callable[[R], None] | None = None) -> T:
    """Drive ``gen`` to its end and return what it returns.

    ``on_record`` is called with every record. Any exception (Ctrl-C included) closes the
    generator, so the solve stops at once, and is raised again.
    """
    try:
        while True:
            try:
                record = next(gen)
            except StopIteration as stop:
                return stop.value
            if on_record is not None:
                on_record(record)
    except BaseException:
        gen.close()
        raise


def relay(gen: Generator[R, Any, T], change: Callable[[R], S]) -> Generator[S, None, T]:
    """Yield ``change(record)`` for every record of ``gen``; return what ``gen`` returns.

    Use as ``result = yield from relay(inner, change)``.
    """
    try:
        while True:
            try:
                record = next(gen)
            except StopIteration as stop:
                return stop.value
            yield change(record)
    finally:
        gen.close()  # closing the relay closes the inner generator at once
