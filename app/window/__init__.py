"""The window shell: widgets, docks, actions and what joins the session to the view.

- :mod:`.mainwindow`    MainWindow: docks, status bar, session signals to widgets
- :mod:`.actions`       the actions, menus and toolbar
- :mod:`.files`         open, save, export, the unsaved-changes prompt
- :mod:`.loading`       big models opened in the background, with progress and Cancel
- :mod:`.framedraw`     the window's frames: what the session hands out, drawn
- :mod:`.tools`         the node tools' wiring: G/R/S, selection helpers, framing
- :mod:`.handletools`   the Handle tool, handle gestures and symmetry wired to the session
- :mod:`.timelinetools` the Timeline dock's wiring: keys, scrubbing, playing
- :mod:`.panel`         the Inspector: selection, pins, solve options, lattice, display;
  :mod:`.goalbox` its Constraints group, :mod:`.handlebox` its Handles group
- :mod:`.timelinebar`   the Timeline dock's widgets: scrubber and panel
- :mod:`.readout`       the status bar, the notes and the marks on the view
- :mod:`.plot`          the live convergence plot (QPainter, log scale)
"""
