"""Isochor core: volume-preserving free-form deformation (Hirota, Maheshwari, Lin 1999).

numpy + scipy + trimesh + fast-simplification only; never imports Qt, VTK, pyvista or
matplotlib. The paper's objects and the library's face sit at the top; the subpackages below
hold one role each. Arrows point down this list, never up (``tests/test_structure.py``)::

    api, adapters, export, report      the library's face (re-exported by ``isochor``)
    scenario/    the document: scenario file, edits, poses, examples -> a solvable problem
    solve/       the multi-level loop, augmented Lagrangian, L-BFGS, records
    goal/        what a solve holds: volume per body, centroid, handles, anchor, symmetry, folds
    io/          read, repair, rewrite and write model files (OBJ, PLY, STL, OFF, glTF)
    mesh, lattice, volume, springs, bodies, inside   the paper's geometry (Eq 2-14)
    kernels/     optional compiled (numba) hot loops, NumPy fallback
    errors, defaults, validate, forked, blas     what every module shares

Modules at this level:

- :mod:`.errors`    IsochorError: the one exception type for user errors
- :mod:`.defaults`  the tolerances, padding and lattice size every module shares
- :mod:`.validate`  checks of user values (finite, in range, JSON fields) and input files
- :mod:`.blas`      the solver's BLAS threads: one while a solve step runs (threadpoolctl),
  unless the user set them
- :mod:`.forked`    run a function in a forked child, so that the memory it leaves behind
  (fast-simplification's) goes back to the system when the child ends
- :mod:`.mesh`      TriMesh, an immutable triangle mesh
- :mod:`.lattice`   Lattice: nodes per axis, affine frame (Eq 5), Bernstein basis (Eq 2-4)
- :mod:`.localbasis`  Blender's lattice bases (B-spline, Catmull-Rom, cardinal, linear):
  per-axis windows of 4 nodes, displacements from the rest grid, the "Outside" map
- :mod:`.volume`    signed volume of a closed triangle mesh and its gradient (Eq 7-13), first
  moment (centre of mass) and its gradient
- :mod:`.springs`   the spring network: 6 axis + 8 body-diagonal neighbours (Eq 14)
- :mod:`.bodies`    separate closed bodies of one model: cavities, overlaps (winding numbers)
- :mod:`.inside`    which points of a regular grid are inside a closed mesh (signed ray
  crossings per grid column; the fold guard's interior samples)
- :mod:`.estimate`  a solve's peak memory and time before it starts, from its sizes, and
  whether this machine has them (the one line that refuses it, the largest lattice that fits)
- :mod:`.api`       the Python API: ``deform``, ``Session``, ``load``
- :mod:`.adapters`  the mesh types the API takes and gives back (arrays, trimesh, pyvista)
- :mod:`.export`    the one export path (``--out``, the window's Export, ``Session.export``)
- :mod:`.report`    the JSON report of a solve (``--report`` and the API)

Each subpackage's ``__init__`` docstring is its own map.
"""

from .errors import IsochorError

__all__ = ["IsochorError"]
