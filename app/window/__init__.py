"""The window shell: widgets, docks, actions and what joins the session to the view.

- :mod:`.mainwindow`    MainWindow: docks, status bar, session signals to widgets; it holds
  the parts below as fields
- :mod:`.actions`       ActionSet: every action by name, the menus and the toolbar
- :mod:`.files`         FileCommands: open, save, export, the unsaved-changes prompt
- :mod:`.autosave`      AutoSave: the recovery file while changes are unsaved, the offer to
  recover at start
- :mod:`.layout`        LayoutMemory: the docks and the window's geometry kept between runs
- :mod:`.loading`       big models opened in the background, with progress and Cancel
- :mod:`.rebuild`       LatticeRebuild: a big model's lattice rebuilt on a thread
- :mod:`.framedraw`     FrameDrawer: the window's frames, what the session hands out, drawn
- :mod:`.tools`         NodeTools: G/R/S wired to the session, the selection helpers
- :mod:`.handletools`   HandleTools: handle gestures and symmetry wired to the session
- :mod:`.timelinetools` TimelineTool: the Timeline dock's panel, keys, scrubbing, playing
- :mod:`.panel`         the Inspector: selection, pins, solve options, lattice, display;
  :mod:`.goalbox` its Constraints group, :mod:`.handlebox` its Handles group
- :mod:`.timelinebar`   the Timeline dock's widgets: scrubber and panel
- :mod:`.readout`       Readout: the status bar's labels, the notes and the marks on the view
- :mod:`.plot`          the live convergence plot (QPainter, log scale)
"""
