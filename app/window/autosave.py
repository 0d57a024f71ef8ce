"""Autosave and recovery in the window: a part of the main window (``window.autosave``).

While the document has unsaved changes, each edit (undo and redo too) restarts a short
timer; when it fires, the recovery file is written (:mod:`isochor.app.editor.recovery`). A
save, a newly opened document or a clean quit removes it. At start, :meth:`AutoSave.offer`
asks whether to recover what a crashed or killed editor left. GUI thread only.
"""

from __future__ import annotations

from PySide6.QtCore import QObject, QTimer
from PySide6.QtWidgets import QMessageBox

from ...core.errors import IsochorError
from ...core.scenario.problem import build, scenario_model
from ..editor import recovery
from ..editor.document import Document

#: the recovery file is written this long after the last edit (ms)
DEBOUNCE_MS = 1000
#: ... and at least this often while changes are unsaved (ms)
PERIOD_MS = 30_000


class AutoSave(QObject):
    """The recovery file of one window.

    Attributes
    ----------
    file : where this window's recovery file goes
    written : the file holds the current state (nothing to write until the next edit)
    """

    def __init__(self, window) -> None:
        super().__init__(window)
        self.win = window
        self.file = recovery.own_file()
        self.written = False
        self.timer = QTimer(self)
        self.timer.setSingleShot(True)
        self.timer.setInterval(DEBOUNCE_MS)
        self.timer.timeout.connect(self.write_now)
        self.period = QTimer(self)
        self.period.setInterval(PERIOD_MS)
        self.period.timeout.connect(self._tick)
        self.period.start()
        stack = window.session.undo_stack
        stack.indexChanged.connect(self.changed)
        stack.cleanChanged.connect(self.changed)
        window.session.documentLoaded.connect(self.changed)

    def changed(self, *_args) -> None:
        """The document changed (an edit, undo, a save, another document)."""
        if self.win.closed:
            return
        if self.win.session.undo_stack.isClean():
            self.timer.stop()
            self.discard()
            return
        self.written = False
        self.timer.start()

    def _tick(self) -> None:
        if not self.written and not self.win.session.undo_stack.isClean():
            self.write_now()

    def write_now(self) -> None:
        """Write the recovery file now (nothing when the changes are saved)."""
        if self.win.closed or self.win.session.undo_stack.isClean():
            return
        doc = self.win.doc
        try:
            recovery.write(doc.scenario(), title=doc.title, path=doc.path, file=self.file)
        except (OSError, IsochorError) as exc:  # a full disk must not stop the editing
            self.win.statusBar().showMessage(f"Could not write the recovery file: {exc}", 8000)
            return
        self.written = True

    def discard(self) -> None:
        """Remove this window's recovery file (saved, or a clean quit)."""
        self.timer.stop()
        self.written = False
        recovery.remove(self.file)

    def stop(self) -> None:
        self.timer.stop()
        self.period.stop()

    # -- at start ------------------------------------------------------------------------------
    def offer(self) -> bool:
        """Offer to recover what an editor that did not quit cleanly left, newest first;
        True when a document was recovered."""
        for file in recovery.left_behind():
            try:
                found = recovery.read(file)
            except IsochorError as exc:
                self.win.statusBar().showMessage(str(exc), 8000)
                recovery.remove(file)
                continue
            answer = self.ask(found)
            if answer == "later":
                return False
            if answer == "recover" and self.recover(found):
                recovery.remove(file)
                return True
            recovery.remove(file)
        return False

    def ask(self, found: recovery.Recovered) -> str:
        """The dialog: ``"recover"``, ``"discard"`` or ``"later"``."""
        box = QMessageBox(self.win)
        box.setObjectName("recoveryDialog")
        box.setIcon(QMessageBox.Icon.Question)
        box.setWindowTitle("Recover unsaved work")
        box.setText(
            f"Isochor did not quit cleanly: {found.title} had unsaved changes "
            f"(last kept {found.when()})."
        )
        box.setInformativeText("Recover them? Discard deletes them for good.")
        recover = box.addButton("Recover", QMessageBox.ButtonRole.AcceptRole)
        discard = box.addButton("Discard", QMessageBox.ButtonRole.DestructiveRole)
        box.addButton("Later", QMessageBox.ButtonRole.RejectRole)
        box.setDefaultButton(recover)
        box.exec()
        clicked = box.clickedButton()
        return "recover" if clicked is recover else "discard" if clicked is discard else "later"

    def recover(self, found: recovery.Recovered) -> bool:
        """Open the recovered edit as the document, marked as changed (Save writes it)."""
        try:
            scenario = found.scenario
            doc = Document(
                build(scenario, model=scenario_model(scenario)),
                path=found.path,
                title=found.title,
            )
        except (OSError, IsochorError) as exc:
            self.win.error("Cannot recover the work", str(exc))
            return False
        self.win.session.load(doc)
        self.win.session.undo_stack.resetClean()  # not saved: the title shows it
        self.win.update_title()
        self.win.statusBar().showMessage(f"Recovered {found.title} (unsaved).", 8000)
        return True
