"""Isochor's desktop editor and command line: PySide6 + pyvistaqt, imported only here.

Arrows point down this list, never up (``tests/test_structure.py``)::

    cli/       ``isochor``: the editor, ``solve``, ``examples``; exit statuses, signals
    window/    the window shell: docks, panels, actions, file commands, loading
    session/   the editing session (QObjects, no widgets): undo stack, solve worker, frames
    view/      the 3D view: camera, actors, overlays, picking, gestures (VTK)
    editor/    the Qt-free editor model: document, states, edit rules, drags, timeline
    isochor.core

``session`` and ``view`` do not import each other; the window joins them. Each
subpackage's ``__init__`` docstring is its map.
"""
