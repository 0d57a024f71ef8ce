"""How the command line opens a scenario: its session, with the compiled kernels where they
pay in a one-shot command."""

from __future__ import annotations

import contextlib
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ...core.api import Session
    from ...core.scenario.document import Scenario


#: glibc's malloc for a one-shot command: blocks under this size come from the heap, and
#: freed ones stay for the next (its default starts at 128 kB and grows only as blocks
#: are freed, so a first solve maps and unmaps, and faults in, the same fresh pages step
#: after step); ...
MMAP_THRESHOLD = 4 << 20
#: ... and this much free heap is kept rather than given back at once
TRIM_THRESHOLD = 16 << 20


def one_shot() -> None:
    """A one-shot command decides itself whether to load the compiled kernels
    (:func:`open_session`): evaluations do not start them on their own. Its heap keeps
    the blocks a solve frees for the next step (:func:`steady_heap`)."""
    from ...core import kernels

    kernels.set_autostart(False)
    steady_heap()


def steady_heap() -> bool:
    """Set glibc's malloc thresholds (:data:`MMAP_THRESHOLD`, :data:`TRIM_THRESHOLD`) for
    this process; whether they were set (not on another C library). Measured (the
    benchmark's first-solve rows, interleaved): the cold torus examples' first solves
    about 4 % shorter with about 40 % fewer page faults, and the 1.38M command's peak
    612 -> 557 MB (its pyramid's child keeps less free heap)."""
    import ctypes

    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    return bool(mallopt(m_mmap_threshold, MMAP_THRESHOLD)) and bool(
        mallopt(m_trim_threshold, TRIM_THRESHOLD)
    )


def open_session(scenario: Scenario, progress=None, force: bool = False) -> Session:
    """The scenario's session, with the compiled kernels where they pay: a big model file
    starts them once its level pyramid is made (they load while the problem is built) and
    the solve waits for them; a small model never loads them, since numba would load
    beside the solve on the same cores and slow it down
    (:func:`isochor.core.kernels.worth`; the benchmark's cold command rows measure both).

    Not before the pyramid: it is made in a forked child where the process runs one
    thread (:func:`isochor.core.scenario.problem.pyramid_of`), so that fast-simplification's
    memory goes when the child ends, and numba's 110 MB would add to the child's peak.

    ``progress``: ``callable(stage, fraction)`` while the model loads (see
    :class:`isochor.core.api.Session`); ``force``: the session's (solve even when the
    estimate says it is too slow)."""
    from ...core import kernels
    from ...core.api import Session

    one_shot()
    big = False
    if "path" in scenario.model:
        with contextlib.suppress(OSError):
            big = scenario.model_path().stat().st_size >= kernels.WORTH_BYTES

    def told(stage: str, fraction: float) -> None:
        if big and stage == "load" and fraction >= 1.0:
            # the pyramid is made: the problem is built on the path the solve takes (the
            # two paths round differently; built before numba is ready, the level volumes
            # would differ in their last bits from run to run)
            kernels.ready()
        if progress is not None:
            progress(stage, fraction)

    told_or_none = told if progress or big else None
    session = Session(scenario, progress=told_or_none, force=force)
    if kernels.worth(session.problem.surface.full.n_faces):
        kernels.ready()
    return session
