"""Undo commands: one per completed edit (a drag, a pin change, a typed position, a lattice
rebuild, a target change), never one per solver iteration.

Every command swaps whole states: it holds the :class:`~app.document.StateCell` that was
current before the edit and the one the edit made. A solve that ends updates its cell in
place, so redo and undo land on solved states without solving again; a cell whose solve was
interrupted is solved again when it becomes current.
"""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtGui import QUndoCommand

from app.document import StateCell


class StateCommand(QUndoCommand):
    """Switch between two state cells.

    ``restore(cell)`` is the window's method that makes a cell current (stops the running
    solve, redraws, and solves the cell again if it was never solved). The edit is already
    applied when the command is pushed, so the first ``redo`` (which ``QUndoStack.push``
    calls) does nothing.
    """

    def __init__(self, text: str, before: StateCell, after: StateCell,
                 restore: Callable[[StateCell], None]) -> None:
        super().__init__(text)
        self.before = before
        self.after = after
        self._restore = restore
        self._pushed = False

    def redo(self) -> None:
        if not self._pushed:
            self._pushed = True
            return
        self._restore(self.after)

    def undo(self) -> None:
        self._restore(self.before)
