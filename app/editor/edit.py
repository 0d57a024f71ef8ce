"""What every edit rule takes and returns (Qt-free): the :class:`EditBase` an edit starts
from and the :class:`Edit` it makes.

A rule is a module-level function of an edit base and the rule's own arguments, e.g.
``goalrules.edit_anchor(doc.base(), on)``; it returns the :class:`Edit` to commit (a new
state, unsolved, with the words of its undo step), or None when nothing would change. The
base is a snapshot: a rule reads it and never changes the document, so the rules are plain
functions, tested without a document.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .problems import ProblemCache
from .state import DocState


@dataclass(frozen=True)
class Edit:
    """A new state and the words of its undo step."""

    state: DocState
    text: str


@dataclass(frozen=True, eq=False)
class EditBase:
    """What an edit starts from: the document's state, the nodes on screen and the
    selection, as they are when the base is taken (``Document.base()``).

    Attributes
    ----------
    state : the current :class:`~isochor.app.editor.state.DocState`
    nodes : (n, 3) read-only, the nodes on screen: the newest intermediate nodes of a
        running solve, or with "preserve volume" off the plain FFD (free nodes at rest)
    rows : (k,) int read-only, the selected node rows, sorted
    handle : the selected handle's index, if any
    problems : the problems built for the document's model, one per lattice (a lattice
        rebuild reuses them, see :mod:`isochor.app.editor.latticerules`)
    """

    state: DocState
    nodes: np.ndarray
    rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    handle: int | None = None
    problems: ProblemCache | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "nodes", _read_only(self.nodes, np.float64))
        object.__setattr__(self, "rows", _read_only(self.rows, int))

    def start(self) -> np.ndarray:
        """(n, 3) a fresh, writable copy of :attr:`nodes`: where an edit's nodes start."""
        return np.array(self.nodes, dtype=np.float64)


def _read_only(a, dtype) -> np.ndarray:
    out = np.array(a, dtype=dtype)
    out.flags.writeable = False
    return out
