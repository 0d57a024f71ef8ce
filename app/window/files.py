"""The window's file commands: open, open an example, save, save as, export, and the
unsaved-changes prompt. A file that cannot be read or written is shown in a dialog and the
current document is kept. Every way of opening (File > Open, a file dropped on the view,
the examples, the command line's file) comes through :meth:`FileCommands.open_path`; a big
file is read on a thread with its progress in the status bar (:mod:`isochor.app.window.loading`).
"""

from __future__ import annotations

import os
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication, QFileDialog, QMessageBox

from ...core.errors import IsochorError
from ...core.io.formats import READ_FORMATS, SCENARIO_SUFFIXES, WRITE_FORMATS
from ..editor.document import Document
from .loading import Loader, failure_message, in_background


def _patterns(suffixes) -> str:
    return " ".join(f"*{s}" for s in suffixes)


OPEN_FILTER = (
    f"Models and scenarios ({_patterns([*READ_FORMATS, *SCENARIO_SUFFIXES])});;"
    f"Models ({_patterns(READ_FORMATS)});;Scenarios ({_patterns(SCENARIO_SUFFIXES)});;"
    "All files (*)"
)
#: export filter -> suffix
EXPORT_FILTERS = {
    "Wavefront OBJ (*.obj)": ".obj",
    "Stanford PLY (*.ply)": ".ply",
    "STL (*.stl)": ".stl",
    "OFF (*.off)": ".off",
    "glTF binary (*.glb)": ".glb",
    "glTF (*.gltf)": ".gltf",
}
assert set(EXPORT_FILTERS.values()) == set(WRITE_FORMATS)


