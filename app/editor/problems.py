"""The problems built for one document's model, one per lattice (Qt-free).

Building a :class:`~isochor.core.scenario.problem.Problem` fits a lattice around the model
and computes caches on it (bases, springs). When the user rebuilds the lattice and later
returns to a shape used before, the problem built then is reused with its caches
(:func:`isochor.app.editor.latticerules.edit_lattice`).
"""

from __future__ import annotations

from ...core.scenario.document import Scenario
from ...core.scenario.problem import Problem, build


def lattice_key(scenario: Scenario) -> tuple:
    """What tells two lattices around the same model apart: shape, basis, padding and
    frame."""
    return (
        tuple(scenario.lattice_nodes),
        tuple(scenario.lattice_basis),
        scenario.lattice_outside,
        scenario.padding,
        scenario.frame,
    )


class ProblemCache:
    """The problems built around one model, by :func:`lattice_key`."""

    def __init__(self, problem: Problem) -> None:
        self._problems: dict[tuple, Problem] = {lattice_key(problem.scenario): problem}

    def built(self, scenario: Scenario, model) -> Problem:
        """The problem of ``scenario``'s lattice around ``model``: the one built before
        for the same lattice, else a new one (kept for next time)."""
        problem = self._problems.get(lattice_key(scenario))
        if problem is None:
            problem = build(scenario, model=model)
            self._problems[lattice_key(problem.scenario)] = problem
        return problem
