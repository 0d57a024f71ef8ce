"""Isochor core: volume-preserving free-form deformation (Hirota, Maheshwari, Lin 1999).

numpy + scipy + trimesh + fast-simplification only; never imports Qt, VTK or pyvista.

Modules, in the order of the paper:

- :mod:`core.lattice`    trivariate Bernstein FFD lattice (Eq 2-5)
- :mod:`core.volume`     signed volume of a closed triangle mesh and its gradient (Eq 7-13)
- :mod:`core.springs`    the 14-neighbour spring network energy (Eq 14)
- :mod:`core.solver`     augmented Lagrangian over the free nodes (Eq 15-21, Fig 3)
- :mod:`core.multilevel` the multi-level bootstrapping optimizer (Sec 4.3, Fig 4, Eq 27-29)
- :mod:`core.shapes`     built-in parametric shapes sampled level by level (torus, sphere, club)
"""

from .errors import IsochorError

__all__ = ["IsochorError"]
