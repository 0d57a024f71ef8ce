"""Isochor's desktop editor and command line: PySide6 + pyvistaqt, imported only here.

Arrows point down: ``launch -> mainwindow -> (actions, files, controller, viewport, panel,
goalbox, plot, readout) -> (document, goalrules, state, picking, scene, worker, commands) ->
isochor.core``.

- :mod:`.cli`         ``isochor``: the editor, ``solve``, ``examples`` (Qt only for the editor)
- :mod:`.launch`      ``run_editor``: the display check, the Qt application, screenshot mode
- :mod:`.mainwindow`  the window shell: docks, status bar, session signals to widgets
- :mod:`.actions`     the actions, menus and toolbar
- :mod:`.files`       open, save, export, the unsaved-changes prompt
- :mod:`.loading`     big models opened in the background, with progress and Cancel;
  :mod:`.reader` reads them and builds the pyramid in a child process
- :mod:`.controller`  the editing session (a QObject, no widgets): document, undo stack,
  solver worker; :mod:`.sessiondrag` its drags and live previews, :mod:`.framedraw` the
  frame scheduling
- :mod:`.document`    the editor model (Qt-free): edit rules, selection, drag session, files
- :mod:`.goalrules`   the goal's edit rules (Qt-free): hold far side, centre of mass, each
  body, fold guard, pins on some axes, what the far-side anchor holds
- :mod:`.state`       the editable states, solve summaries and their words (Qt-free)
- :mod:`.commands`    undo commands acting on the document
- :mod:`.worker`      the solve generator on a background thread; records reach the GUI by
  queued signals
- :mod:`.viewport`    the 3D view: camera, overlays, mouse and key gestures
- :mod:`.scene`       the view's actors, updated in place per frame; :mod:`.modelview` and
  :mod:`.modeldraw` draw a proxy level while the model moves, the full mesh when it stops
- :mod:`.picking`     projection and picking maths (numpy only)
- :mod:`.panel`       the Inspector: selection, pins, solve options, lattice, display
- :mod:`.goalbox`     the Inspector's Constraints group and the last solve's notes
- :mod:`.readout`     the status bar, the notes and the marks on the view (roles, held, folds)
- :mod:`.plot`        the live convergence plot (QPainter, log scale)
- :mod:`.style`       colours and the application look
"""