class FileCommands:
    """The file menu of one window."""

    def __init__(self, window) -> None:
        self.win = window
        self._loader: Loader | None = None

    @property
    def doc(self) -> Document:
        return self.win.session.document

    def _dialog_dir(self) -> str:
        return str(self.doc.path.parent) if self.doc.path is not None else os.getcwd()

    def confirm_discard(self) -> bool:
        """True when there are no unsaved changes or the user lets them go."""
        if self.win.session.undo_stack.isClean():
            return True
        buttons = QMessageBox.StandardButton
        answer = QMessageBox.question(
            self.win,
            "Unsaved changes",
            f"Save the changes to {self.doc.title} before closing it?",
            buttons.Save | buttons.Discard | buttons.Cancel,
            buttons.Save,
        )
        if answer == buttons.Save:
            return self.save()
        return answer == buttons.Discard

    def open_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self.win, "Open a model or a scenario", self._dialog_dir(), OPEN_FILTER
        )
        if path:
            self.open_path(path)

    def open_path(
        self, path: str | Path, *, template: bool = False, background: bool | None = None
    ) -> bool:
        """Open a model or scenario; on error show it and keep the current document.

        A big file (:func:`~isochor.app.window.loading.in_background`; ``background`` says so
        instead) is read on a thread with its progress in the status bar, and the current
        document stays until the new one is ready: then this returns True when the loading
        started. A small one opens at once: True when it opened."""
        if not self.confirm_discard():
            return False
        if self._loader is not None:
            self._loader.cancel(quiet=True)  # the newest open wins
        if background if background is not None else in_background(path):
            self.loader.start(path, template=template, mark=self._mark())
            return True
        win = self.win
        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        win.statusBar().showMessage(f"Opening {Path(path).name}…")
        QApplication.processEvents()
        try:
            doc = Document.open(path, template=template)
        except Exception as exc:
            QApplication.restoreOverrideCursor()
            return self._open_failed(failure_message(path, exc))
        QApplication.restoreOverrideCursor()
        win.statusBar().clearMessage()
        win.session.load(doc)
        return True

    @property
    def loader(self) -> Loader:
        """The background opening (its bar joins the status bar the first time)."""
        if self._loader is None:
            self._loader = Loader(self.win, self._loaded, self._open_failed)
        return self._loader

    def loading(self) -> bool:
        """A file is being opened in the background."""
        return self._loader is not None and self._loader.busy()

    def _loaded(self, doc: Document, mark, prep=None) -> None:
        """A background load is done: show ``doc`` (drawn from ``prep``, the view's arrays
        computed with it), unless the window has closed meanwhile or the user edited the
        current document and now keeps it."""
        if self.win.closed:
            return
        doc_then, cell_then, saved_then = mark
        kept = doc_then is self.doc and cell_then is self.doc.cell
        kept = kept and saved_then == self.win.session.undo_stack.cleanIndex()
        if not kept and not self.confirm_discard():  # edited (or saved) meanwhile: ask again
            self.win.statusBar().showMessage(f"{doc.title} was not opened.", 6000)
            return
        self.win.viewport.scene.offer(prep)
        self.win.session.load(doc)

    def _mark(self) -> tuple:
        """What the user agreed to let go: the document, its state, what was saved."""
        return self.doc, self.doc.cell, self.win.session.undo_stack.cleanIndex()

    def _open_failed(self, message: str) -> bool:
        self.win.statusBar().clearMessage()
        self.win.error("Cannot open the file", message)
        return False

    def open_example(self, path: Path) -> bool:
        """A shipped example: opened as a new document, so Save asks where to write."""
        return self.open_path(path, template=True)

    def save(self) -> bool:
        if self.doc.path is None:
            return self.save_as()
        return self.save_to(self.doc.path)

    def save_as(self) -> bool:
        start = str(self.doc.path) if self.doc.path else os.path.join(os.getcwd(), "scenario.json")
        path, _ = QFileDialog.getSaveFileName(
            self.win, "Save scenario", start, "Scenarios (*.json)"
        )
        if not path:
            return False
        if not path.lower().endswith(".json"):
            path += ".json"
        return self.save_to(Path(path))

    def save_to(self, path: Path) -> bool:
        try:
            self.doc.save(path)
        except (IsochorError, OSError) as exc:
            self.win.error("Cannot save the scenario", str(exc))
            return False
        self.win.session.undo_stack.setClean()
        self.win.update_title()
        self.win.statusBar().showMessage(f"Saved {path}", 4000)
        return True

    def export_dialog(self) -> None:
        base = Path(self.doc.title).stem or "deformed"
        path, chosen = QFileDialog.getSaveFileName(
            self.win,
            "Export the deformed mesh",
            os.path.join(self._dialog_dir(), f"{base}-deformed.obj"),
            ";;".join(EXPORT_FILTERS),
        )
        if path:
            if not Path(path).suffix:
                path += EXPORT_FILTERS.get(chosen, ".obj")
            self.export(path)

    def export(self, path: str | Path) -> bool:
        """Export the deformed model. While a solve runs, wait for it (a progress dialog
        with Cancel): a mesh in the middle of a solve is never written as the result. What
        is written is said: the result, or an edit not solved or not converged."""
        if self.win.is_solving() and not self.wait_for_solve():
            self.win.statusBar().showMessage(
                "Export cancelled: the solve was still running; nothing was written.", 8000
            )
            return False
        st = self.doc.state
        try:
            notes = self.doc.export(path, self.doc.view_nodes())
        except (IsochorError, OSError, ValueError) as exc:
            self.win.error("Cannot export the mesh", str(exc))
            return False
        what = [f"Exported {path}."]
        if self.doc.preserve and not st.solved:
            what.append("Not solved: the edit as it stands, its volume not kept.")
        elif self.doc.preserve and not st.converged:
            what.append("The solve did not converge: the volume is not within its tolerance.")
        self.win.statusBar().showMessage(" ".join([*what, *notes]), 8000)
        return True

    def wait_for_solve(self) -> bool:
        """Wait for the running solve to end, with a progress dialog and Cancel; True when
        it ended, False when the user cancelled (the solve goes on)."""
        from PySide6.QtCore import QEventLoop, QTimer
        from PySide6.QtWidgets import QProgressDialog

        dialog = QProgressDialog(
            "Waiting for the solve to finish before exporting…", "Cancel", 0, 0, self.win
        )
        dialog.setObjectName("exportWait")
        dialog.setWindowTitle("Export")
        dialog.setWindowModality(Qt.WindowModality.WindowModal)
        dialog.setMinimumDuration(0)
        loop = QEventLoop()
        poll = QTimer()
        poll.setInterval(30)
        poll.timeout.connect(lambda: self.win.is_solving() or loop.quit())
        cancelled = []
        dialog.canceled.connect(lambda: cancelled.append(True) or loop.quit())
        poll.start()
        dialog.show()
        loop.exec()
        poll.stop()
        ended = not cancelled
        dialog.canceled.disconnect()
        dialog.close()
        dialog.deleteLater()
        return ended
