"""What a solve holds besides the pinned nodes, as constraints on the lattice nodes.

- :mod:`.constraints` :class:`~.constraints.Goal` (the goal's fields, declared once) and the
  constraints of one pyramid level: total or per-body volume, centroid
- :mod:`.anchor`      no rigid drift: which lattice face to hold while too little is fixed
- :mod:`.handles`     surface handles: points of the model sent to places, as linear
  constraints reduced to what the free nodes can reach (least squares)
- :mod:`.symmetry`    Mirror: symmetric editing across a lattice mid-plane
- :mod:`.folds`       det J at the model's vertices and inside it: fold detection and guard

Uses :mod:`isochor.core.io` and the geometry at the top of :mod:`isochor.core`.
"""
