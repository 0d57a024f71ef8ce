"""The editor model, Qt-free: what the user edits and the rules of every edit.

Tested headless (``tests/test_document.py``, ``tests/test_tool_rules.py``,
``tests/test_timeline_rules.py``); a test keeps Qt out of it.

- :mod:`.document`      the document: the current state cell, the selection, the drag, events
- :mod:`.state`         DocState (one editable state), SolveSummary, StateCell, their words
- :mod:`.goalrules`     the goal's edit rules: far side, centre of mass, bodies, fold guard,
  pins on some axes; :class:`~.goalrules.Edit`, what every rule returns
- :mod:`.handlerules`   surface handles: place, select, move, remove; a handle's drag
- :mod:`.selection`     a lattice layer, row or face of the selection; invert
- :mod:`.drag`          the drag session: a mouse drag, a gizmo arrow, G/R/S, mirrored
- :mod:`.transform`     grab / rotate / scale with axis locks and typed values
- :mod:`.timeline`      the timeline's keys and settings, the frame cache, what a frame shows
- :mod:`.timelinerules` keys, range, rate and interpolation as edits
"""
