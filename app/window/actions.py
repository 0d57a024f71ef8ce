"""The window's actions, menus and toolbar.

Every command the user can give is one ``QAction`` on the window (so its shortcut works while
the menus are closed); menus, the toolbar, the context menu and the panel's buttons share
them. Built once by :func:`build` for a :class:`~isochor.app.window.mainwindow.MainWindow`.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QToolBar

from ...core.scenario.examples import EXAMPLES
from ..editor import goalrules, noderules
from . import handletools, timelinetools, tools

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


def _action(
    win, text, slot=None, shortcut=None, checkable=False, checked=False, tip=None
) -> QAction:
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


def build(win) -> None:
    """Create the actions as ``win.act_*``, then the menus and the toolbar."""
    _build_actions(win)
    _build_menus(win)
    _build_toolbar(win)


def _build_actions(win) -> None:
    def A(*args, **kwargs):
        return _action(win, *args, **kwargs)

    K = QKeySequence  # noqa: N806
    s, vp = win.session, win.viewport
    win.act_open = A(
        "&Open…",
        win.files.open_dialog,
        K.StandardKey.Open,
        tip="Open a model (OBJ, PLY, STL, OFF) or a scenario (.json)",
    )
    win.act_save = A("&Save Scenario", win.files.save, K.StandardKey.Save)
    win.act_save_as = A("Save Scenario &As…", win.files.save_as, K("Ctrl+Shift+S"))
    win.act_export = A(
        "&Export Deformed Mesh…",
        win.files.export_dialog,
        K("Ctrl+E"),
        tip="Write the deformed full-resolution mesh (OBJ, PLY, STL)",
    )
    win.act_quit = A("&Quit", win.close, K.StandardKey.Quit)
    win.act_undo = s.undo_stack.createUndoAction(win, "&Undo")
    win.act_undo.setShortcuts([K("Ctrl+Z")])
    win.act_redo = s.undo_stack.createRedoAction(win, "&Redo")
    win.act_redo.setShortcuts([K("Ctrl+Shift+Z"), K("Ctrl+Y")])
    win.addAction(win.act_undo)
    win.addAction(win.act_redo)
    win.act_select_all = A("Select &All Nodes", lambda: win.doc.selection.all(), K("Ctrl+A"))
    win.act_pin = A(
        "Toggle &Pin",
        win.toggle_pin,
        K("P"),
        tip="Pin the selected nodes, or unpin them if all are fixed",
    )
    win.act_pin_all = A("Pin All", lambda: win.set_pins(None, True))
    win.act_unpin_all = A("Unpin All", lambda: win.set_pins(None, False))
    win.act_reset = A(
        "Reset Nodes",
        lambda: s.commit(noderules.edit_reset(win.doc.base())),
        tip="Every node back to rest, no pins",
    )
    win.act_box = A(
        "&Box Select",
        lambda on: setattr(vp, "box_mode", bool(on)),
        K("B"),
        checkable=True,
        tip="Drag a box to select nodes (Shift-drag does it any time)",
    )
    win.act_preserve = A(
        "Preserve &Volume",
        s.set_preserve,
        K("V"),
        checkable=True,
        checked=True,
        tip="Off: plain FFD, the nodes stay where you put them",
    )
    win.act_live = A(
        "&Live Solve",
        lambda on: setattr(s, "live", bool(on)),
        K("L"),
        checkable=True,
        tip="Solve continuously while a node is dragged",
    )
    win.act_pin_axes = [
        A(
            f"Pin on {axis.upper()} Only",
            lambda _=False, a=axis: win.pin_on(a),
            tip=f"Pin the selected nodes on {axis} only: the solver keeps their {axis} "
            "and moves them on the other axes",
        )
        for axis in "xyz"
    ]
    _goal_actions(win)
    win.act_solve = A("&Solve Again", win.solve_again, K("Ctrl+R"))
    win.act_stop = A("S&top Solve", s.stop_solve, K("Ctrl+."))
    win.act_frame = A(
        "&Frame Selection",
        vp.frame_selection,
        K("F"),
        tip="Fit the selected nodes in the view (the whole model when nothing is selected)",
    )
    tools.build(win, A)
    handletools.build(win, A)
    timelinetools.build(win, A)
    win.act_views = {
        name: A(f"{name.title()} View", lambda _=False, n=name: vp.standard_view(n), K(key))
        for name, key in VIEWS
    }
    win.act_lattice = A("Show &Lattice", win.display_changed, checkable=True, checked=True)
    win.act_diag = A("Show Diagonal Springs", win.display_changed, checkable=True)
    win.act_ghost = A("Show &Ghost of the Original", win.display_changed, checkable=True)
    win.act_smooth = A("&Smooth Shading", win.display_changed, checkable=True, checked=True)
    win.act_help = A("&Controls", win.show_controls, K("F1"))
    win.act_about = A("&About Isochor", win.show_about)


def _goal_actions(win) -> None:
    """The goal's settings as checkable actions: a user's trigger commits one undoable edit
    (the window keeps their check marks in step with the state)."""
    from .goalbox import ANCHOR_TIP, CENTROID_TIP, FOLD_TIP, VOLUME_TIP

    doc = lambda: win.doc  # noqa: E731 (the window's document changes when a file opens)
    rules = {
        "anchor": (
            "&Hold Far Side",
            ANCHOR_TIP,
            True,
            lambda on: goalrules.edit_anchor(doc().base(), on),
        ),
        "centroid": (
            "&Keep Centre of Mass",
            CENTROID_TIP,
            False,
            lambda on: goalrules.edit_keep_centroid(doc().base(), on),
        ),
        "per_body": (
            "Preserve &Each Body",
            VOLUME_TIP,
            False,
            lambda on: goalrules.edit_preserve(doc().base(), "per-body" if on else "total"),
        ),
        "fold_guard": (
            "&Fold Guard",
            FOLD_TIP,
            True,
            lambda on: goalrules.edit_fold_guard(doc().base(), on),
        ),
    }
    for name, (text, tip, checked, rule) in rules.items():
        a = _action(win, text, checkable=True, checked=checked, tip=tip)
        a.triggered.connect(lambda on, rule=rule: win.commit_edit(rule(on)))
        setattr(win, f"act_{name}", a)


def _build_menus(win) -> None:
    from ... import assets

    mb = win.menuBar()
    m = mb.addMenu("&File")
    m.addAction(win.act_open)
    ex = m.addMenu("Open &Example")
    files = assets.example_files()
    for name, text in EXAMPLES.items():
        ex.addAction(text, lambda _=False, p=files[name]: win.files.open_example(p))
    ex.addSeparator()
    for name, path in assets.model_files().items():
        ex.addAction(
            f"The {name} as a mesh file ({path.name})",
            lambda _=False, p=path: win.files.open_example(p),
        )
    m.addSeparator()
    for a in (win.act_save, win.act_save_as, win.act_export):
        m.addAction(a)
    m.addSeparator()
    m.addAction(win.act_quit)
    m = mb.addMenu("&Edit")
    for a in (
        win.act_undo,
        win.act_redo,
        None,
        win.act_select_all,
        win.act_box,
        None,
        "tools",
        None,
        win.act_pin,
        *win.act_pin_axes,
        win.act_pin_all,
        win.act_unpin_all,
        win.act_reset,
    ):
        if a == "tools":
            tools.add_to_edit_menu(win, m)
            m.addAction(win.act_handle_tool)
            m.addAction(win.act_remove_handle)
        else:
            m.addSeparator() if a is None else m.addAction(a)
    m = mb.addMenu("&Solve")
    for a in (
        win.act_preserve,
        win.act_live,
        win.act_solve,
        win.act_stop,
        None,
        win.act_anchor,
        win.act_centroid,
        win.act_per_body,
        win.act_fold_guard,
    ):
        m.addSeparator() if a is None else m.addAction(a)
    m = mb.addMenu("&View")
    m.addAction(win.act_frame)
    m.addAction(win.act_ortho)
    for a in win.act_views.values():
        m.addAction(a)
    m.addSeparator()
    for a in (win.act_lattice, win.act_diag, win.act_ghost, win.act_smooth):
        m.addAction(a)
    m.addSeparator()
    m.addAction(win.inspector_dock.toggleViewAction())
    m.addAction(win.plot_dock.toggleViewAction())
    m.addAction(win.timeline_dock.toggleViewAction())
    timelinetools.add_menu(win, mb)
    m = mb.addMenu("&Help")
    m.addAction(win.act_help)
    m.addAction(win.act_about)


def _build_toolbar(win) -> None:
    tb = QToolBar("Main", win)
    tb.setObjectName("main-toolbar")
    tb.setMovable(False)
    tb.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
    win.addToolBar(tb)
    for action, text in (
        (win.act_open, "Open"),
        (win.act_save, "Save"),
        (win.act_export, "Export"),
        (win.act_undo, "Undo"),
        (win.act_redo, "Redo"),
        (win.act_box, "Box select"),
        (win.act_pin, "Pin"),
        (win.act_handle_tool, "Handle"),
        (win.act_preserve, "Preserve volume"),
        (win.act_live, "Live"),
        (win.act_frame, "Frame"),
    ):
        action.setIconText(text)
    for a in (
        win.act_open,
        win.act_save,
        win.act_export,
        None,
        win.act_undo,
        win.act_redo,
        None,
        win.act_box,
        win.act_pin,
        win.act_handle_tool,
        None,
        win.act_preserve,
        win.act_live,
        None,
        win.act_frame,
    ):
        tb.addSeparator() if a is None else tb.addAction(a)
    for name in ("home", "front", "right", "top"):
        a = win.act_views[name]
        a.setIconText(name.title())
        tb.addAction(a)
