"""Before a solve: how much memory and time it will take, and whether this machine has them.

::

    >>> from isochor.core.estimate import Machine, Sizes, estimate
    >>> e = estimate(Sizes((64, 64, 64), triangles=346_000), Machine(3.2e9, 0.05))
    >>> e.fits()
    False
    >>> e.message()
    'a 64x64x64 lattice needs about 8.3 GB and 2 min; this machine has 3.2 GB free; 40x40x40 fits'

:func:`estimate` takes a :class:`Sizes` (nodes per axis, basis kind, triangles), a solvable
problem (``isochor.core.scenario.problem.Problem``) or an API ``Session`` and gives an
:class:`Estimate`: :attr:`~Estimate.memory_bytes` (the process's peak resident memory),
:attr:`~Estimate.seconds` (the whole solve's wall time on this machine, one core), and the
machine it is judged against (:class:`Machine`: the memory available now, read from
``/proc/meminfo`` or ``os.sysconf``, and the machine unit, measured here once per process).
:meth:`Estimate.message` is the one line the command line, the API, the editor and the
Blender add-on show; :meth:`Estimate.largest_fitting` the largest lattice of the same
proportions that fits.

**The model.** What grows with a lattice of ``N`` nodes is the sparse curvature's
factorisation (:mod:`isochor.core.solve.precondition`: SuperLU in the nested-dissection
order of the grid, on the nodes above :data:`~isochor.core.solve.precondition.NODE_FACTOR`
variables). Its fill and operations are counted by walking the same dissection
(:func:`dissection_cost`: each separator's front is the separator and the ancestors'
separators around it, factored dense), so a flat lattice (64x64x4) costs what it costs and
not what a cube of as many nodes would. The rest is linear in what the solve holds:
per node (springs' Hessian pattern, fold guard samples, the solver's vectors), per
triangle of the pyramid (bases of 64 weights a point, volume operators) and, for the
paper's Bernstein basis, its dense weights (every node weighs every point). Times are
kept in machine units (the time one thread takes to sum 1 GB of float64, as
``benchmarks/machine.py`` defines it) and turned into seconds by this machine's unit.

The constants were fitted to solves measured on the development machine (a child process
per size: its own peak resident memory and wall time; the figures and the fit are in
docs/BENCHMARKS.md, ``python -m benchmarks.estimate`` measures them again). The estimate
is stated to be within :data:`MEMORY_FACTOR` of the measured peak and :data:`TIME_FACTOR`
of the measured time: a solve's time depends on how many steps it takes, which no size
predicts better.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from dataclasses import dataclass, replace
from functools import cache, lru_cache
from typing import Any

#: the measured peak is within this factor of the estimate (either way)
MEMORY_FACTOR = 2.0
#: the measured time is within this factor of the estimate (either way)
TIME_FACTOR = 3.0
#: a solve estimated to take longer than this is too slow (seconds) unless forced
TIME_LIMIT = 600.0
#: the share of the available memory a solve may plan to take (the rest: the system, the
#: editor's window, the estimate's own error)
MEMORY_SHARE = 0.8

# -- memory, bytes --------------------------------------------------------------------
#: the interpreter, NumPy, SciPy, trimesh and a small solve
BASE_BYTES = 250e6
#: per triangle of the full mesh (the pyramid's levels, their bases and volume operators)
TRIANGLE_BYTES = 1.2e3
#: per lattice node (springs' Hessian pattern and its sort, fold guard samples, vectors)
NODE_BYTES = 24e3
#: per entry of the sparse factor (float32 value, row index, SuperLU's work space)
FILL_BYTES = 8.0
#: per weight of a Bernstein basis (dense float64, every node for every vertex)
WEIGHT_BYTES = 8.0

# -- time, machine units (seconds / the unit) ---------------------------------------
#: the development machine's unit, seconds, when the constants below were measured
CALIBRATION_UNIT = 0.165
#: a solve's fixed cost
BASE_UNITS = 1.2 / CALIBRATION_UNIT
#: per triangle of the full mesh (its levels' steps, the final measurement)
TRIANGLE_UNITS = 25e-6 / CALIBRATION_UNIT
#: per lattice node (the Hessian's assembly, each step's products and fold guard)
NODE_UNITS = 0.8e-3 / CALIBRATION_UNIT
#: per operation of the sparse factorisation as :func:`dissection_cost` counts them
FLOP_UNITS = 1.5e-9 / CALIBRATION_UNIT
#: sparse factorisations a solve makes (one where it starts, one taken again on the way)
FACTORISATIONS = 2
#: the Bernstein basis's weights cost this per weight and step-level (dense products)
WEIGHT_UNITS = 2e-9 / CALIBRATION_UNIT

#: a dense Cholesky's operations run this many times faster than the sparse factor's
DENSE_SPEED = 30.0
#: above this many node coordinates the curvature is sparse (core.springs.SPARSE_VARIABLES)
SPARSE_VARIABLES = 3000
#: above this many variables the sparse factor is on whole nodes
#: (core.solve.precondition.NODE_FACTOR)
NODE_FACTOR = 6000


@dataclass(frozen=True)
class Sizes:
    """What a solve's cost depends on.

    Attributes
    ----------
    nodes : lattice nodes per axis
    local : a local (Blender's) basis; False for the paper's Bernstein basis, whose every
        node weighs every point
    triangles : the full mesh's triangles (0: the lattice alone)
    """

    nodes: tuple[int, int, int]
    local: bool = True
    triangles: int = 0

    @property
    def node_count(self) -> int:
        return math.prod(self.nodes)

    def words(self) -> str:
        """``"64x64x64"``."""
        return "x".join(str(n) for n in self.nodes)

    @classmethod
    def of(cls, what: Any) -> Sizes:
        """The sizes of a :class:`Sizes`, a lattice shape (three ints), a ``Problem`` or a
        ``Session`` (anything with ``.problem``), or an ``EmbeddedSurface``."""
        if isinstance(what, Sizes):
            return what
        if isinstance(what, (tuple, list)) and len(what) == 3:
            return cls(tuple(int(n) for n in what))  # type: ignore[arg-type]
        problem = getattr(what, "problem", what)
        surface = getattr(problem, "surface", problem)
        lattice = surface.lattice
        return cls(
            tuple(int(n) for n in lattice.shape),  # type: ignore[arg-type]
            bool(lattice.local),
            int(len(surface.levels[-1].faces)),
        )


@dataclass(frozen=True)
class Machine:
    """What a solve may take here.

    Attributes
    ----------
    available_bytes : the memory free for a new job (``MemAvailable``)
    unit_seconds : the machine unit: one thread's time to sum 1 GB of float64
    time_limit : a solve estimated longer than this (seconds) is too slow
    """

    available_bytes: float
    unit_seconds: float
    time_limit: float = TIME_LIMIT

    @classmethod
    def here(cls, time_limit: float = TIME_LIMIT) -> Machine:
        """This machine now: its available memory (read at each call) and its unit
        (measured once per process, about 0.1 s)."""
        return cls(available_memory(), machine_unit(), time_limit)


@dataclass(frozen=True)
class Estimate:
    """A solve's estimated peak memory and time, judged against a :class:`Machine`.

    Attributes
    ----------
    sizes : what was estimated
    memory_bytes : the process's peak resident memory, bytes
    units : the solve's time in machine units
    machine : the machine judged against (:meth:`Machine.here` by default)
    """

    sizes: Sizes
    memory_bytes: float
    units: float
    machine: Machine

    @property
    def seconds(self) -> float:
        """The solve's time on :attr:`machine`, seconds."""
        return self.units * self.machine.unit_seconds

    def memory_fits(self, machine: Machine | None = None) -> bool:
        m = machine or self.machine
        return self.memory_bytes <= MEMORY_SHARE * m.available_bytes

    def time_fits(self, machine: Machine | None = None) -> bool:
        m = machine or self.machine
        return self.units * m.unit_seconds <= m.time_limit

    def fits(self, machine: Machine | None = None) -> bool:
        """Whether the solve fits the machine: its memory and its time limit."""
        return self.memory_fits(machine) and self.time_fits(machine)

    def largest_fitting(self, machine: Machine | None = None) -> tuple[int, int, int] | None:
        """The largest lattice of the same proportions (each axis scaled alike, at least
        2 nodes) that fits, or None when not even 2x2x2 does."""
        return largest_fitting(self.sizes, machine or self.machine)

    def message(self, machine: Machine | None = None) -> str:
        """One line: what the solve needs, what the machine has, the largest lattice that
        fits (when this one does not)."""
        m = machine or self.machine
        need = f"a {self.sizes.words()} lattice needs about {_bytes(self.memory_bytes)} and "
        need += _duration(self.units * m.unit_seconds)
        if self.fits(m):
            return f"{need}; this machine has {_bytes(m.available_bytes)} free"
        have = f"this machine has {_bytes(m.available_bytes)} free"
        if not self.time_fits(m):
            have += f" and the limit is {_duration(m.time_limit)}"
        best = self.largest_fitting(m)
        fit = f"; {'x'.join(map(str, best))} fits" if best else "; no lattice fits"
        return f"{need}; {have}{fit}"


def estimate(what: Any, machine: Machine | None = None) -> Estimate:
    """The :class:`Estimate` of a solve of ``what`` (see :meth:`Sizes.of`) on ``machine``
    (this one now, by default)."""
    sizes = Sizes.of(what)
    memory, units = cost(sizes)
    return Estimate(sizes, memory, units, machine or Machine.here())


#: a unit no machine is slower than (a loaded, slow machine's 1 GB sum): a solve under the
#: time limit even at this unit needs no measurement of this one
SLOWEST_UNIT = 2.0


def screen(what: Any, time_limit: float | None = None) -> Estimate | None:
    """None when a solve of ``what`` surely fits this machine (its memory fits and it
    would be under ``time_limit``, :data:`TIME_LIMIT` by default, even at
    :data:`SLOWEST_UNIT`: nothing is measured, so a small solve pays only the count);
    otherwise its :class:`Estimate` on this machine,
    whose :meth:`~Estimate.memory_fits` and :meth:`~Estimate.time_fits` the caller acts on
    (refuse, or warn and go on)."""
    limit = TIME_LIMIT if time_limit is None else time_limit
    sizes = Sizes.of(what)
    memory, units = cost(sizes)
    free = available_memory()
    if memory <= MEMORY_SHARE * free and units * SLOWEST_UNIT <= limit:
        return None
    return Estimate(sizes, memory, units, Machine(free, machine_unit(), limit))


def largest_fitting(what: Any, machine: Machine | None = None) -> tuple[int, int, int] | None:
    """The largest lattice shaped like ``what``'s that fits ``machine``, or None."""
    sizes, m = Sizes.of(what), machine or Machine.here()
    top = max(sizes.nodes)
    for k in range(top, 1, -1):
        shape = tuple(max(2, round(n * k / top)) for n in sizes.nodes)
        memory, units = cost(replace(sizes, nodes=shape))  # type: ignore[arg-type]
        if memory <= MEMORY_SHARE * m.available_bytes and units * m.unit_seconds <= m.time_limit:
            return shape  # type: ignore[return-value]
    return None


def cost(sizes: Sizes) -> tuple[float, float]:
    """(peak bytes, machine units) of a solve of ``sizes`` (the module's model)."""
    n, tri = sizes.node_count, max(int(sizes.triangles), 0)
    fill, flops = factor_cost(sizes.nodes)
    memory = BASE_BYTES + TRIANGLE_BYTES * tri + NODE_BYTES * n + FILL_BYTES * fill
    units = BASE_UNITS + TRIANGLE_UNITS * tri + NODE_UNITS * n
    units += FACTORISATIONS * FLOP_UNITS * flops
    if not sizes.local:  # dense weights: every node for each vertex (about tri / 2)
        weights = n * tri / 2 * 4 / 3  # the pyramid's levels together
        memory += WEIGHT_BYTES * weights
        units += WEIGHT_UNITS * weights * 50  # some 50 products over the levels
    return memory, units


def factor_cost(nodes: tuple[int, int, int]) -> tuple[float, float]:
    """(entries, operations) of the curvature's factorisation of a lattice of ``nodes``
    per axis: a dense Cholesky up to :data:`SPARSE_VARIABLES` coordinates, then the sparse
    LU on the coordinates (3x3 blocks: 9x the entries, 27x the operations of the nodes'
    pattern) up to :data:`NODE_FACTOR`, then on the nodes alone."""
    variables = 3 * math.prod(nodes)
    if variables <= SPARSE_VARIABLES:  # LAPACK's blocked Cholesky: some 30x SuperLU's rate
        return variables * variables, variables**3 / 3 / DENSE_SPEED
    fill, flops = dissection_cost(tuple(sorted(nodes)))
    if variables <= NODE_FACTOR:
        return 9 * fill, 27 * flops
    return fill, flops


@lru_cache(maxsize=256)
def dissection_cost(nodes: tuple[int, int, int]) -> tuple[float, float]:
    """(entries of L and U, operations) of factoring a lattice's 27-point node pattern in
    the nested-dissection order of :func:`isochor.core.solve.precondition.dissection`,
    each separator's front (the separator and the ancestors' separator nodes around it)
    dense. An estimate of the fill, not SuperLU's count: the constants above absorb the
    difference (measured 1.2-1.6x at 16^3-32^3)."""
    return _block(nodes, (False,) * 6)


@cache
def _block(ext: tuple[int, int, int], inner: tuple[bool, ...]) -> tuple[float, float]:
    """(entries, operations) of one block of the dissection: its extents, and which of its
    six faces touch an ancestor's separator."""
    size = ext[0] * ext[1] * ext[2]
    if size <= 8:
        b = _boundary(ext, inner)
        return size * size + 2.0 * size * b, size**3 / 3 + size * size * b + size * b * b
    axis = max(range(3), key=lambda i: ext[i])
    c = ext[axis] // 2
    fill = flops = 0.0
    for length, side in ((c, 1), (ext[axis] - c - 1, 0)):
        if length > 0:
            half = tuple(length if i == axis else e for i, e in enumerate(ext))
            faces = tuple(True if i == 2 * axis + side else f for i, f in enumerate(inner))
            f, o = _block(half, faces)
            fill, flops = fill + f, flops + o
    sep = tuple(1 if i == axis else e for i, e in enumerate(ext))
    k = sep[0] * sep[1] * sep[2]
    b = _boundary(sep, inner)  # type: ignore[arg-type]
    return fill + k * k + 2.0 * k * b, flops + k**3 / 3 + k * k * b + k * b * b


def _boundary(ext: tuple[int, int, int], inner: tuple[bool, ...]) -> int:
    """Nodes of the ancestors' separators next to a block: each inner face's area, grown
    by one node each way (the 27-point pattern reaches the diagonals)."""
    total = 0
    for axis in range(3):
        a, b = (ext[i] + 2 for i in range(3) if i != axis)
        total += a * b * (inner[2 * axis] + inner[2 * axis + 1])
    return total


def available_memory() -> float:
    """Bytes of memory available for a new job: ``MemAvailable`` of ``/proc/meminfo``
    (Linux), else the free physical pages (``os.sysconf``), capped by the process's own
    address-space limit when it has one; infinity when nothing says."""
    free = math.inf
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    free = float(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if free == math.inf:
        with contextlib.suppress(ValueError, OSError, AttributeError):
            free = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY and soft > 0:
            free = min(free, float(soft))
    except (ImportError, OSError, ValueError):
        pass
    return free


#: the calibration's array: 64 MB of float64, summed :data:`_PASSES` times a repeat
_UNIT_WORDS = 1 << 23
_PASSES = 4
_REPEATS = 3


@lru_cache(maxsize=1)
def machine_unit() -> float:
    """This machine's unit, seconds (one thread summing 1 GB of float64): a 64 MB array
    summed 4 times, the median of 3 repeats, scaled to 1 GB; measured once per process
    (about 0.2 s)."""
    import numpy as np

    a = np.ones(_UNIT_WORDS)
    times = []
    for _ in range(_REPEATS):
        t = time.perf_counter()
        for _ in range(_PASSES):
            np.add.reduce(a)
        times.append(time.perf_counter() - t)
    return sorted(times)[len(times) // 2] * (1 << 30) / (_PASSES * a.nbytes)


def _bytes(n: float) -> str:
    if n == math.inf:
        return "unlimited memory"
    for unit, size in (("GB", 1e9), ("MB", 1e6)):
        if n >= size:
            value = n / size
            return f"{value:.2g} {unit}" if value < 10 else f"{value:.0f} {unit}"
    return f"{n / 1e3:.0f} kB"


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{max(seconds, 1):.0f} s"
    if seconds < 3600:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
