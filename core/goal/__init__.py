"""What a solve holds besides the pinned nodes, as constraints on the lattice nodes.

- :mod:`.spec`        :class:`~.spec.Goal`: the goal's fields, each declared once with its
  default, its allowed values and its public spellings (:data:`~.spec.GOAL_FIELDS`: the
  scenario key, the API keyword, the command-line option); light, no numpy
- :mod:`.constraints` the goal's constraints on one pyramid level: total or per-body volume,
  centroid
- :mod:`.anchor`      the far side stays: which lattice face to hold, from the edit's push
- :mod:`.handles`     surface handles: points of the model sent to places, as linear
  constraints reduced to what the free nodes can reach (least squares)
- :mod:`.symmetry`    Mirror: symmetric editing across a lattice mid-plane
- :mod:`.certify`     a proof that det J > 0 over the whole solid (Bernstein coefficients,
  de Casteljau subdivision), or a point between the samples where it is not
- :mod:`.folds`       det J at the model's vertices and inside it: fold detection and guard

Uses :mod:`isochor.core.io` and the geometry at the top of :mod:`isochor.core`.
"""
