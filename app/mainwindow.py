"""The main window: the view, the side panel, the convergence plot, menus, undo, solving.

Data flow. The document's current :class:`~app.document.StateCell` is the truth. An edit
(drag, pin, typed position, target, lattice) builds a new state from what is on screen,
makes it current through :meth:`MainWindow.restore` and pushes one undo command. Making a
cell current stops the running solve and, when "preserve volume" is on and the cell was
never solved, starts a new solve from it. Progress records arrive by queued signals; the
newest one is kept and a 60 Hz frame timer draws it, so the view redraws at most once per
frame however fast records come. Records of any solve but the accepted one are dropped by
their generation id, so a stale result can never overwrite a newer state.
"""

from __future__ import annotations

import os
import sys
from collections import deque
from pathlib import Path

import numpy as np



from PySide6.QtCore import QPoint, Qt, QTimer, Signal  # noqa: E402
from PySide6.QtGui import QAction, QKeySequence, QUndoStack  # noqa: E402
from PySide6.QtWidgets import (  # noqa: E402
    QApplication,
    QDockWidget,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMenu,
    QMessageBox,
    QScrollArea,
    QToolBar,
)

from app import style  # noqa: E402
from app.document import DocState, Document, StateCell  # noqa: E402
from app.panel import Panel, bind  # noqa: E402
from app.plot import ConvergencePlot  # noqa: E402
from app.undo import StateCommand  # noqa: E402
from app.viewport import Viewport  # noqa: E402
from app.worker import SolveWorker  # noqa: E402
from core.errors import IsochorError  # noqa: E402
from core.examples import EXAMPLES  # noqa: E402

FRAME_MS = 16  # the redraw timer: at most one redraw per frame (~60 Hz)
LIVE_MS = 40  # during a live drag, restart the solve at most this often

OPEN_FILTER = ("Models and scenarios (*.obj *.ply *.stl *.off *.json);;"
               "Models (*.obj *.ply *.stl *.off);;Scenarios (*.json);;All files (*)")
EXPORT_FILTER = "Wavefront OBJ (*.obj);;Stanford PLY (*.ply);;STL (*.stl)"


