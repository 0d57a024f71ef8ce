"""The window's actions, menus and toolbar.

Every command the user can give is one ``QAction`` on the window (so its shortcut works while
the menus are closed); menus, the toolbar, the context menu and the panel's buttons share
them. :class:`ActionSet` holds them all, for a
:class:`~isochor.app.window.mainwindow.MainWindow` whose parts (the session, the view, the
file commands, the node, handle and timeline tools) their slots call; it builds the menus
(:meth:`ActionSet.build_menus`) and the toolbar (:meth:`ActionSet.build_toolbar`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QDockWidget, QMainWindow, QMenu, QMenuBar, QToolBar

from ...core.scenario.examples import EXAMPLES
from ..editor import goalrules, noderules
from ..editor.transform import VERBS
from .goalbox import ANCHOR_TIP, CENTROID_TIP, FOLD_TIP, VOLUME_TIP
from .handlebox import TOOL_TIP

#: (name, shortcut) of the standard views
VIEWS = (
    ("home", "Home"),
    ("front", "1"),
    ("back", "Ctrl+1"),
    ("right", "3"),
    ("left", "Ctrl+3"),
    ("top", "7"),
    ("bottom", "Ctrl+7"),
)

K = QKeySequence


class ActionSet:
    """The actions of one window, by name: ``win.action_set.save``,
    ``win.action_set.pin_axes[0]`` (not ``win.actions``: that is QWidget's list).

    Every action is added to the window (its shortcut works while the menus are closed);
    the timeline's arrow and Space keys only in the view and on the scrubber, where other
    widgets do not want them.
    """

    def __init__(self, win) -> None:
        self.window: QMainWindow = win
        s, vp, files = win.session, win.viewport, win.files
        A = self._new  # noqa: N806
        # -- File
        self.open = A(
            "&Open…",
            files.open_dialog,
            K.StandardKey.Open,
            tip="Open a model (OBJ, PLY, STL, OFF) or a scenario (.json)",
        )
        self.save = A("&Save Scenario", files.save, K.StandardKey.Save)
        self.save_as = A("Save Scenario &As…", files.save_as, K("Ctrl+Shift+S"))
        self.export = A(
            "&Export Deformed Mesh…",
            files.export_dialog,
            K("Ctrl+E"),
            tip="Write the deformed full-resolution mesh (OBJ, PLY, STL)",
        )
        self.quit = A("&Quit", win.close, K.StandardKey.Quit)
        # -- Edit
        self.undo = s.undo_stack.createUndoAction(win, "&Undo")
        self.undo.setShortcuts([K("Ctrl+Z")])
        self.redo = s.undo_stack.createRedoAction(win, "&Redo")
        self.redo.setShortcuts([K("Ctrl+Shift+Z"), K("Ctrl+Y")])
        win.addAction(self.undo)
        win.addAction(self.redo)
        self.select_all = A("Select &All Nodes", lambda: win.doc.selection.all(), K("Ctrl+A"))
        self.pin = A(
            "Toggle &Pin",
            win.toggle_pin,
            K("P"),
            tip="Pin the selected nodes, or unpin them if all are fixed",
        )
        self.pin_all = A("Pin All", lambda: win.set_pins(None, True))
        self.unpin_all = A("Unpin All", lambda: win.set_pins(None, False))
        self.reset = A(
            "Reset Nodes",
            lambda: s.commit(noderules.edit_reset(win.doc.base())),
            tip="Every node back to rest, no pins",
        )
        self.box = A(
            "&Box Select",
            vp.set_box_mode,
            K("B"),
            checkable=True,
            tip="Drag a box to select nodes (Shift-drag does it any time)",
        )
        self.preserve = A(
            "Preserve &Volume",
            s.set_preserve,
            K("V"),
            checkable=True,
            checked=True,
            tip="Off: plain FFD, the nodes stay where you put them",
        )
        self.live = A(
            "&Live Solve",
            s.set_live,
            K("L"),
            checkable=True,
            tip="Solve continuously while a node is dragged",
        )
        self.pin_axes = [
            A(
                f"Pin on {axis.upper()} Only",
                lambda _=False, a=axis: win.pin_on(a),
                tip=f"Pin the selected nodes on {axis} only: the solver keeps their {axis} "
                "and moves them on the other axes",
            )
            for axis in "xyz"
        ]
        self._goal_actions(win)
        self.solve = A("&Solve Again", win.solve_again, K("Ctrl+R"))
        self.stop = A("S&top Solve", s.stop_solve, K("Ctrl+."))
        self.frame = A(
            "&Frame Selection",
            vp.camera_control.frame_selection,
            K("F"),
            tip="Fit the selected nodes in the view (the whole model when nothing is selected)",
        )
        self._node_tools(win)
        self.ortho = A(
            "&Orthographic",
            vp.camera_control.set_orthographic,
            K("5"),
            checkable=True,
            tip="Parallel projection (on) or perspective (off)",
        )
        self.handle_tool = A(
            "&Handle Tool",
            vp.handle_tool.set_active,
            K("H"),
            checkable=True,
            tip=TOOL_TIP,
        )
        self.remove_handle = A(
            "&Remove Handle",
            win.handle_tools.remove_handle,
            [K("Delete"), K("Backspace")],
            tip="Remove the selected surface handle",
        )
        self._timeline_actions(win)
        self.views = {
            name: A(
                f"{name.title()} View",
                lambda _=False, n=name: vp.camera_control.standard_view(n),
                K(key),
            )
            for name, key in VIEWS
        }
        self.lattice = A("Show &Lattice", win.display_changed, checkable=True, checked=True)
        self.diag = A("Show Diagonal Springs", win.display_changed, checkable=True)
        self.ghost = A("Show &Ghost of the Original", win.display_changed, checkable=True)
        self.smooth = A("&Smooth Shading", win.display_changed, checkable=True, checked=True)
        self.caps = A(
            "Show &Caps over Holes",
            win.display_changed,
            checkable=True,
            tip="Show the caps Isochor adds over an open model's holes: the volume kept "
            "is the volume inside them (they are never written to a file)",
        )
        # -- Help
        self.help = A("&Controls", win.show_controls, K("F1"))
        self.about = A("&About Isochor", win.show_about)

    def _new(
        self,
        text: str,
        slot: Callable | None = None,
        shortcut=None,
        checkable: bool = False,
        checked: bool = False,
        tip: str | None = None,
    ) -> QAction:
        """An action on the window: ``slot`` gets its trigger (or its toggle, checkable)."""
        win = self.window
        a = QAction(text, win)
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
        win.addAction(a)  # shortcuts work while the menus are closed
        return a

    def _node_tools(self, win) -> None:
        """Grab, rotate, scale; the selection helpers (:mod:`isochor.app.window.tools`)."""
        A = self._new  # noqa: N806
        tools, vp = win.node_tools, win.viewport
        self.transform = {
            mode: A(
                f"{VERBS[mode] if mode != 'grab' else 'Grab'}",
                lambda _=False, m=mode: tools.start_transform(m),
                K(key),
                tip=f"{tip} the selected nodes about their centre with the mouse; X/Y/Z lock "
                "an axis, type a value, Enter confirms, Esc cancels",
            )
            for mode, key, tip in (
                ("grab", "G", "Move"),
                ("rotate", "R", "Rotate"),
                ("scale", "S", "Scale"),
            )
        }
        self.select_layer = [
            A(
                f"Layer Across {a.upper()}",
                lambda _=False, i=i: tools.select_layer(i),
                tip=f"Select every node with the same {'ijk'[i]} as a selected node",
            )
            for i, a in enumerate("xyz")
        ]
        self.select_line = [
            A(
                f"Row Along {a.upper()}",
                lambda _=False, i=i: tools.select_line(i),
                tip=f"Select the lattice rows along {a} through the selected nodes",
            )
            for i, a in enumerate("xyz")
        ]
        self.select_face = A(
            "Face of the Lattice",
            tools.select_face,
            tip="Select the lattice face that holds the selected nodes",
        )
        self.invert = A("&Invert Selection", lambda: win.doc.selection.inverse(), K("Ctrl+I"))
        self.visible_only = A(
            "Select &Visible Only",
            vp.set_visible_only,
            checkable=True,
            tip="Box selection skips the nodes the model hides from the camera",
        )

    def _goal_actions(self, win) -> None:
        """The goal's settings as checkable actions: a user's trigger commits one undoable
        edit (the readout keeps their check marks in step with the state)."""
        doc = lambda: win.doc  # noqa: E731 (the window's document changes when a file opens)

        def goal(text: str, tip: str, checked: bool, rule) -> QAction:
            a = self._new(text, checkable=True, checked=checked, tip=tip)
            a.triggered.connect(lambda on, rule=rule: win.commit_edit(rule(on)))
            return a

        self.anchor = goal(
            "&Hold Far Side", ANCHOR_TIP, True, lambda on: goalrules.edit_anchor(doc().base(), on)
        )
        self.centroid = goal(
            "&Keep Centre of Mass",
            CENTROID_TIP,
            False,
            lambda on: goalrules.edit_keep_centroid(doc().base(), on),
        )
        self.per_body = goal(
            "Preserve &Each Body",
            VOLUME_TIP,
            False,
            lambda on: goalrules.edit_preserve(doc().base(), "per-body" if on else "total"),
        )
        self.fold_guard = goal(
            "&Fold Guard", FOLD_TIP, True, lambda on: goalrules.edit_fold_guard(doc().base(), on)
        )

    def _timeline_actions(self, win) -> None:
        """Keys, the playhead and playing (:mod:`isochor.app.window.timelinetools`)."""
        tool, vp = win.timeline, win.viewport
        self.set_key = self._new(
            "Set &Key", tool.set_key, K("I"), tip="Key the working pose at the current frame"
        )
        self.remove_key = self._new(
            "&Remove Key", tool.remove_key, K("Alt+I"), tip="Remove the key at the current frame"
        )

        def local(text: str, slot: Callable, key: str) -> QAction:
            """An action whose keys other widgets use too (arrows, Space): only in the view
            and on the scrubber."""
            a = self._new(text, slot)
            a.setShortcut(K(key))
            a.setShortcutContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
            win.removeAction(a)
            vp.addAction(a)
            tool.panel.scrubber.addAction(a)
            return a

        self.prev_key = local("&Previous Key", lambda: tool.jump_key(-1), "Down")
        self.next_key = local("&Next Key", lambda: tool.jump_key(+1), "Up")
        self.prev_frame = local("Previous &Frame", lambda: tool.step(-1), "Left")
        self.next_frame = local("Next F&rame", lambda: tool.step(+1), "Right")
        self.first = local("&Start of the Range", lambda: tool.go_to_end(-1), "Shift+Left")
        self.last = local("&End of the Range", lambda: tool.go_to_end(+1), "Shift+Right")
        self.play = local("&Play / Pause", tool.toggle_play, "Space")
        self.play.setToolTip("Play the solved frames at the frame rate, looping (Space)")
        tool.panel.use_actions(
            {
                "first": self.first,
                "prev_key": self.prev_key,
                "play": self.play,
                "next_key": self.next_key,
                "last": self.last,
                "set_key": self.set_key,
                "remove_key": self.remove_key,
            }
        )

    # -- menus and toolbar ------------------------------------------------------------------------
    def build_menus(self, mb: QMenuBar, files, docks: list[QDockWidget]) -> None:
        """The menu bar: File, Edit, Solve, View (with ``docks``' toggles), Timeline, Help;
        ``files``: the window's file commands (the examples open with them)."""
        from ... import assets

        def opens(path: Path) -> Callable[..., object]:
            return lambda _=False: files.open_example(path)

        m = mb.addMenu("&File")
        m.addAction(self.open)
        ex = m.addMenu("Open &Example")
        paths = assets.example_files()
        for name, text in EXAMPLES.items():
            ex.addAction(text, opens(paths[name]))
        ex.addSeparator()
        for name, path in assets.model_files().items():
            ex.addAction(f"The {name} as a mesh file ({path.name})", opens(path))
        m.addSeparator()
        for a in (self.save, self.save_as, self.export):
            m.addAction(a)
        m.addSeparator()
        m.addAction(self.quit)
        m = mb.addMenu("&Edit")
        edit: tuple[QAction | str | None, ...] = (
            self.undo,
            self.redo,
            None,
            self.select_all,
            self.box,
            None,
            "tools",
            None,
            self.pin,
            *self.pin_axes,
            self.pin_all,
            self.unpin_all,
            self.reset,
        )
        for entry in edit:
            if isinstance(entry, str):  # "tools"
                self._tool_menus(m)
                m.addAction(self.handle_tool)
                m.addAction(self.remove_handle)
            else:
                _add(m, entry)
        m = mb.addMenu("&Solve")
        solve: tuple[QAction | None, ...] = (
            self.preserve,
            self.live,
            self.solve,
            self.stop,
            None,
            self.anchor,
            self.centroid,
            self.per_body,
            self.fold_guard,
        )
        for entry in solve:
            _add(m, entry)
        m = mb.addMenu("&View")
        m.addAction(self.frame)
        m.addAction(self.ortho)
        for a in self.views.values():
            m.addAction(a)
        m.addSeparator()
        for a in (self.lattice, self.diag, self.ghost, self.smooth, self.caps):
            m.addAction(a)
        m.addSeparator()
        for dock in docks:
            m.addAction(dock.toggleViewAction())
        m = mb.addMenu("&Timeline")
        timeline: tuple[QAction | None, ...] = (
            self.set_key,
            self.remove_key,
            None,
            self.play,
            self.prev_key,
            self.next_key,
            self.prev_frame,
            self.next_frame,
            self.first,
            self.last,
        )
        for entry in timeline:
            _add(m, entry)
        m = mb.addMenu("&Help")
        m.addAction(self.help)
        m.addAction(self.about)

    def _tool_menus(self, menu: QMenu) -> None:
        """The Transform and Select submenus."""
        m = menu.addMenu("&Transform")
        for a in self.transform.values():
            m.addAction(a)
        m = menu.addMenu("Se&lect")
        select: tuple[QAction | None, ...] = (
            *self.select_layer,
            None,
            *self.select_line,
            None,
            self.select_face,
        )
        for entry in select:
            _add(m, entry)
        m.addSeparator()
        m.addAction(self.invert)
        m.addAction(self.visible_only)

    def build_toolbar(self) -> QToolBar:
        """The window's toolbar (text buttons)."""
        win = self.window
        tb = QToolBar("Main", win)
        tb.setObjectName("main-toolbar")
        tb.setMovable(False)
        tb.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        # in the menu bar's row, as Blender's header: the view keeps the height (the file
        # commands and the standard views are in the menus, with their keys)
        win.menuBar().setCornerWidget(tb, Qt.Corner.TopRightCorner)
        for action, text in (
            (self.open, "Open"),
            (self.save, "Save"),
            (self.export, "Export"),
            (self.undo, "Undo"),
            (self.redo, "Redo"),
            (self.box, "Box select"),
            (self.pin, "Pin"),
            (self.handle_tool, "Handle"),
            (self.preserve, "Preserve volume"),
            (self.live, "Live"),
            (self.frame, "Frame"),
        ):
            action.setIconText(text)
        buttons: tuple[QAction | None, ...] = (
            self.undo,
            self.redo,
            None,
            self.box,
            self.pin,
            self.handle_tool,
            None,
            self.preserve,
            self.live,
            None,
            self.frame,
        )
        for entry in buttons:
            _add(tb, entry)
        return tb


def _add(menu: QMenu | QToolBar, action: QAction | None) -> None:
    """Add ``action`` to a menu or toolbar (None: a separator)."""
    if action is None:
        menu.addSeparator()
    else:
        menu.addAction(action)
