"""The 3D view (pyvista / VTK), GUI thread only.

- :mod:`.viewport`   Viewport: the pyvistaqt widget and the mouse and key gestures on nodes
- :mod:`.camera`     standard views, framing, projection of world points to the widget
- :mod:`.viewtools`  the view's G/R/S, gizmo, framing, orthographic, visible-only box select
- :mod:`.handleview` placing, selecting and dragging surface handles in the view
- :mod:`.modeldraw`  the model's frames: a proxy while it moves, the full mesh when it stops
- :mod:`.modelview`  the model as drawn: full mesh or proxy level, shading, draw order
- :mod:`.scene`      the actors: the model, its ghost, the lattice, the selection
- :mod:`.overlays`   drawn over the scene: the translate gizmo, handle markers
- :mod:`.glyphs`     node shapes by role, sizes by lattice density
- :mod:`.gestures`   typed records of what a mouse press started
- :mod:`.picking`    projection and picking maths (numpy only, tested headless)
- :mod:`.style`      colours and the application look
"""
