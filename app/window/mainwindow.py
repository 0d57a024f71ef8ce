"""The main window: the shell around the editing session.

The window holds no editing state. The :class:`~isochor.app.session.controller.EditorSession` owns
the document, the undo stack, the solver worker and the frame schedule; the window turns what
the user does into calls on it (edits come from the document's rules) and draws what its
signals say: the view (:mod:`isochor.app.view.viewport`), the Inspector panel, the convergence
plot. It is composed of parts it holds as fields: the status bar, the notes and the marks on
the view (``readout``, :mod:`isochor.app.window.readout`); the actions, menus and toolbar
(``action_set``, :mod:`isochor.app.window.actions`); the file commands (``files``,
:mod:`isochor.app.window.files`); the frames, a big model's proxy while it moves
(``frames``, :mod:`isochor.app.window.framedraw`); a big model's lattice rebuilt on a thread
(``lattice_rebuild``, :mod:`isochor.app.window.rebuild`); the node tools, the handles and the
timeline (``node_tools``, ``handle_tools``, ``timeline``: :mod:`isochor.app.window.tools`,
:mod:`isochor.app.window.handletools`, :mod:`isochor.app.window.timelinetools`).
"""

from __future__ import annotations

import sys

from PySide6.QtCore import QPoint, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QIcon
from PySide6.QtWidgets import QDockWidget, QMainWindow, QMenu, QMessageBox, QScrollArea

from ... import assets
from ...core.errors import IsochorError
from ...core.io.caps import summary
from ..editor import goalrules, noderules
from ..editor.document import Document, plural
from ..session.controller import EditorSession
from ..view.viewport import Viewport
from .actions import ActionSet
from .autosave import AutoSave
from .files import FileCommands
from .framedraw import FrameDrawer
from .handletools import HandleTools
from .layout import LayoutMemory
from .panel import Panel, bind
from .plot import ConvergencePlot
from .readout import Readout
from .rebuild import LatticeRebuild
from .timelinetools import TimelineTool
from .tools import CONTROLS_HTML, NodeTools


