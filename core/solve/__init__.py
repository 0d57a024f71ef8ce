"""The solve: one generator that yields progress records and returns the result.

- :mod:`.multilevel`   the bootstrapping loop (Sec 4.3, Fig 4, Eq 27-29): ``solve``, the one
  solve generator every consumer drives; ``live=True`` for a drag's frames
- :mod:`.plan`         Request, Plan, Iterate, Ending: what the solve's steps hand each other
- :mod:`.solver`       augmented Lagrangian with an L-BFGS inner loop (Eq 15-21, Fig 3)
- :mod:`.lbfgs`        the inner loop: L-BFGS as a generator, preconditioned
- :mod:`.linesearch`   its strong-Wolfe line search (SciPy's, without importing scipy.optimize)
- :mod:`.precondition` the L-BFGS start: springs' Hessian + Gauss-Newton terms, inverted
- :mod:`.surface`      EmbeddedSurface: the level pyramid in its lattice, per-level caches
- :mod:`.pyramid`      the QEM level pyramid (fast-simplification), each level checked
- :mod:`.local`        the local release: a small edit re-solved where it reaches, at full
  resolution, the rest remembered (not yet called by ``solve``)
- :mod:`.outcome`      the result measured on the full mesh: a success or not, and why
- :mod:`.records`      Progress, LevelStats, SolveResult: what a solve yields and returns
- :mod:`.generators`   ``run_to_end`` / ``relay``: drive a progress generator to its result

Uses :mod:`isochor.core.goal`, :mod:`isochor.core.io`, :mod:`isochor.core.kernels` and the
geometry.
"""
