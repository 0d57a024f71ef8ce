"""Defaults that more than one module needs: their one owner.

Every length is relative to the object size and every volume to the model's rest volume, so
the defaults suit a model in millimetres and in metres alike.
"""

from __future__ import annotations

#: |dV| / V0 that counts as preserved
TOL_VOLUME = 5e-4
#: epsilon of the paper (Sec 4.3): largest node change between levels, / object size
TOL_NODES = 1e-3
#: a fitted lattice box is padded on each side by this fraction of the model's extent
PADDING = 0.05
#: nodes per axis of a lattice when nothing else is said
LATTICE_NODES = (3, 3, 3)