class MainWindow(QMainWindow):
    """The editor window.

    Signals
    -------
    solveDone(int, bool) : a solve the window accepted ended (generation, success)
    """

    solveDone = Signal(int, bool)

    def __init__(self, document: Document | None = None) -> None:
        super().__init__()
        self.setWindowTitle("Isochor")
        self.resize(1360, 860)
        self.headless_errors = False  # screenshot mode: errors to stderr, no dialogs
        self.doc = document if document is not None else Document.example()

        # solving and drawing state
        self.worker = SolveWorker(self)
        self.worker.progress.connect(self._on_progress)
        self.worker.finished.connect(self._on_finished)
        self.worker.failed.connect(self._on_failed)
        self._accept_gen: int | None = None  # the only generation whose records count
        self._solving_cell: StateCell | None = None
        self._live = False  # the accepted solve is a live-drag preview
        self._pending: tuple[np.ndarray, object, int | None] | None = None  # to draw next
        self._shown = np.zeros((0, 3))  # nodes drawn last
        self._drag: dict | None = None
        self._frame_after_solve = False
        self._deferred_solve = False
        self._last_progress = None
        # counters the tests read
        self.redraws = 0
        self.frames_by_generation: dict[int, int] = {}
        self.accepted_log: deque[tuple[int, str]] = deque(maxlen=50_000)  # (gen, kind)
        self.dropped = 0
        self.last_solve_input: tuple[np.ndarray, np.ndarray, float] | None = None
        self.last_result = None

        self.undo_stack = QUndoStack(self)
        self.undo_stack.cleanChanged.connect(lambda _: self._update_title())

        self.viewport = Viewport(self)
        self.setCentralWidget(self.viewport)
        self.panel = Panel()
        self.plot = ConvergencePlot()
        self._build_docks()
        self._build_actions()
        self._build_menus()
        self._build_toolbar()
        self._build_status()
        self._connect()

        self.frame_timer = QTimer(self)
        self.frame_timer.setInterval(FRAME_MS)
        self.frame_timer.timeout.connect(self._on_frame)
        self.frame_timer.start()
        self.live_timer = QTimer(self)
        self.live_timer.setSingleShot(True)
        self.live_timer.setInterval(LIVE_MS)
        self.live_timer.timeout.connect(self._live_solve)

        self._load(self.doc)

    # -- construction ------------------------------------------------------------------------
    def _build_docks(self) -> None:
        scroll = QScrollArea()
        scroll.setWidget(self.panel)
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QScrollArea.Shape.NoFrame)
        scroll.setMinimumWidth(290)
        dock = QDockWidget("Inspector", self)
        dock.setObjectName("inspector")
        dock.setWidget(scroll)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QDockWidget.DockWidgetFeature.DockWidgetFloatable)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
        self.inspector_dock = dock
        pdock = QDockWidget("Convergence", self)
        pdock.setObjectName("convergence")
        pdock.setWidget(self.plot)
        pdock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                          | QDockWidget.DockWidgetFeature.DockWidgetFloatable
                          | QDockWidget.DockWidgetFeature.DockWidgetClosable)
        self.addDockWidget(Qt.DockWidgetArea.BottomDockWidgetArea, pdock)
        self.plot_dock = pdock
        self.resizeDocks([pdock], [190], Qt.Orientation.Vertical)

    def _action(self, text, slot=None, shortcut=None, checkable=False, checked=False,
                tip=None) -> QAction:
        a = QAction(text, self)
        if shortcut is not None:
            a.setShortcuts(shortcut if isinstance(shortcut, list) else [shortcut])
        if checkable:
            a.setCheckable(True)
            a.setChecked(checked)
        if tip:
            a.setToolTip(tip)
            a.setStatusTip(tip)
        if slot is not None:
            (a.toggled if checkable else a.triggered).connect(slot)
        self.addAction(a)  # shortcuts work while the menus are closed
        return a

    def _build_actions(self) -> None:
        A, K = self._action, QKeySequence
        self.act_open = A("&Open…", self.open_dialog, K.StandardKey.Open,
                          tip="Open a model (OBJ, PLY, STL, OFF) or a scenario (.json)")
        self.act_save = A("&Save Scenario", self.save, K.StandardKey.Save)
        self.act_save_as = A("Save Scenario &As…", self.save_as, K("Ctrl+Shift+S"))
        self.act_export = A("&Export Deformed Mesh…", self.export_dialog, K("Ctrl+E"),
                            tip="Write the deformed full-resolution mesh (OBJ, PLY, STL)")
        self.act_quit = A("&Quit", self.close, K.StandardKey.Quit)
        self.act_undo = self.undo_stack.createUndoAction(self, "&Undo")
        self.act_undo.setShortcuts([K("Ctrl+Z")])
        self.act_redo = self.undo_stack.createRedoAction(self, "&Redo")
        self.act_redo.setShortcuts([K("Ctrl+Shift+Z"), K("Ctrl+Y")])
        self.addAction(self.act_undo)
        self.addAction(self.act_redo)
        self.act_select_all = A("Select &All Nodes", self.select_all, K("Ctrl+A"))
        self.act_pin = A("Toggle &Pin", self.toggle_pin, K("P"),
                         tip="Pin the selected nodes, or unpin them if all are fixed")
        self.act_pin_all = A("Pin All", lambda: self.set_pins(None, True))
        self.act_unpin_all = A("Unpin All", lambda: self.set_pins(None, False))
        self.act_reset = A("Reset Nodes", self.reset_nodes,
                           tip="Every node back to rest, no pins")
        self.act_box = A("&Box Select", self.viewport_box_mode, K("B"), checkable=True,
                         tip="Drag a box to select nodes (Shift-drag does it any time)")
        self.act_preserve = A("Preserve &Volume", self.set_preserve, K("V"), checkable=True,
                              checked=True,
                              tip="Off: plain FFD, the nodes stay where you put them")
        self.act_live = A("&Live Solve", None, K("L"), checkable=True,
                          tip="Solve continuously while a node is dragged")
        self.act_solve = A("&Solve Again", self.solve_again, K("Ctrl+R"))
        self.act_stop = A("S&top Solve", self.stop_solve, K("Ctrl+."))
        self.act_frame = A("&Frame Model", self.viewport.frame, K("F"))
        self.act_views = {}
        for name, key in (("home", "Home"), ("front", "1"), ("back", "Ctrl+1"),
                          ("right", "3"), ("left", "Ctrl+3"), ("top", "7"),
                          ("bottom", "Ctrl+7")):
            self.act_views[name] = A(f"{name.title()} View",
                                     lambda _=False, n=name: self.viewport.standard_view(n),
                                     K(key))
        self.act_lattice = A("Show &Lattice", self._display_changed, checkable=True,
                             checked=True)
        self.act_diag = A("Show Diagonal Springs", self._display_changed, checkable=True,
                          checked=False)
        self.act_ghost = A("Show &Ghost of the Original", self.viewport_ghost,
                           checkable=True, checked=False)
        self.act_smooth = A("&Smooth Shading", self.viewport_smooth, checkable=True,
                            checked=True)
        self.act_help = A("&Controls", self.show_controls, K("F1"))
        self.act_about = A("&About Isochor", self.show_about)

    def _build_menus(self) -> None:
        mb = self.menuBar()
        m = mb.addMenu("&File")
        m.addAction(self.act_open)
        ex = m.addMenu("Open &Example")
        ex.addAction("Torus in a 3x3x3 lattice (no moves)",
                     lambda: self.open_example(None))
        for name, text in EXAMPLES.items():
            ex.addAction(text, lambda _=False, n=name: self.open_example(n))
        m.addSeparator()
        for a in (self.act_save, self.act_save_as, self.act_export):
            m.addAction(a)
        m.addSeparator()
        m.addAction(self.act_quit)
        m = mb.addMenu("&Edit")
        for a in (self.act_undo, self.act_redo):
            m.addAction(a)
        m.addSeparator()
        for a in (self.act_select_all, self.act_box):
            m.addAction(a)
        m.addSeparator()
        for a in (self.act_pin, self.act_pin_all, self.act_unpin_all, self.act_reset):
            m.addAction(a)
        m = mb.addMenu("&Solve")
        for a in (self.act_preserve, self.act_live, self.act_solve, self.act_stop):
            m.addAction(a)
        m = mb.addMenu("&View")
        m.addAction(self.act_frame)
        for a in self.act_views.values():
            m.addAction(a)
        m.addSeparator()
        for a in (self.act_lattice, self.act_diag, self.act_ghost, self.act_smooth):
            m.addAction(a)
        m.addSeparator()
        m.addAction(self.inspector_dock.toggleViewAction())
        m.addAction(self.plot_dock.toggleViewAction())
        m = mb.addMenu("&Help")
        m.addAction(self.act_help)
        m.addAction(self.act_about)

    def _build_toolbar(self) -> None:
        tb = QToolBar("Main", self)
        tb.setObjectName("main-toolbar")
        tb.setMovable(False)
        tb.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        self.addToolBar(tb)
        self.act_open.setIconText("Open")
        self.act_save.setIconText("Save")
        self.act_export.setIconText("Export")
        self.act_undo.setIconText("Undo")
        self.act_redo.setIconText("Redo")
        self.act_box.setIconText("Box select")
        self.act_pin.setIconText("Pin")
        self.act_preserve.setIconText("Preserve volume")
        self.act_live.setIconText("Live")
        self.act_frame.setIconText("Frame")
        for a in (self.act_open, self.act_save, self.act_export, None, self.act_undo,
                  self.act_redo, None, self.act_box, self.act_pin, None, self.act_preserve,
                  self.act_live, None, self.act_frame):
            tb.addSeparator() if a is None else tb.addAction(a)
        for name in ("home", "front", "right", "top"):
            a = self.act_views[name]
            a.setIconText(name.title())
            tb.addAction(a)

    def _build_status(self) -> None:
        sb = self.statusBar()
        self.st_state = QLabel()
        self.st_volume = QLabel()
        self.st_level = QLabel()
        self.st_solver = QLabel()
        self.st_time = QLabel()
        for w in (self.st_state, self.st_volume, self.st_level, self.st_solver, self.st_time):
            sb.addPermanentWidget(w)
        self._set_state_chip("Ready", "#8b95a5")

    def _connect(self) -> None:
        vp = self.viewport
        vp.selectionChanged.connect(self._selection_changed)
        vp.dragStarted.connect(self._drag_started)
        vp.dragMoved.connect(self._drag_moved)
        vp.dragFinished.connect(self._drag_finished)
        vp.dragCanceled.connect(self._drag_canceled)
        vp.lockChanged.connect(self._lock_changed)
        vp.contextMenuRequested.connect(self._context_menu)
        vp.fileDropped.connect(lambda path: QTimer.singleShot(0, lambda: self.open_path(path)))
        p = self.panel
        p.positionEdited.connect(self.type_position)
        p.pinClicked.connect(lambda on: self.set_pins(self.viewport.selection, on))
        p.pin_all.clicked.connect(self.act_pin_all.trigger)
        p.unpin_all.clicked.connect(self.act_unpin_all.trigger)
        p.targetEdited.connect(self.set_target)
        p.latticeRequested.connect(self.rebuild_lattice)
        p.solve_button.clicked.connect(self.solve_again)
        p.reset_button.clicked.connect(self.reset_nodes)
        bind(self.act_preserve, p.preserve_box)
        bind(self.act_live, p.live_box)
        bind(self.act_lattice, p.lattice_box)
        bind(self.act_diag, p.diag_box)
        bind(self.act_ghost, p.ghost_box)
        bind(self.act_smooth, p.smooth_box)

    # -- document ----------------------------------------------------------------------------
    @property
    def state(self) -> DocState:
        return self.doc.state

    @property
    def preserve(self) -> bool:
        return self.act_preserve.isChecked()

    def _load(self, doc: Document) -> None:
        """Show a new document (not undoable: the undo history starts afresh)."""
        self._stop()
        self.doc = doc
        st = doc.state
        up = "z" if "builtin" in st.problem.scenario.model else "y"
        self.viewport.set_scene(st.surface, self._view_nodes(st), st.pinned, st.moved, up=up)
        self.viewport.set_ghost(self.act_ghost.isChecked())
        self.viewport.set_smooth(self.act_smooth.isChecked())
        self.viewport.set_lattice_visible(self.act_lattice.isChecked(),
                                          self.act_diag.isChecked())
        self.panel.show_shape(st.lattice.shape)
        self.panel.show_target(st.target_ratio * 100)
        self.plot.reset(st.surface.size, st.problem.scenario.tol_volume,
                        st.problem.scenario.tol_nodes)
        self.undo_stack.clear()
        self.undo_stack.setClean()
        self._frame_after_solve = True  # once the opening solve ends, fit it in the view
        self._update_title()
        self._selection_changed()
        self._pending = (self._view_nodes(st), None, None)
        for w in st.problem.warnings:
            self.statusBar().showMessage(w, 10000)
        if self.viewport.paints == 0:
            # Not drawn yet: solve after the first frame, whose set-up (shader compilation
            # in a software renderer) would otherwise hold up the solver thread.
            self._deferred_solve = True
        else:
            self._solve_if_needed()

    def restore(self, cell: StateCell) -> None:
        """Make ``cell`` the current state (undo, redo and every edit come through here)."""
        self._stop()
        self._drag = None
        old = self.doc.state
        self.doc.cell = cell
        st = cell.state
        if st.problem is not old.problem:
            up = "z" if "builtin" in st.problem.scenario.model else "y"
            same_model = st.surface.full is old.surface.full
            self.viewport.set_scene(st.surface, self._view_nodes(st), st.pinned, st.moved,
                                    up=up, reset_camera=not same_model)
            self.viewport.set_ghost(self.act_ghost.isChecked())
            self.viewport.set_smooth(self.act_smooth.isChecked())
            self.viewport.set_lattice_visible(self.act_lattice.isChecked(),
                                              self.act_diag.isChecked())
            self.panel.show_shape(st.lattice.shape)
        else:
            self.viewport.set_flags(st.pinned, st.moved)
        self.panel.show_target(st.target_ratio * 100)
        self._pending = (self._view_nodes(st), None, None)
        self._selection_changed()
        self._solve_if_needed()

    def _commit(self, state: DocState, text: str) -> None:
        """Make ``state`` current as one undoable step."""
        self._frame_after_solve = False
        before = self.doc.cell
        after = StateCell(state)
        self.restore(after)
        self.undo_stack.push(StateCommand(text, before, after, self.restore))

    def _view_nodes(self, st: DocState) -> np.ndarray:
        """What the view shows for a state: with "preserve volume" off, plain FFD (the free
        nodes at rest, the fixed ones where the user put them)."""
        if self.preserve:
            return np.array(st.nodes)
        rest = st.lattice.rest_nodes
        return np.where(st.fixed[:, None], st.nodes, rest)

    def _current_nodes(self) -> np.ndarray:
        """The nodes on screen (or about to be): the base of every new edit."""
        if self._pending is not None:
            return np.array(self._pending[0])
        return np.array(self._shown)

    # -- solving -----------------------------------------------------------------------------
    def _solve_if_needed(self) -> None:
        st = self.state
        if self.preserve and not st.solved:
            self._start_solve()
        else:
            self._show_idle_state()

    def _start_solve(self) -> None:
        st = self.state
        self._solving_cell = self.doc.cell
        self._live = False
        self.last_solve_input = (np.array(st.nodes), np.array(st.fixed), st.target_ratio)
        self._begin_generation(st, st.nodes, st.fixed)

    def _begin_generation(self, st: DocState, nodes, fixed) -> None:
        gen = self.worker.start(st.surface, nodes, fixed, target_ratio=st.target_ratio,
                                options=st.problem.options)
        self._accept_gen = gen
        self._last_progress = None
        self.plot.reset(st.surface.size, st.problem.scenario.tol_volume,
                        st.problem.scenario.tol_nodes)
        self._set_state_chip("Solving…", style.MOVED)

    def _stop(self) -> None:
        """Stop the running solve; its queued records will be dropped."""
        self._deferred_solve = False
        self.worker.stop()
        self._accept_gen = None
        self._solving_cell = None
        self.live_timer.stop()

    def is_solving(self) -> bool:
        """A solve runs, or is about to start (the opening solve waits for a first frame)."""
        return self._accept_gen is not None or self._deferred_solve

    def stop_solve(self) -> None:
        if self.is_solving():
            self._stop()
            self._set_state_chip("Stopped", "#8b95a5")

    def solve_again(self) -> None:
        if not self.preserve:
            self.statusBar().showMessage("Turn on “Preserve volume” to solve.", 4000)
            return
        self._start_solve()

    def _on_progress(self, gen: int, record) -> None:
        if gen != self._accept_gen:
            self.dropped += 1
            return
        self.accepted_log.append((gen, "progress"))
        nodes = np.array(record.nodes)
        if self._live and self._drag is not None:
            nodes[self._drag["rows"]] = self._drag["nodes"][self._drag["rows"]]
        self._pending = (nodes, record, gen)
        self._last_progress = record
        self.plot.add(record.elapsed, record.nodes, record.rel_volume_error, record.level,
                      record.level_done)

    def _on_finished(self, gen: int, result) -> None:
        if gen != self._accept_gen:
            self.dropped += 1
            return
        self.accepted_log.append((gen, "finished"))
        self._accept_gen = None
        self.last_result = result
        self.plot.finish(result.nodes)
        if self._live:  # a preview during a live drag: show it, keep no state
            nodes = np.array(result.nodes)
            if self._drag is not None:
                nodes[self._drag["rows"]] = self._drag["nodes"][self._drag["rows"]]
            self._pending = (nodes, None, None)
            self.solveDone.emit(gen, True)
            return
        cell, self._solving_cell = self._solving_cell, None
        if cell is not None:
            cell.state = cell.state.with_(nodes=result.nodes, solved=True,
                                          converged=result.converged, message=result.message)
        self._pending = (np.array(result.nodes), None, None)
        if self._frame_after_solve:
            self._frame_after_solve = False
            self._on_frame()
            self.viewport.frame()
        self._show_idle_state()
        self.solveDone.emit(gen, bool(result.converged))

    def _on_failed(self, gen: int, message: str) -> None:
        if gen != self._accept_gen:
            self.dropped += 1
            return
        self.accepted_log.append((gen, "failed"))
        self._accept_gen = None
        live = self._live
        cell, self._solving_cell = self._solving_cell, None
        if cell is not None and not live:
            cell.state = cell.state.with_(solved=True, converged=False, message=message)
            self._pending = (self._view_nodes(cell.state), None, None)
        self._set_state_chip("Solver failed", style.PINNED)
        self.solveDone.emit(gen, False)
        if not live:
            self._error("The solver stopped", message)

    # -- drawing -----------------------------------------------------------------------------
    def _on_frame(self) -> None:
        """The frame timer: draw the newest pending nodes, if any (at most once a frame)."""
        if self._deferred_solve and self.viewport.paints > 0:
            self._deferred_solve = False
            self._solve_if_needed()
        if self._pending is None:
            return
        nodes, record, gen = self._pending
        self._pending = None
        self._draw(nodes, record, gen)
        # A software renderer can take longer than a frame and holds the GIL meanwhile:
        # leave the solver thread more time than the last repaint took.
        # (Only while a solve runs: a drag alone should follow the mouse at full rate.)
        paint_ms = int(1500 * self.viewport.paint_seconds) if self.is_solving() else 0
        self.frame_timer.setInterval(max(FRAME_MS, paint_ms))

    def _draw(self, nodes: np.ndarray, record=None, gen: int | None = None) -> None:
        surface = self.state.surface
        if len(nodes) != surface.lattice.n_nodes:
            return
        points = surface.deform(nodes)
        self._shown = np.array(nodes)
        self.viewport.set_frame(nodes, points)
        self.viewport.update()
        self.redraws += 1
        if gen is not None:
            self.frames_by_generation[gen] = self.frames_by_generation.get(gen, 0) + 1
        volume = self.viewport.volume
        rest = surface.rest_volume
        target = self.state.target_ratio
        self.st_volume.setText(f"Volume {100 * volume / rest:.2f} % "
                               f"(target {100 * target:.4g} %)")
        if record is not None:
            self.st_level.setText(f"Level {record.level + 1}/{record.n_levels} · "
                                  f"{record.triangles:,} triangles")
            self.st_solver.setText(f"step {record.step} · σ {record.sigma:.3g} · "
                                   f"λ {record.lam:.3g} · |dV|/V0 "
                                   f"{abs(record.rel_volume_error):.1e}")
            self.st_time.setText(f"{1000 * record.elapsed:.0f} ms")
            self.plot.update()
        self._refresh_selection_panel()

    def _show_idle_state(self) -> None:
        st = self.state
        if not self.preserve:
            self._set_state_chip("Plain FFD", "#8b95a5")
            self.panel.show_solve_state("Volume constraint off: plain free-form deformation.")
            return
        r = self.last_result
        if st.solved and not st.converged:
            self._set_state_chip("Not converged", style.PINNED)
            self.panel.show_solve_state(st.message or "The solve did not converge.",
                                        style.PINNED)
        elif st.solved:
            self._set_state_chip("Converged", style.FREE)
            if r is not None:
                levels = [s.level + 1 for s in r.levels]
                span = (f"level {levels[0]}" if len(levels) == 1 else
                        f"levels {levels[0]}–{levels[-1]}") if levels else "no level"
                self.st_level.setText(f"Solved {span} of {len(st.surface.levels)}")
                self.st_solver.setText(f"σ {r.sigma:.3g} · λ {r.lam:.3g} · |dV|/V0 "
                                       f"{abs(r.rel_volume_error):.1e} (full mesh)")
                self.st_time.setText(f"{1000 * r.elapsed:.0f} ms")
                self.panel.show_solve_state(
                    f"Converged: |dV|/V0 = {abs(r.rel_volume_error):.1e} on the full mesh, "
                    f"{r.free_nodes} free nodes.", style.FREE)
            else:
                self.panel.show_solve_state("At rest: nothing to solve.")
        else:
            self._set_state_chip("Edited", "#8b95a5")
            self.panel.show_solve_state("Not solved yet.")

    def _set_state_chip(self, text: str, color: str) -> None:
        self.st_state.setText(f'<span style="color:{color}">&#9679;</span> {text}')

    def _update_title(self) -> None:
        star = "" if self.undo_stack.isClean() else " *"
        self.setWindowTitle(f"{self.doc.title}{star} — Isochor")

    # -- selection ---------------------------------------------------------------------------
    def _selection_changed(self) -> None:
        self._refresh_selection_panel()

    def _refresh_selection_panel(self) -> None:
        st = self.state
        nodes = self._shown if len(self._shown) == st.lattice.n_nodes else st.nodes
        self.panel.show_selection(st.lattice, self.viewport.selection, nodes, st.pinned,
                                  st.moved, step=st.surface.size / 100)

    def select_all(self) -> None:
        self.viewport.set_selection(range(self.state.lattice.n_nodes))

    # -- edits -------------------------------------------------------------------------------
    def _drag_started(self) -> None:
        self._frame_after_solve = False
        base = self._current_nodes()
        self._stop()
        rows = self.viewport.selection.copy()
        self._drag = {"before": self.doc.cell, "base": base, "rows": rows,
                      "nodes": base.copy()}
        self._pending = (base, None, None)
        self.viewport.show_info(f"Moving {len(rows)} node{'s' if len(rows) != 1 else ''} — "
                                "X/Y/Z lock an axis, Shift+X/Y/Z a plane, Esc cancels")

    def _drag_moved(self, delta) -> None:
        d = self._drag
        if d is None:
            return
        rows = d["rows"]
        # Live: the free nodes follow the newest preview solve; otherwise they stay put.
        nodes = self._current_nodes() if self._live_active() else d["base"].copy()
        nodes[rows] = d["base"][rows] + delta
        d["nodes"] = nodes
        self._pending = (nodes, None, None)
        if self._live_active() and not self.live_timer.isActive():
            self.live_timer.start()

    def _live_active(self) -> bool:
        return self.act_live.isChecked() and self.preserve

    def _live_solve(self) -> None:
        """Restart the preview solve from the nodes on screen (free nodes where the last
        preview left them, the dragged ones under the cursor)."""
        d = self._drag
        if d is None:
            return
        st = d["before"].state
        nodes = self._current_nodes()
        nodes[d["rows"]] = d["nodes"][d["rows"]]
        fixed = st.fixed.copy()
        fixed[d["rows"]] = True
        self._solving_cell = None
        self._live = True
        self._begin_generation(st, nodes, fixed)

    def _drag_finished(self) -> None:
        d = self._drag
        if d is None:
            return
        self.viewport.show_info("")
        rows = d["rows"]
        nodes = np.array(d["nodes"])
        if self._live_active():
            nodes = self._current_nodes()
            nodes[rows] = d["nodes"][rows]
        self._drag = None
        self._live = False
        before = d["before"]
        state = before.state.moved_to(nodes, rows)
        after = StateCell(state)
        self.restore(after)
        n = len(rows)
        self.undo_stack.push(StateCommand(f"Move {n} node{'s' if n != 1 else ''}", before,
                                          after, self.restore))

    def _drag_canceled(self) -> None:
        d = self._drag
        self.viewport.show_info("")
        if d is None:
            return
        self._live = False
        self.restore(d["before"])

    def _lock_changed(self, text: str) -> None:
        if self._drag is not None:
            rows = self._drag["rows"]
            lock = f" — locked to the {text}" if text else ""
            self.viewport.show_info(
                f"Moving {len(rows)} node{'s' if len(rows) != 1 else ''}{lock} — "
                "X/Y/Z lock an axis, Shift+X/Y/Z a plane, Esc cancels")

    def type_position(self, axis: int, value: float) -> None:
        rows = self.viewport.selection
        if len(rows) == 0:
            return
        nodes = self._current_nodes()
        now = nodes[rows, axis].mean()
        if abs(value - now) < 1e-12:
            return
        nodes[rows, axis] += value - now
        self._commit(self.state.moved_to(nodes, rows),
                     f"Move {len(rows)} node{'s' if len(rows) != 1 else ''}")

    def toggle_pin(self) -> None:
        rows = self.viewport.selection
        if len(rows) == 0:
            self.statusBar().showMessage("Select nodes to pin first.", 3000)
            return
        self.set_pins(rows, not bool(self.state.fixed[rows].all()))

    def set_pins(self, rows, pin: bool) -> None:
        """Pin (or unpin) ``rows``; None means every node. One undo step."""
        st = self.state
        rows = np.arange(st.lattice.n_nodes) if rows is None else np.asarray(rows, dtype=int)
        if len(rows) == 0:
            return
        changes = (~st.pinned[rows]).any() if pin else st.fixed[rows].any()
        if not changes:
            return
        new = st.with_(nodes=self._current_nodes()).pinned_as(rows, pin)
        n = len(rows)
        what = "all nodes" if n == st.lattice.n_nodes else f"{n} node{'s' if n != 1 else ''}"
        self._commit(new, f"{'Pin' if pin else 'Unpin'} {what}")

    def set_target(self, percent: float) -> None:
        ratio = float(percent) / 100.0
        if ratio == self.state.target_ratio:
            return
        self._commit(self.state.with_(nodes=self._current_nodes(), target_ratio=ratio),
                     f"Target volume {percent:g} %")

    def reset_nodes(self) -> None:
        st = self.state
        n = st.lattice.n_nodes
        self._commit(st.with_(nodes=st.lattice.rest_nodes, pinned=np.zeros(n, bool),
                              moved=np.zeros(n, bool), solved=st.target_ratio == 1.0),
                     "Reset nodes")

    def rebuild_lattice(self, shape) -> None:
        if tuple(shape) == tuple(self.state.lattice.shape):
            return
        try:
            state = self.doc.rebuilt(tuple(shape))
        except IsochorError as exc:
            self._error("Cannot rebuild the lattice", str(exc))
            return
        self._commit(state, "Rebuild lattice {}x{}x{}".format(*shape))

    def set_preserve(self, on: bool) -> None:
        if not hasattr(self, "doc") or not hasattr(self, "undo_stack"):
            return
        if not on:
            self._stop()
        self._pending = (self._view_nodes(self.state), None, None)
        self._solve_if_needed()

    # -- display -----------------------------------------------------------------------------
    def viewport_box_mode(self, on: bool) -> None:
        self.viewport.box_mode = bool(on)

    def viewport_ghost(self, on: bool) -> None:
        self.viewport.set_ghost(on)
        self.viewport.update()

    def viewport_smooth(self, on: bool) -> None:
        self.viewport.set_smooth(on)
        self.viewport.update()

    def _display_changed(self, _=None) -> None:
        self.viewport.set_lattice_visible(self.act_lattice.isChecked(),
                                          self.act_diag.isChecked())
        self.viewport.update()

    def _context_menu(self, row: int, pos: QPoint) -> None:
        self.exec_menu(self.context_menu(row), pos)

    def context_menu(self, row: int) -> QMenu:
        """The right-click menu for node ``row`` (-1: empty space): pins and selection."""
        if row >= 0 and row not in self.viewport.selection:
            self.viewport.set_selection([row])
        menu = QMenu(self)
        rows = self.viewport.selection
        if len(rows):
            fixed = bool(self.state.fixed[rows].all())
            n = len(rows)
            what = f"{n} node{'s' if n != 1 else ''}"
            menu.addAction(f"Unpin {what}" if fixed else f"Pin {what}",
                           lambda: self.set_pins(rows, not fixed))
            menu.addSeparator()
        menu.addAction(self.act_pin_all)
        menu.addAction(self.act_unpin_all)
        menu.addSeparator()
        menu.addAction(self.act_select_all)
        menu.addAction(self.act_frame)
        return menu

    def exec_menu(self, menu: QMenu, pos: QPoint) -> None:
        menu.exec(pos)

    # -- files -------------------------------------------------------------------------------
    def _error(self, title: str, message: str) -> None:
        if self.headless_errors:
            print(f"isochor: {message}", file=sys.stderr)
            return
        QMessageBox.critical(self, title, message)

    def _confirm_discard(self) -> bool:
        """True when there are no unsaved changes or the user lets them go."""
        if self.undo_stack.isClean():
            return True
        answer = QMessageBox.question(
            self, "Unsaved changes",
            f"Save the changes to {self.doc.title} before closing it?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard
            | QMessageBox.StandardButton.Cancel, QMessageBox.StandardButton.Save)
        if answer == QMessageBox.StandardButton.Save:
            return self.save()
        return answer == QMessageBox.StandardButton.Discard

    def open_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open a model or a scenario",
                                              self._dialog_dir(), OPEN_FILTER)
        if path:
            self.open_path(path)

    def _dialog_dir(self) -> str:
        if self.doc.path is not None:
            return str(self.doc.path.parent)
        return os.getcwd()

    def open_path(self, path: str | Path) -> bool:
        """Open a model or scenario; on error show it and keep the current document."""
        if not self._confirm_discard():
            return False
        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        self.statusBar().showMessage(f"Opening {Path(path).name}…")
        QApplication.processEvents()
        try:
            doc = Document.open(path)
        except IsochorError as exc:
            QApplication.restoreOverrideCursor()
            self.statusBar().clearMessage()
            self._error("Cannot open the file", str(exc))
            return False
        except Exception as exc:  # noqa: BLE001 (a loader bug must not take the document)
            QApplication.restoreOverrideCursor()
            self.statusBar().clearMessage()
            self._error("Cannot open the file", f"{Path(path).name}: {type(exc).__name__}: {exc}")
            return False
        QApplication.restoreOverrideCursor()
        self.statusBar().clearMessage()
        self._load(doc)
        return True

    def open_example(self, name: str | None) -> None:
        if not self._confirm_discard():
            return
        if name is None:
            from core.scenario import Scenario, build  # noqa: PLC0415

            sc = Scenario.from_dict({"model": {"builtin": "torus"},
                                     "lattice": {"nodes": [3, 3, 3]}})
            doc = Document(build(sc), title="torus")
        else:
            doc = Document.example(name)
        self._load(doc)

    def save(self) -> bool:
        if self.doc.path is None:
            return self.save_as()
        return self._save_to(self.doc.path)

    def save_as(self) -> bool:
        start = str(self.doc.path) if self.doc.path else os.path.join(os.getcwd(),
                                                                       "scenario.json")
        path, _ = QFileDialog.getSaveFileName(self, "Save scenario", start,
                                              "Scenarios (*.json)")
        if not path:
            return False
        if not path.lower().endswith(".json"):
            path += ".json"
        return self._save_to(Path(path))

    def _save_to(self, path: Path) -> bool:
        try:
            self.doc.save(path)
        except (IsochorError, OSError) as exc:
            self._error("Cannot save the scenario", str(exc))
            return False
        self.undo_stack.setClean()
        self._update_title()
        self.statusBar().showMessage(f"Saved {path}", 4000)
        return True

    def export_dialog(self) -> None:
        base = Path(self.doc.title).stem or "deformed"
        path, chosen = QFileDialog.getSaveFileName(
            self, "Export the deformed mesh", os.path.join(self._dialog_dir(),
                                                           f"{base}-deformed.obj"),
            EXPORT_FILTER)
        if path:
            if not Path(path).suffix:
                path += {"Stanford PLY (*.ply)": ".ply", "STL (*.stl)": ".stl"}.get(chosen,
                                                                                   ".obj")
            self.export(path)

    def export(self, path: str | Path) -> bool:
        try:
            self.doc.export(path, self._current_nodes())
        except (IsochorError, OSError, ValueError) as exc:
            self._error("Cannot export the mesh", str(exc))
            return False
        self.statusBar().showMessage(f"Exported {path}", 4000)
        return True

    # -- help --------------------------------------------------------------------------------
    def show_controls(self) -> None:
        QMessageBox.information(self, "Controls", CONTROLS_HTML)

    def show_about(self) -> None:
        QMessageBox.about(self, "About Isochor",
                          "<b>Isochor</b><br>Volume-preserving free-form deformation after "
                          "Hirota, Maheshwari and Lin (1999).")

    # -- closing -----------------------------------------------------------------------------
    def closeEvent(self, ev) -> None:  # noqa: N802
        if not self._confirm_discard():
            ev.ignore()
            return
        self.shutdown()
        super().closeEvent(ev)

    def shutdown(self) -> None:
        """Stop the timers and the worker (waits at most half a second), release VTK."""
        self.frame_timer.stop()
        self.live_timer.stop()
        self._stop()
        self.worker.shutdown(timeout=0.5)
        self.viewport.close()


CONTROLS_HTML = """
<b>Mouse</b><br>
Click a node: select it · Shift-click: add or remove it<br>
Shift-drag on empty space (or Box select mode): select the nodes in a box<br>
Drag a selected node: move the selection in the view plane<br>
Left-drag on empty space: rotate · middle: pan · wheel or right-drag: zoom<br>
Right click: pin menu<br><br>
<b>While dragging</b><br>
X / Y / Z: lock to that axis · Shift+X / Y / Z: lock to the plane across it<br>
the same key again unlocks · Esc: cancel<br><br>
<b>Keys</b><br>
P: pin or unpin the selection · F: frame · Home, 1, 3, 7 (Ctrl: opposite): views<br>
B: box select · V: preserve volume · L: live solve · Ctrl+A: select all<br>
Ctrl+Z / Ctrl+Shift+Z: undo / redo
"""
