"""The API's first solves on a busy machine when nobody chose BLAS's threads (issue 27: fast
where a user feels it), with :mod:`isochor.core.blas`'s limit and without it.

A program that imports NumPy before Isochor (a script using the API, Blender with the
add-on) gets OpenBLAS on every core; the command line and the editor set one thread before
NumPy loads. Each run is a child process that imports NumPy first and solves the four paper
examples one after the other (each one's first solve, the result's ``elapsed``), in one of
three ways, interleaved:

* **limited**: as shipped, threadpoolctl limits BLAS to one thread while a step runs;
* **unlimited**: threadpoolctl hidden from the import, so nothing is limited (what the
  dependency buys);
* **one thread**: ``OPENBLAS_NUM_THREADS=1`` set, as the command line runs (the floor).

Two rows: with one other process keeping one core busy meanwhile (the machine a user has: a
browser, a build), and without. The NumPy path (``ISOCHOR_NO_JIT=1``): the compiled kernels
call no BLAS, and a session's first solves run on NumPy while numba loads.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from benchmarks import BLAS_ENV
from benchmarks.display import Row
from benchmarks.scale import ROOT
from benchmarks.timing import Timing

_CHILD = (
    "import json, sys\n"
    "if sys.argv[1] == 'unlimited':\n"
    "    sys.modules['threadpoolctl'] = None  # the import fails: nothing is limited\n"
    "import numpy\n"
    "from isochor.core.scenario.examples import EXAMPLES, example_scenario\n"
    "from isochor.core.scenario.problem import build\n"
    "from isochor.core.solve.generators import run_to_end\n"
    "spent = [run_to_end(build(example_scenario(n)).solve()).elapsed for n in EXAMPLES]\n"
    "print('BENCH:' + json.dumps(spent))\n"
)
WAYS = ("limited", "unlimited", "one thread")


def _run(way: str) -> float:
    """Seconds of the four first solves in one child run ``way``."""
    env = {k: v for k, v in os.environ.items() if k not in BLAS_ENV}
    env["ISOCHOR_NO_JIT"] = "1"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    if way == "one thread":
        env["OPENBLAS_NUM_THREADS"] = "1"
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, way], capture_output=True, text=True, env=env, timeout=600
    )
    line = next((s for s in proc.stdout.splitlines() if s.startswith("BENCH:")), None)
    if line is None:
        raise RuntimeError(f"the API child ({way}) failed: {proc.stderr.strip()[-300:]}")
    return float(sum(json.loads(line[6:])))


def api_threads_rows(repeats: int) -> list[Row]:
    """The rows, busy and idle: the limited runs' median against the unlimited ones'
    (ratio <= 1.0)."""
    return [_row(repeats, busy=True), _row(repeats, busy=False)]


def _row(repeats: int, busy: bool) -> Row:
    other = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        spent: dict[str, list[float]] = {way: [] for way in WAYS}
        for _ in range(max(3, repeats)):
            for way in WAYS:
                spent[way].append(_run(way))
    finally:
        if other is not None:
            other.kill()
            other.wait()
    t = {way: Timing(tuple(v)) for way, v in spent.items()}
    ratio = t["limited"].median / t["unlimited"].median
    machine = "one other process busy" if busy else "nothing else running"
    why = (
        f"ratio {ratio:.2f}: limited {t['limited'].ms(1)} ms, unlimited (no threadpoolctl) "
        f"{t['unlimited'].ms(1)} ms, OPENBLAS_NUM_THREADS=1 {t['one thread'].ms(1)} ms; the "
        f"four examples' first solves in a child that imported NumPy first, NumPy path, "
        f"{machine}, {os.cpu_count()} CPUs"
    )
    what = (
        f"API first solves, {'busy' if busy else 'idle'} machine, BLAS threads unset: "
        "limited / unlimited"
    )
    return Row(what, t["limited"], "ratio <= 1.0", ratio <= 1.0, why)
