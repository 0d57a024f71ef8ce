"""The estimate before a solve (:mod:`isochor.core.estimate`) against the solve measured.

``python -m benchmarks.estimate [--sizes 12:4,16:5,24:5,32:5]`` solves an icosphere (``:S``
its subdivisions: 20 * 4^S triangles) under an ``N x N x N`` B-spline lattice, one face
node moved and the opposite one pinned, each in a fresh child process, and prints a row per
size: the estimate, the child's peak resident memory (its own map's ``VmHWM``) and wall time, their
ratios, and MET when each ratio is within the estimate's stated factor
(:data:`~isochor.core.estimate.MEMORY_FACTOR`, :data:`~isochor.core.estimate.TIME_FACTOR`),
MISSED otherwise. The machine unit is measured before each child, and the time's ratio
compares estimate and measurement at the same unit.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

DEFAULT_SIZES = "12:4,16:5,24:5,32:5"


def child(n: int, subdivisions: int) -> dict:
    """Solve the size in this process; its peak memory and the solve's wall time."""
    import trimesh

    from benchmarks.timing import peak_rss_mb
    from isochor.core.api import Session

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    t = time.perf_counter()
    session = Session((mesh.vertices, mesh.faces), lattice=(n, n, n), basis="bspline")
    session.move((n - 1, n // 2, n // 2), by=(1.2 / n, 0.0, 0.0))
    session.pin((0, n // 2, n // 2))
    result = session.solve()
    return {
        "seconds": time.perf_counter() - t,
        "peak": peak_rss_mb() * 1024.0 * 1024.0,
        "converged": bool(result.converged),
        "triangles": len(mesh.faces),
    }


def row(n: int, subdivisions: int) -> str:
    from benchmarks.machine import measure
    from isochor.core.estimate import MEMORY_FACTOR, TIME_FACTOR, Machine, Sizes, estimate

    unit = measure(3).seconds
    code = f"import json, benchmarks.estimate as b; print(json.dumps(b.child({n}, {subdivisions})))"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    got = json.loads(done.stdout.strip().splitlines()[-1])
    e = estimate(Sizes((n, n, n), True, got["triangles"]), Machine(float("inf"), unit))
    memory, seconds = got["peak"] / e.memory_bytes, got["seconds"] / e.seconds
    met = 1 / MEMORY_FACTOR <= memory <= MEMORY_FACTOR and 1 / TIME_FACTOR <= seconds <= TIME_FACTOR
    return (
        f"{n:>3}^3 {got['triangles']:>7} tri  memory est {e.memory_bytes / 1e6:7.0f} MB "
        f"meas {got['peak'] / 1e6:7.0f} MB (x{memory:.2f})  time est {e.seconds:6.1f} s "
        f"meas {got['seconds']:6.1f} s (x{seconds:.2f}; unit {1000 * unit:.0f} ms)  "
        f"{'MET' if met else 'MISSED'}" + ("" if got["converged"] else " (not converged)")
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default=DEFAULT_SIZES, help="N:S,... (lattice, subdivisions)")
    args = parser.parse_args(argv)
    from isochor.core.estimate import MEMORY_FACTOR, TIME_FACTOR

    print(
        f"estimate vs measured (MET: memory within x{MEMORY_FACTOR:g}, "
        f"time within x{TIME_FACTOR:g} either way)"
    )
    for item in args.sizes.split(","):
        n, s = (int(v) for v in item.split(":"))
        print(row(n, s), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
