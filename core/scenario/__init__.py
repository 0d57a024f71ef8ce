"""The scenario: what the user did, as one versioned JSON document, and how it is solved.

- :mod:`.document`     the scenario file: parse, validate, write (``docs/SCENARIO.md``)
- :mod:`.edits`        Edit: moves, pins and handles, read from JSON and applied to a lattice
- :mod:`.poses`        keyframed poses and what holds between keys (the timeline)
- :mod:`.problem`      scenario -> solvable problem: load the pyramid, fit the lattice, moves;
  ``Problem.solve`` is the one place a scenario's solve is started
- :mod:`.sequence`     solve every frame of a timeline, each from the frame before
- :mod:`.examples`     the paper's examples (Sec 5) as built-in scenarios
- :mod:`.shapes`       torus, sphere and the paper's club, sampled level by level
- :mod:`.paper_models` the cow bending and generic bend/squash edits on model files

Uses :mod:`isochor.core.solve` and everything below it.
"""
