"""The editor model, Qt-free: what the user edits and the rules of every edit.

Tested headless (``tests/test_document.py``, ``tests/test_tool_rules.py``,
``tests/test_timeline_rules.py``); a test keeps Qt out of it.

- :mod:`.document`      the document: the current state cell, its parts (the selection, the
  drag), the edit base it hands out, events, files
- :mod:`.state`         DocState (one editable state), SolveSummary, StateCell, their words
- :mod:`.edit`          EditBase, what every edit rule starts from; Edit, what it returns
- :mod:`.noderules`     the nodes' edit rules: type a position, pin and unpin, reset
- :mod:`.goalrules`     the goal's edit rules: far side, centre of mass, bodies, fold guard,
  symmetry, target volume, pins on some axes; what the far-side anchor holds
- :mod:`.handlerules`   surface handles: where they are, place, move, remove; a handle's drag
- :mod:`.latticerules`  a new lattice around the same model
- :mod:`.problems`      the problems built for one model, one per lattice
- :mod:`.selection`     the selection part (node rows, the handle); a lattice layer, row or
  face of the selection; invert
- :mod:`.drag`          the drag session: a mouse drag, a gizmo arrow, G/R/S, mirrored
- :mod:`.transform`     grab / rotate / scale with axis locks and typed values
- :mod:`.timeline`      the timeline's keys and settings, the frame cache, what a frame shows
- :mod:`.timelinerules` keys, range, rate and interpolation as edits
- :mod:`.recovery`      the recovery file of unsaved work: where, write, read, left behind
"""
