"""Undo commands: one per completed edit (a drag, a pin change, a typed position, a lattice
rebuild, a target change), never one per solver step.

A command acts on the :class:`~isochor.app.document.Document`: it swaps the document's
current state cell between the one before the edit and the one the edit made. The session
controller reacts to the document's ``"state"`` event (stops the running solve, redraws,
solves the new state if it was never solved), so undo, redo and the edit itself take the same
path. A solve that ends puts its result into its cell (``Document.record_result``), so undo
and redo land on solved states without solving again.
"""

from __future__ import annotations

from PySide6.QtGui import QUndoCommand

from .document import Document, StateCell


class EditCommand(QUndoCommand):
    """Switch the document between two state cells; ``push`` applies the edit."""

    def __init__(self, document: Document, text: str, before: StateCell, after: StateCell) -> None:
        super().__init__(text)
        self.document = document
        self.before = before
        self.after = after

    def redo(self) -> None:
        self.document.set_cell(self.after)

    def undo(self) -> None:
        self.document.set_cell(self.before)
