"""Isochor's desktop editor: PySide6 + pyvistaqt. The only package that imports them.

- :mod:`app.window`     ``run_editor``: the display check, the Qt application, screenshot mode
- :mod:`app.mainwindow` the main window: menus, toolbar, docks, status bar, solve scheduling
- :mod:`app.viewport`   the 3D view: actors, node picking, dragging, box selection
- :mod:`app.document`   the editable state (Qt-free): model, lattice, node positions and flags
- :mod:`app.worker`     the solver worker: the core generator on a background thread
- :mod:`app.undo`       undo commands: one per completed edit, never per solver step
- :mod:`app.panel`      the side panel (selection, pins, solve options, lattice, display)
- :mod:`app.plot`       the live convergence plot (QPainter, log scale)
- :mod:`app.style`      colours and the application look
"""
