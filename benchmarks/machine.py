"""The machine unit: what the benchmark's times are divided by, so that a figure from another
day or another host compares.

The machines this benchmark runs on differ by 2-4x from day to day (a shared host, other
programs on the two cores, the memory's clock): an absolute millisecond says little without
the machine it was measured on. Two fixed measurements say which machine that was:

* :func:`unit_seconds`, **the unit**: the time one thread takes to read (sum) 1 GB of
  float64, a streaming read far larger than the caches (a 256 MB array summed four times,
  so that the benchmark's memory stays small). Most of the solver's work at scale streams
  arrays (the basis, the fans, the sparse solves), so a figure in units moves with the
  machine's memory;
* :func:`compute_seconds`, a fixed compute kernel: Horner's rule for a polynomial of
  degree :data:`DEGREE` on a cache-resident array, :data:`FLOPS` floating-point operations
  on one thread: what the arithmetic-bound parts (the local basis, det J) move with.

Both are medians of repeats, measured once per process (the first call) and kept: every
row of one run is divided by the same unit. ``python -m benchmarks.machine`` prints them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from benchmarks.timing import Timing, time_call

#: bytes the unit reads: 1 GB
UNIT_BYTES = 1 << 30
#: the array the unit sums, bytes (UNIT_BYTES / READ_BYTES passes over it)
READ_BYTES = 1 << 28
#: the compute kernel: Horner's rule of this degree ...
DEGREE = 16
#: ... on this many float64 (256 KB: in a core's L2) ...
COMPUTE_POINTS = 1 << 15
#: ... this many times: a multiply and an add per degree and point
COMPUTE_PASSES = 200
FLOPS = 2 * DEGREE * COMPUTE_POINTS * COMPUTE_PASSES
#: repeats of each measurement (the median is kept)
REPEATS = 7


@dataclass(frozen=True)
class MachineUnit:
    """One measurement of the machine.

    Attributes
    ----------
    read : seconds to sum 1 GB of float64 on one thread, per repeat
    compute : seconds of the compute kernel (:data:`FLOPS` operations), per repeat
    """

    read: Timing
    compute: Timing

    @property
    def seconds(self) -> float:
        """The unit: the median time to sum 1 GB, seconds."""
        return self.read.median

    @property
    def bandwidth(self) -> float:
        """Bytes a second one thread reads (the median)."""
        return UNIT_BYTES / self.read.median

    @property
    def flops(self) -> float:
        """Floating-point operations a second of the compute kernel (the median)."""
        return FLOPS / self.compute.median

    def words(self) -> str:
        """One line for the console and the report."""
        return (
            f"machine unit: 1 GB of float64 summed on one thread in {self.read.ms(1)} ms "
            f"({self.bandwidth / 1e9:.1f} GB/s; medians (min-max) of {len(self.read.values)}); "
            f"compute kernel {self.compute.ms(1)} ms ({self.flops / 1e9:.2f} GFLOP/s)"
        )


def _read_once(a: np.ndarray) -> None:
    for _ in range(UNIT_BYTES // a.nbytes):
        np.add.reduce(a)


#: the compute kernel's polynomial, highest power first
COEFFICIENTS = np.linspace(1.0, 0.5, DEGREE + 1)


def compute_kernel(x: np.ndarray, y: np.ndarray, passes: int = COMPUTE_PASSES) -> np.ndarray:
    """The compute kernel: ``y`` set to the polynomial :data:`COEFFICIENTS` at ``x`` by
    Horner's rule, in place, ``passes`` times; returns ``y``."""
    coefficients = COEFFICIENTS
    for _ in range(passes):
        y.fill(coefficients[0])
        for c in coefficients[1:]:
            np.multiply(y, x, out=y)
            np.add(y, c, out=y)
    return y


def measure(repeats: int = REPEATS) -> MachineUnit:
    """Measure the machine now (about ``repeats`` x 0.2 s)."""
    a = np.ones(READ_BYTES // 8)  # (freed when this returns)
    read = time_call(lambda: _read_once(a), repeats)
    x = np.linspace(0.0, 0.999, COMPUTE_POINTS)
    y = np.empty_like(x)
    compute = time_call(lambda: compute_kernel(x, y), repeats)
    return MachineUnit(read, compute)


_MEASURED: MachineUnit | None = None


def machine_unit() -> MachineUnit:
    """This process's measurement of the machine (made at the first call, then kept)."""
    global _MEASURED
    if _MEASURED is None:
        _MEASURED = measure()
    return _MEASURED


def use(unit: MachineUnit | None) -> MachineUnit | None:
    """Take ``unit`` as this process's measurement (a child process handed its parent's, so
    that both divide by the same unit; None: measure again at the next call). Returns the
    one it replaces."""
    global _MEASURED
    previous, _MEASURED = _MEASURED, unit
    return previous


def unit_seconds() -> float:
    """The unit, seconds: one thread's time to sum 1 GB of float64 (the median, measured
    once per process). Divide a time by it to compare across machines."""
    return machine_unit().seconds


def in_units(seconds: float) -> str:
    """``seconds`` in machine units, for a row: ``"0.42 u"``."""
    u = seconds / unit_seconds()
    return f"{u:.3g} u" if u < 100 else f"{u:.0f} u"


if __name__ == "__main__":
    print(measure().words())
