"""Rebuilding a big model's lattice in the background.

A new lattice around a big model needs its full level's basis (every vertex's weights for
the new nodes), the spring network, the model's bodies and the view's arrays: on the 346k
armadillo about 0.5-1.3 s, which froze the window when it ran on the GUI thread.
:class:`LatticeRebuild` runs that on a thread (it only calls the core and the numpy half of
the view, :mod:`isochor.app.view.meshprep`) and hands the finished edit and the view's
arrays to the GUI thread by a queued signal; there it is committed as one undo step as
before, and the view only makes its VTK objects. Only the GUI thread touches widgets, VTK
and pyvista.

Each rebuild has a generation id. A newer rebuild, an edit, undo or redo made meanwhile
(the state it started from is no longer the current one), or closing the window drops
what the thread delivers: a thread cannot be stopped, so it ends on its own, unheard, and
quitting never waits for it (it is a daemon thread). A model of at most
:data:`BACKGROUND_FACES` triangles is rebuilt at once on the GUI thread, as before: it takes
a few milliseconds.
"""

from __future__ import annotations

import contextlib
import threading

from PySide6.QtCore import QObject, Signal

from ...core.errors import IsochorError
from ...core.estimate import Sizes, screen
from ...core.lattice import basis_names
from ...core.localbasis import BERNSTEIN
from ..editor import latticerules
from ..view.meshprep import DisplayPrep
from .loading import Gate

#: a model with more triangles has its lattice rebuilt on a thread (the 346k armadillo:
#: 0.5-1.3 s; below this it is a fraction of a frame's worth)
BACKGROUND_FACES = 100_000


def prepare_rebuild(base, shape, basis=None, outside=None):
    """The edit that rebuilds the lattice with ``shape`` nodes (and ``basis`` and
    ``outside``: None keeps them) from ``base`` and the view's
    arrays for it: ``(edit, prep)``, or ``(None, None)`` when the lattice has that shape
    already. Qt-free: what the thread runs. Raises :class:`IsochorError` for a bad shape."""
    edit = latticerules.edit_lattice(base, shape, basis, outside)
    if edit is None:
        return None, None
    surface = edit.state.surface
    # what the session prepares for the display when the scene changes (found cached then)
    surface.level(-1)
    _ = surface.springs, surface.bodies
    return edit, DisplayPrep.of(surface, edit.state.nodes)


class LatticeRebuild(QObject):
    """The lattice rebuilds of one window.

    Parameters
    ----------
    win : the main window (its document, session, view and status bar)

    Attributes
    ----------
    threads : the rebuild threads started (the tests read which ran)

    Signals (internal: the thread's reports, queued to the GUI thread; generation first)
    ---------------------------------------------------------------------------------------
    built(int, object) : ``(edit, prep)`` is ready
    failed(int, str) : the rebuild raised; the message to show
    """

    built = Signal(int, object)
    failed = Signal(int, str)

    def __init__(self, win) -> None:
        super().__init__(win)
        self.win = win
        self.generation = 0
        self.threads: list[threading.Thread] = []
        self._running: tuple[int, object] | None = None  # (generation, the cell it left)
        self._gate = Gate()
        self.built.connect(self._on_built)
        self.failed.connect(self._on_failed)
        self.destroyed.connect(self._gate.close)

    def busy(self) -> bool:
        """A rebuild runs whose result will be committed."""
        return self._running is not None

    def start(self, shape, basis=None, outside=None) -> bool:
        """Rebuild the lattice with ``shape`` nodes (and ``basis`` and ``outside``): at
        once for a small model (True when the lattice changed), on a thread for a big one
        (True: it started)."""
        win = self.win
        if not self._affordable(shape, basis):
            return False
        self.cancel()
        base = win.doc.base()
        if win.state.surface.full.n_faces <= BACKGROUND_FACES:
            edit, prep = prepare_rebuild(base, shape, basis, outside)
            return self._commit(edit, prep)
        self.generation += 1
        gen = self.generation
        self._running = (gen, win.doc.cell)
        thread = threading.Thread(
            target=self._run,
            args=(gen, base, shape, basis, outside),
            name=f"isochor-lattice-{gen}",
            daemon=True,
        )
        self.threads = [t for t in self.threads if t.is_alive()] + [thread]
        win.statusBar().showMessage("Rebuilding the lattice {}x{}x{}…".format(*shape))
        thread.start()
        return True

    def _affordable(self, shape, basis) -> bool:
        """Whether a solve on the new lattice fits this machine (:mod:`isochor.core.estimate`):
        one whose memory does not fit is not rebuilt, the line that says so in the status
        bar; one over the time limit is rebuilt, the line shown as a warning (the solve
        runs in the background with its progress, and stops at the next edit)."""
        surface = self.win.state.surface
        names = basis_names(basis) if basis is not None else surface.lattice.basis
        nx, ny, nz = (int(n) for n in shape)
        sizes = Sizes((nx, ny, nz), names[0] != BERNSTEIN, surface.full.n_faces)
        estimate = screen(sizes)
        if estimate is None or estimate.fits():
            return True
        if not estimate.memory_fits():
            self.win.statusBar().showMessage(f"The lattice was not rebuilt: {estimate.message()}")
            return False
        self.win.statusBar().showMessage(f"Warning: {estimate.message()}", 10_000)
        return True

    def cancel(self) -> None:
        """Drop the running rebuild's result (its thread ends on its own)."""
        self._running = None

    # -- the thread ----------------------------------------------------------------------------
    def _run(self, gen: int, base, shape, basis, outside) -> None:
        try:
            done = prepare_rebuild(base, shape, basis, outside)
        except IsochorError as exc:
            self._emit(self.failed, gen, str(exc))
        except Exception as exc:  # every failure becomes the message shown
            self._emit(self.failed, gen, f"{type(exc).__name__}: {exc}")
        else:
            self._emit(self.built, gen, done)

    def _emit(self, signal, gen: int, payload) -> None:
        with self._gate.lock:  # never into a deleted object
            if self._gate.closed:
                return
            with contextlib.suppress(RuntimeError):  # the window went away meanwhile
                signal.emit(gen, payload)

    # -- back on the GUI thread ----------------------------------------------------------------
    def _current(self, gen: int) -> bool:
        running, self._running = self._running, None
        if running is None or running[0] != gen:
            self._running = running
            return False
        if self.win.closed:
            return False
        if self.win.doc.cell is not running[1]:  # edited, undone or redone meanwhile
            self.win.statusBar().showMessage("The lattice was not rebuilt: the model changed.")
            return False
        return True

    def _on_built(self, gen: int, done) -> None:
        if self._current(gen):
            self.win.statusBar().clearMessage()
            if self._commit(*done):
                # the new scene's first paint is the proxy's; the full mesh (its buffers
                # uploaded anew, a render of every triangle) comes in passes after a pause
                self.win.viewport.model_frames.lower()

    def _on_failed(self, gen: int, message: str) -> None:
        if self._current(gen):
            self.win.statusBar().clearMessage()
            self.win.error("Cannot rebuild the lattice", message)

    def _commit(self, edit, prep) -> bool:
        if edit is None:
            return False
        self.win.viewport.scene.offer(prep)
        return self.win.commit_edit(edit)
