"""The 3D view (pyvista / VTK), GUI thread only.

- :mod:`.viewport`      Viewport: the pyvistaqt widget; its Qt events dispatch to its parts
- :mod:`.camera`        CameraControl: standard views, framing, orthographic, what is under
  a point of the widget (the projection of world points to it)
- :mod:`.nodedrag`      NodeDragger: the running drag of nodes or a handle's target, locks
- :mod:`.transformtool` TransformTool: the G/R/S gestures on the selection
- :mod:`.handletool`    HandleTool: placing, selecting and dragging surface handles
- :mod:`.modeldraw`     ModelFrames: a proxy while the model moves, the full mesh when it stops
- :mod:`.modelview`     the model as drawn: full mesh or proxy level, their actors
- :mod:`.composer`      Composer: a big model's full-mesh frame drawn in passes, one per
  event-loop turn, and shown whole
- :mod:`.meshprep`      what drawing a model needs, numpy only (draw order, shading, closed
  or not): computed off the GUI thread when a model opens or its lattice is rebuilt
- :mod:`.scene`         the actors: the model, its ghost, the lattice, the selection
- :mod:`.overlays`      drawn over the scene: the translate gizmo, handle markers
- :mod:`.glyphs`        node shapes by role, sizes by lattice density
- :mod:`.gestures`      typed records of what a mouse press started
- :mod:`.picking`       projection and picking maths (numpy only, tested headless)
- :mod:`.style`         colours and the application look
"""
