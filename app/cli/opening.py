"""How the command line opens a scenario: its session, with the compiled kernels where they
pay in a one-shot command."""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ...core.api import Session
    from ...core.scenario.document import Scenario


def one_shot() -> None:
    """A one-shot command decides itself whether to load the compiled kernels
    (:func:`open_session`): evaluations do not start them on their own."""
    from ...core import kernels

    kernels.set_autostart(False)


def open_session(scenario: Scenario, progress=None) -> Session:
    """The scenario's session, with the compiled kernels where they pay: a big model file
    starts them before it is read (they load while it does) and the solve waits for them;
    a small model never loads them, since numba would load beside the solve on the same
    cores and slow it down (:func:`isochor.core.kernels.worth`; the benchmark's cold
    command rows measure both).

    ``progress``: ``callable(stage, fraction)`` while the model loads (see
    :class:`isochor.core.api.Session`)."""
    from ...core import kernels
    from ...core.api import Session

    one_shot()
    if "path" in scenario.model:
        with contextlib.suppress(OSError):
            if scenario.model_path().stat().st_size >= kernels.WORTH_BYTES:
                kernels.start()
    session = Session(scenario, progress=progress) if progress else Session(scenario)
    if kernels.worth(session.problem.surface.full.n_faces):
        kernels.ready()
    return session
