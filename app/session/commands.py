"""Undo commands: one per completed edit (a drag, a pin change, a typed position, a lattice
rebuild, a target change), never one per solver step.

A command acts on the :class:`~isochor.app.editor.document.Document`: it swaps the document's
current state cell between the one before the edit and the one the edit made. The session
controller reacts to the document's ``"state"`` event (stops the running solve, redraws,
solves the new state if it was never solved), so undo, redo and the edit itself take the same
path. A solve that ends puts its result into its cell (``Document.record_result``), so undo
and redo land on solved states without solving again.
"""

from __future__ import annotations

from PySide6.QtGui import QUndoCommand

from ..editor.document import Document, StateCell
from ..editor.timeline import pose_of, same_pose


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


class GoToKeyCommand(EditCommand):
    """Loading a key's edit as the working edit ("Go to key N"). Going from key to key
    merges into one step, so scrubbing leaves one undo step that returns to the working edit
    from before (none when it ends on that very edit)."""

    ID = 1301

    def id(self) -> int:
        return self.ID

    def mergeWith(self, other) -> bool:
        if other.id() != self.ID:
            return False
        self.after = other.after
        self.setText(other.text())
        a, b = self.before.state, self.after.state
        if a.problem is b.problem and same_pose(pose_of(a, 0), pose_of(b, 0), a.lattice):
            self.setObsolete(True)  # back where it started: no step to undo
        return True