class MainWindow(QMainWindow):
    """The editor window.

    Parameters
    ----------
    document : the document to edit (None: the built-in example)

    Attributes
    ----------
    headless_errors : errors go to stderr, not to dialogs (:meth:`set_headless_errors`)
    closed : shut down (:meth:`shutdown`): nothing may reach the window any more

    Signals
    -------
    solveDone(int, bool) : a solve the session accepted ended (generation, success)
    idle() : nothing runs and the last frame is drawn
    """

    solveDone = Signal(int, bool)
    idle = Signal()

    def __init__(self, document: Document | None = None) -> None:
        super().__init__()
        self.setWindowTitle("Isochor")
        self.setWindowIcon(QIcon(str(assets.icon_path())))
        self.resize(1360, 860)
        self.headless_errors = False
        self.closed = False
        self._keyed = False  # the state shown last had timeline keys
        self.session = EditorSession(document if document is not None else Document.example(), self)
        # a paint outside a frame (Qt's, after a mouse move or an overlay change) holds the
        # solver too, like a frame does (see isochor.app.session.worker)
        self.viewport = Viewport(self, paint_hold=self.session.worker.held)
        self.setCentralWidget(self.viewport)
        self.files = FileCommands(self)
        self.panel = Panel()
        self.plot = ConvergencePlot(deferred=True)  # repainted with the frames
        self.readout = Readout(self)
        self.frames = FrameDrawer(self)
        self.node_tools = NodeTools(self)
        self.handle_tools = HandleTools(self)
        self.timeline = TimelineTool(self)
        self.lattice_rebuild = LatticeRebuild(self)
        self._build_docks()
        self.action_set = ActionSet(self)
        self.action_set.build_menus(
            self.menuBar(), self.files, [self.inspector_dock, self.plot_dock, self.timeline_dock]
        )
        self.action_set.build_toolbar()
        self._connect()
        self.autosave = AutoSave(self)
        self.layout_memory = LayoutMemory(self)
        self.layout_memory.restore()
        self._document_loaded()
        self._status_changed()

    # -- what the tests and the launcher use ---------------------------------------------------
    @property
    def doc(self) -> Document:
        return self.session.document

    @property
    def state(self):
        return self.session.document.state

    @property
    def undo_stack(self):
        return self.session.undo_stack

    @property
    def worker(self):
        return self.session.worker

    def is_solving(self) -> bool:
        """A solve runs, or waits for the first frame to start."""
        return self.session.busy()

    # -- construction --------------------------------------------------------------------------
    def _build_docks(self) -> None:
        scroll = QScrollArea()
        scroll.setWidget(self.panel)
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QScrollArea.Shape.NoFrame)
        # wide enough for the panel and a vertical scroll bar: never a horizontal one
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        bar = scroll.verticalScrollBar().sizeHint().width()
        scroll.setMinimumWidth(self.panel.minimumSizeHint().width() + bar)
        self.inspector_scroll = scroll
        features = QDockWidget.DockWidgetFeature
        self.inspector_dock = QDockWidget("Inspector", self)
        self.inspector_dock.setObjectName("inspector")
        self.inspector_dock.setWidget(scroll)
        self.inspector_dock.setFeatures(
            features.DockWidgetMovable | features.DockWidgetFloatable | features.DockWidgetClosable
        )  # every dock can be hidden (View menu) to give the view the room
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, self.inspector_dock)
        self.plot_dock = QDockWidget("Convergence", self)
        self.plot_dock.setObjectName("convergence")
        self.plot_dock.setWidget(self.plot)
        self.plot_dock.setFeatures(
            features.DockWidgetMovable | features.DockWidgetFloatable | features.DockWidgetClosable
        )
        # the view first: the convergence plot is a tab behind the Inspector, the timeline
        # at the bottom appears with the first key (or from View > Timeline)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, self.plot_dock)
        self.tabifyDockWidget(self.inspector_dock, self.plot_dock)
        self.inspector_dock.raise_()
        self.timeline_dock = QDockWidget("Timeline", self)
        self.timeline_dock.setObjectName("timeline")
        self.timeline_dock.setWidget(self.timeline.panel)
        self.timeline_dock.setFeatures(
            features.DockWidgetMovable | features.DockWidgetFloatable | features.DockWidgetClosable
        )
        self.addDockWidget(Qt.DockWidgetArea.BottomDockWidgetArea, self.timeline_dock)
        self.timeline_dock.hide()
        self.resizeDocks([self.inspector_dock], [scroll.minimumWidth()], Qt.Orientation.Horizontal)
        self.setCorner(Qt.Corner.BottomRightCorner, Qt.DockWidgetArea.RightDockWidgetArea)

    def _connect(self) -> None:
        s, vp, p = self.session, self.viewport, self.panel
        acts, frames = self.action_set, self.frames
        s.documentLoaded.connect(self._document_loaded)
        s.sceneChanged.connect(self._scene_changed)
        s.stateChanged.connect(self._state_changed)
        s.selectionChanged.connect(self._selection_changed)
        s.statusChanged.connect(self._status_changed)
        acts.preserve.toggled.connect(lambda _: self.readout.show_state())
        s.frameReady.connect(frames.draw)
        s.solveStarted.connect(frames.solve_started)
        s.recordAccepted.connect(frames.record)
        s.solveDone.connect(frames.solve_done)
        frames.solveDone.connect(self.solveDone)
        s.failed.connect(lambda message: self.error("The solver stopped", message))
        s.idle.connect(self.idle.emit)
        s.watch_view(frames.view_busy)  # idle once the full mesh is drawn
        vp.model_frames.follow_motion(frames.moving)
        s.flushed.connect(vp.model_frames.finish)
        vp.modelDrawn.connect(lambda: self.readout.frame(None))
        # solves start after the view's first paint (queued: not from inside the paint)
        vp.firstPainted.connect(s.view_ready, Qt.ConnectionType.QueuedConnection)
        s.undo_stack.cleanChanged.connect(self.update_title)
        vp.selectRequested.connect(lambda rows, mode: self.doc.selection.select(rows, mode))
        vp.dragStarted.connect(self._drag_started)
        vp.dragMoved.connect(s.drag_to)
        vp.dragFinished.connect(self._drag_finished)
        vp.dragCanceled.connect(self._drag_canceled)
        vp.lockChanged.connect(lambda text: vp.show_info(s.drag_text(text)))
        self.node_tools.connect_signals()
        self.handle_tools.connect_signals()
        self.timeline.connect_signals()
        vp.contextMenuRequested.connect(
            lambda row, pos: self.exec_menu(self.context_menu(row), pos)
        )
        vp.fileDropped.connect(
            lambda path: QTimer.singleShot(0, lambda: self.files.open_path(path))
        )
        p.positionEdited.connect(self.type_position)
        p.pinClicked.connect(lambda on: self.set_pins(self.doc.selection.rows, on))
        p.pinAxisClicked.connect(
            lambda axis, on: self.commit_edit(
                goalrules.edit_pin_axis(self.doc.base(), self.doc.selection.rows, axis, on)
            )
        )
        g = p.goal
        g.anchorClicked.connect(
            lambda on: self.commit_edit(goalrules.edit_anchor(self.doc.base(), on))
        )
        g.centroidClicked.connect(
            lambda on: self.commit_edit(goalrules.edit_keep_centroid(self.doc.base(), on))
        )
        g.preserveChosen.connect(
            lambda mode: self.commit_edit(goalrules.edit_preserve(self.doc.base(), mode))
        )
        g.foldGuardClicked.connect(
            lambda on: self.commit_edit(goalrules.edit_fold_guard(self.doc.base(), on))
        )
        p.pin_all.clicked.connect(acts.pin_all.trigger)
        p.unpin_all.clicked.connect(acts.unpin_all.trigger)
        p.targetEdited.connect(self.set_target)
        p.latticeRequested.connect(self.rebuild_lattice)
        p.solve_button.clicked.connect(self.solve_again)
        p.reset_button.clicked.connect(acts.reset.trigger)
        for action, box in (
            (acts.preserve, p.preserve_box),
            (acts.live, p.live_box),
            (acts.lattice, p.lattice_box),
            (acts.diag, p.diag_box),
            (acts.ghost, p.ghost_box),
            (acts.smooth, p.smooth_box),
        ):
            bind(action, box)

    # -- session -> widgets --------------------------------------------------------------------
    def _document_loaded(self) -> None:
        st = self.state
        self._rebuild_scene(reset_camera=True)
        self.plot.reset(
            st.surface.size, st.problem.scenario.tol_volume, st.problem.scenario.tol_nodes
        )
        self.frames.frame_after_solve()  # once the opening solve ends, fit it in the view
        self.update_title()
        for w in st.problem.warnings:
            self.statusBar().showMessage(w, 10000)
        caps = summary(st.surface.full)  # (the words that matter most for an open model)
        if caps.holes:
            self.statusBar().showMessage(caps.sentence(), 15000)
        self._state_changed()

    def _scene_changed(self) -> None:
        self._rebuild_scene(reset_camera=False)

    def _rebuild_scene(self, reset_camera: bool) -> None:
        st = self.state
        up = "z" if "builtin" in st.problem.scenario.model else "y"
        self.viewport.set_scene(
            st.surface,
            self.doc.view_nodes(),
            st.pin_axes,
            st.moved,
            up=up,
            reset_camera=reset_camera,
        )
        self.display_changed()
        self.panel.show_shape(st.lattice.shape, st.lattice.basis, st.lattice.outside)

    def _state_changed(self) -> None:
        st = self.state
        keyed = bool(st.timeline.keys)
        if keyed and not self._keyed:  # the first key, or a document with keys: the timeline
            self.timeline_dock.show()
        self._keyed = keyed
        self.readout.show_state()
        self.panel.show_target(st.goal.target_ratio * 100)
        # (the state's frame follows and renders the view once: an extra render here was a
        # whole render of a big model's full mesh, 100-170 ms in software OpenGL, per undo)
        self.handle_tools.show(render=False)
        self._selection_changed(repaint=False)
        self._status_changed()

    def _selection_changed(self, repaint: bool = True) -> None:
        self.viewport.set_selection(self.doc.selection.rows, repaint)
        self.show_selection()

    def show_selection(self) -> None:
        """The Inspector's selection fields, at the nodes as drawn."""
        st = self.state
        bar = self.inspector_scroll.verticalScrollBar()
        keep = bar.value()  # the Inspector stays where the user scrolled it
        self.panel.show_selection(
            st.lattice,
            self.doc.selection.rows,
            self.viewport.nodes,
            st.pin_axes,
            st.moved,
            step=st.surface.size / 100,
            held=self.readout.held_mask,
        )
        bar.setValue(keep)
        QTimer.singleShot(0, lambda: self.closed or bar.setValue(keep))  # after the layout

    def _status_changed(self) -> None:
        self.readout.status_changed()

    def update_title(self, *_args) -> None:
        star = "" if self.session.undo_stack.isClean() else " *"
        self.setWindowTitle(f"{self.doc.title}{star} — Isochor")

    # -- edits ---------------------------------------------------------------------------------
    def _drag_started(self) -> None:
        self.frames.keep_camera()
        if self.session.begin_drag():
            self.viewport.scene.set_folds(None)  # they belong to the nodes before the drag
            self.viewport.show_info(self.session.drag_text())

    def _drag_finished(self) -> None:
        self.viewport.show_info("")
        self.session.finish_drag()

    def _drag_canceled(self) -> None:
        self.viewport.show_info("")
        self.session.cancel_drag()

    def commit_edit(self, edit) -> bool:
        """Commit ``edit`` (from a document rule) as one undo step; False: nothing to do."""
        self.frames.keep_camera()
        return self.session.commit(edit)

    def type_position(self, axis: int, value: float) -> None:
        self.commit_edit(noderules.edit_position(self.doc.base(), axis, value))

    def toggle_pin(self) -> None:
        if len(self.doc.selection.rows) == 0:
            self.statusBar().showMessage("Select nodes to pin first.", 3000)
            return
        self.commit_edit(noderules.edit_toggle_pin(self.doc.base()))

    def set_pins(self, rows, pin: bool) -> None:
        """Pin (or unpin) ``rows``; None means every node. One undo step."""
        self.commit_edit(noderules.edit_pins(self.doc.base(), rows, pin))

    def pin_on(self, axes: str) -> None:
        """Pin the selection on ``axes`` only (one undo step)."""
        if len(self.doc.selection.rows) == 0:
            self.statusBar().showMessage("Select nodes to pin first.", 3000)
            return
        self.commit_edit(goalrules.edit_pin_axes(self.doc.base(), self.doc.selection.rows, axes))

    def set_target(self, percent: float) -> None:
        try:
            self.commit_edit(goalrules.edit_target(self.doc.base(), percent))
        except IsochorError as exc:
            self.panel.show_target(self.state.goal.target_ratio * 100)
            self.error("Cannot set the target volume", str(exc))

    def rebuild_lattice(self, shape) -> None:
        """A new lattice of ``shape`` nodes (one undo step; a big model's is computed on a
        thread and committed when ready: :mod:`isochor.app.window.rebuild`)."""
        try:
            self.lattice_rebuild.start(shape, self.panel.basis_name(), self.panel.outside())
        except IsochorError as exc:
            self.error("Cannot rebuild the lattice", str(exc))

    def solve_again(self) -> None:
        if not self.session.solve_again():
            self.statusBar().showMessage("Turn on “Preserve volume” to solve.", 4000)

    # -- display -------------------------------------------------------------------------------
    def display_changed(self, _=None) -> None:
        scene, acts = self.viewport.scene, self.action_set
        if scene.built:
            scene.set_lattice_visible(acts.lattice.isChecked(), acts.diag.isChecked())
            scene.set_ghost(acts.ghost.isChecked())
            if scene.smooth != acts.smooth.isChecked():
                scene.set_smooth(acts.smooth.isChecked())
            scene.set_caps(acts.caps.isChecked())
            self.viewport.show_gizmo()
        self.viewport.update()

    def context_menu(self, row: int) -> QMenu:
        """The right-click menu for node ``row`` (-1: empty space): pins and selection."""
        if row >= 0 and row not in self.doc.selection.rows:
            self.doc.selection.select([row])
        menu = QMenu(self)
        rows = self.doc.selection.rows.copy()
        if len(rows):
            fixed = bool(self.state.fixed[rows].all())
            what = plural(len(rows))
            menu.addAction(
                f"Unpin {what}" if fixed else f"Pin {what}", lambda: self.set_pins(rows, not fixed)
            )
            for a in self.action_set.pin_axes:
                menu.addAction(a)
            menu.addSeparator()
        acts = self.action_set
        common: tuple[QAction | None, ...] = (
            acts.pin_all,
            acts.unpin_all,
            None,
            acts.select_all,
            acts.frame,
        )
        for entry in common:
            menu.addSeparator() if entry is None else menu.addAction(entry)
        return menu

    def exec_menu(self, menu: QMenu, pos: QPoint) -> None:
        menu.exec(pos)

    # -- messages ------------------------------------------------------------------------------
    def set_headless_errors(self, on: bool = True) -> None:
        """Errors go to stderr instead of dialogs (on): nobody is there to close them."""
        self.headless_errors = bool(on)

    def error(self, title: str, message: str) -> None:
        if self.headless_errors:
            print(f"isochor: {message}", file=sys.stderr)
            return
        QMessageBox.critical(self, title, message)

    def show_controls(self) -> None:
        QMessageBox.information(self, "Controls", CONTROLS_HTML)

    def show_about(self) -> None:
        from ... import __version__

        QMessageBox.about(
            self,
            "About Isochor",
            f"<b>Isochor</b> {__version__}<br>Volume-preserving free-form "
            "deformation after Hirota, Maheshwari and Lin (1999).",
        )

    # -- closing -------------------------------------------------------------------------------
    def closeEvent(self, ev) -> None:
        if not self.files.confirm_discard():
            ev.ignore()
            return
        self.autosave.discard()  # a clean quit: nothing to recover
        self.layout_memory.save()
        self.shutdown()
        super().closeEvent(ev)

    def shutdown(self) -> None:
        """Stop the session (waits at most 0.1 s for the solver), release VTK.
        Safe to call more than once."""
        if self.closed:
            return
        self.closed = True
        self.autosave.stop()
        # nothing may reach this window once it is going away
        self.session.undo_stack.cleanChanged.disconnect(self.update_title)
        self.timeline.shutdown()
        self.lattice_rebuild.cancel()  # (its thread is not waited for)
        self.session.shutdown()
        self.viewport.close()
