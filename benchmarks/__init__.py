"""Isochor's benchmark: the paper's Tables 1-2 and Figures 5-8 on this machine.

``python -m benchmarks [--quick] [--repeats N] [--out docs/BENCHMARKS.md]`` (``make bench``)
reproduces Hirota, Maheshwari and Lin (1999) Tables 1 and 2 and Figures 5-8 with Isochor's
solver, profiles one solve, measures how evaluation time scales with the mesh, times the
346k-triangle armadillo, times each constraint beyond the paper's one volume with and
without it (``--only constraints`` runs that section alone and replaces it in the report),
checks the performance targets and writes ``docs/BENCHMARKS.md`` (and the figures next to
it). It lives in the source tree, beside ``tests/``; the wheel does
not ship it.

Every timing is the median of ``--repeats`` runs with the smallest and largest beside it.
BLAS runs on one thread: ``python -m benchmarks`` sets the variables in :data:`BLAS_ENV` to 1
before NumPy is imported (unless they are set already, and then the report says so).

Definitions (as in the paper):

* T2: the multi-level solve (``isochor.core.solve.multilevel.solve``), from the first ``next()``
  to the returned result, on a surface whose levels are already set up (the editor keeps
  them per document). "cold" is the first solve on a fresh surface, which also sets the
  levels up.
* T1: the same solve (same lattice, moves, pins and tolerances) on the terminal mesh only,
  ``EmbeddedSurface(lattice, [terminal mesh])``, levels set up likewise.
* Terminal: where the solve stopped by its own test (Eq 29 estimate, node change, volume on
  the full mesh); "paper size" rows cut the pyramid at the paper's terminal size and disable
  the early stop, so every level up to that size is solved.
* Node error (Figures 5-8): the largest distance of a node from its final position, over
  the object size.

Modules: :mod:`~benchmarks.timing` (timings, memory, the host), :mod:`~benchmarks.machine`
(the machine unit every time is also stated in: one thread summing 1 GB, a compute kernel),
:mod:`~benchmarks.cases`
(the examples and draining a solve), :mod:`~benchmarks.tables` (Tables 1-2, start levels,
first records), :mod:`~benchmarks.scale` (evaluation at scale, the armadillo),
:mod:`~benchmarks.profiling` (where a solve's time goes, with cProfile),
:mod:`~benchmarks.display` (the Display rate section) with :mod:`~benchmarks.drag_cases`
(its solver measurements) and :mod:`~benchmarks.local_lattice` (Blender's 16x16x16 B-spline
lattice), :mod:`~benchmarks.dense_layer` (a whole layer pushed on a dense lattice, a
Session's re-solve after a nudge, the local kernels, in machine units),
:mod:`~benchmarks.first_evaluation` (a fresh process's first evaluation while the kernels
load) and :mod:`~benchmarks.window` (the window's rows) with
:mod:`~benchmarks.stalls` (what the GUI thread does in its long stalls),
:mod:`~benchmarks.sequences` (keyframed poses),
:mod:`~benchmarks.blender` (the Blender add-on: first use, against Blender's modifier and
the command line; run on its own),
:mod:`~benchmarks.constraints` (what each constraint costs: pairs, rows, measuring) with
:mod:`~benchmarks.constraint_cases` (its cases) and :mod:`~benchmarks.constraints_report`
(its Markdown), :mod:`~benchmarks.targets`,
:mod:`~benchmarks.report` (Markdown and figures) and :mod:`~benchmarks.run` (the command
line).
"""

#: the variables that set BLAS's thread count; ``python -m benchmarks`` sets them to 1
BLAS_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
