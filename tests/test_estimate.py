"""The estimate before a solve (isochor.core.estimate): its fill model against SuperLU's
factor, its verdict and its one line, and its memory against a real solve's peak measured
out of process. (Its time against the measured time is a benchmark row:
``python -m benchmarks.estimate``.)"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from isochor.core import estimate as est
from isochor.core.estimate import Machine, Sizes, estimate, factor_cost, largest_fitting

#: the dissection's count of the factor's entries is within this factor of SuperLU's (its
#: separators' fronts are counted as the stencil reaches; SuperLU's supernodes pad them)
FILL_FACTOR = 2.0


def superlu_fill(shape: tuple[int, int, int]) -> int:
    """Entries of L and U of the solver's own sparse factor of a rest lattice's springs."""
    from isochor.core.lattice import Lattice
    from isochor.core.solve.precondition import Curvature, dissection
    from isochor.core.springs import SpringNetwork, lattice_springs

    lattice = Lattice.around(np.random.default_rng(0).random((50, 3)), shape, 0.1, "bspline")
    net = SpringNetwork(lattice_springs(shape), lattice.rest_nodes)
    n = int(np.prod(shape))
    order = np.repeat(3 * dissection(shape), 3) + np.tile(np.arange(3), n)
    curvature = Curvature(net.hessian(lattice.rest_nodes), order, whole_nodes=True)
    lu = curvature._sparse
    assert lu is not None, "the rest lattice's curvature is positive definite"
    return int(lu.L.nnz + lu.U.nnz)


@pytest.mark.parametrize("shape", [(16, 16, 16), (20, 20, 20), (32, 32, 4)])
def test_fill_model_follows_superlu(shape):
    fill, flops = factor_cost(shape)
    measured = superlu_fill(shape)
    assert 1 / FILL_FACTOR <= measured / fill <= FILL_FACTOR, (shape, measured, fill)
    assert flops > fill  # every entry costs at least one operation


def test_cost_grows_with_every_size():
    base = est.cost(Sizes((16, 16, 16), True, 20_000))
    for bigger in (Sizes((24, 24, 24), True, 20_000), Sizes((16, 16, 16), True, 200_000)):
        memory, units = est.cost(bigger)
        assert memory > base[0] and units > base[1]
    # a flat lattice of as many nodes factors far cheaper than a cube (a 2D separator)
    assert factor_cost((64, 64, 4))[1] < factor_cost((26, 26, 24))[1]
    # the paper's basis weighs every point by every node: dense weights cost memory
    assert (
        est.cost(Sizes((10, 10, 10), False, 80_000))[0]
        > est.cost(Sizes((10, 10, 10), True, 80_000))[0]
    )


def test_verdict_message_and_largest_fitting():
    big = Sizes((64, 64, 64), True, 346_000)
    small_machine = Machine(available_bytes=3.2e9, unit_seconds=0.05, time_limit=600.0)
    e = estimate(big, small_machine)
    assert not e.fits() and not e.memory_fits()
    line = e.message()
    assert "\n" not in line and line.startswith("a 64x64x64 lattice needs about ")
    assert "3.2 GB free" in line
    best = e.largest_fitting()
    assert best is not None and best[0] == best[1] == best[2] < 64
    assert f"{best[0]}x{best[1]}x{best[2]} fits" in line
    # the largest that fits does, and one node more per axis does not
    assert estimate(Sizes(best, True, 346_000), small_machine).fits()
    k = best[0] + 1
    assert not estimate(Sizes((k, k, k), True, 346_000), small_machine).fits()
    # proportions are kept
    flat = largest_fitting(Sizes((64, 64, 16), True, 346_000), small_machine)
    assert flat is not None and flat[0] == flat[1] and flat[2] * 4 == pytest.approx(flat[0], abs=2)


def test_too_slow_is_said_and_nothing_fits_is_said():
    slow = Machine(available_bytes=1e12, unit_seconds=1.0, time_limit=10.0)
    e = estimate(Sizes((40, 40, 40), True, 20_000), slow)
    assert e.memory_fits() and not e.time_fits() and not e.fits()
    assert "the limit is 10 s" in e.message()
    tiny = Machine(available_bytes=1e6, unit_seconds=0.05)
    assert estimate(Sizes((4, 4, 4)), tiny).largest_fitting() is None
    assert "no lattice fits" in estimate(Sizes((4, 4, 4)), tiny).message()
    roomy = Machine(available_bytes=1e12, unit_seconds=0.05)
    assert estimate(Sizes((8, 8, 8), True, 5_000), roomy).fits()


def test_sizes_of_a_session_and_this_machine():
    import trimesh

    from isochor.core.api import Session

    mesh = trimesh.creation.icosphere(subdivisions=2)
    session = Session((mesh.vertices, mesh.faces), lattice=(5, 4, 3), basis="bspline")
    sizes = Sizes.of(session)
    assert sizes == Sizes((5, 4, 3), True, len(mesh.faces))
    assert Sizes.of(session.problem) == sizes
    assert Sizes.of((6, 6, 6)).nodes == (6, 6, 6)
    here = Machine.here()
    assert here.available_bytes > 0 and here.unit_seconds > 0
    with open("/proc/meminfo", encoding="ascii") as f:
        total = next(float(line.split()[1]) * 1024 for line in f if line.startswith("MemTotal"))
    assert here.available_bytes <= total


CHILD = """
import json, sys, trimesh
from isochor.core.api import Session
n, s = int(sys.argv[1]), int(sys.argv[2])
mesh = trimesh.creation.icosphere(subdivisions=s)
session = Session((mesh.vertices, mesh.faces), lattice=(n, n, n), basis="bspline")
session.move((n - 1, n // 2, n // 2), by=(1.2 / n, 0.0, 0.0))
session.pin((0, n // 2, n // 2))
session.solve()
# VmHWM is this process's own map's peak: ru_maxrss would carry over the size of the
# pytest process that forked it, since Linux keeps the peak across fork and exec.
with open("/proc/self/status", encoding="ascii") as f:
    peak = next(float(l.split()[1]) * 1024.0 for l in f if l.startswith("VmHWM:"))
print(json.dumps({"peak": peak, "triangles": len(mesh.faces)}))
"""


@pytest.mark.parametrize(("n", "subdivisions"), [(8, 4), (20, 4)])
def test_memory_estimate_against_a_solve_out_of_process(n, subdivisions):
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(n), str(subdivisions)],
        capture_output=True,
        text=True,
        timeout=600,
        check=True,
    )
    got = json.loads(done.stdout.strip().splitlines()[-1])
    e = estimate(Sizes((n, n, n), True, got["triangles"]), Machine(math.inf, 1.0))
    ratio = got["peak"] / e.memory_bytes
    assert 1 / est.MEMORY_FACTOR <= ratio <= est.MEMORY_FACTOR, (ratio, got, e.memory_bytes)


# -- the refusals: the API and the command line ------------------------------------------
def _session(n: int, **options):
    import trimesh

    from isochor.core.api import Session

    mesh = trimesh.creation.icosphere(subdivisions=2)
    session = Session((mesh.vertices, mesh.faces), lattice=(n, n, n), basis="bspline", **options)
    session.move((n - 1, n // 2, n // 2), by=(1.2 / n, 0.0, 0.0))
    return session


def test_api_refuses_a_slow_solve_unless_forced(monkeypatch):
    from isochor.core.errors import IsochorError

    monkeypatch.setattr(est, "TIME_LIMIT", 1e-6)  # every solve is too slow
    session = _session(6)
    before = session.nodes.copy()
    with pytest.raises(
        IsochorError, match=r"^a 6x6x6 lattice needs about .*\(force=True solves it anyway\)$"
    ):
        session.solve()
    assert np.array_equal(session.nodes, before) and session.result is None
    forced = _session(6, force=True)
    assert forced.solve().converged
    with pytest.raises(IsochorError, match="force must be True or False"):
        _session(6, force="yes")


def test_api_refuses_memory_even_when_forced(monkeypatch):
    from isochor.core.errors import IsochorError

    monkeypatch.setattr(est, "available_memory", lambda: 1e8)  # 100 MB free
    with pytest.raises(IsochorError, match=r"this machine has 100 MB free; no lattice fits"):
        _session(6, force=True).solve()


#: the child's address space: its estimate's "free memory" (RLIMIT_AS caps MemAvailable)
CHILD_SPACE = 3 << 30


def _limited() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (CHILD_SPACE, CHILD_SPACE))


def test_cli_refuses_a_lattice_beyond_the_memory_in_one_line(tmp_path):
    from pathlib import Path

    scene = tmp_path / "big.json"
    scene.write_text(
        json.dumps(
            {
                "model": {"builtin": "torus"},
                "lattice": {"nodes": [48, 48, 48], "basis": "bspline"},
                "moves": [{"node": [47, 24, 24], "by": [0.01, 0, 0]}],
            }
        )
    )
    out = tmp_path / "o.ply"
    run = subprocess.run(
        [sys.executable, "-m", "isochor.app.cli.main", "solve", str(scene), "--out", str(out)],
        cwd=Path(__file__).resolve().parents[1],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        preexec_fn=_limited,
    )
    assert run.returncode == 1, run.stderr
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr
    assert run.stderr.startswith("isochor: a 48x48x48 lattice needs about ")
    assert "GB free; " in run.stderr and " fits" in run.stderr
    assert not out.exists()


def test_cli_refuses_a_slow_solve_unless_forced(tmp_path, monkeypatch, capsys):
    from isochor.app.cli.main import main

    monkeypatch.setattr(est, "TIME_LIMIT", 1e-6)  # every solve is too slow
    out = tmp_path / "o.ply"
    assert main(["solve", "--example", "torus-compression", "--out", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("isochor: a 3x3x3 lattice needs about ")
    assert err.rstrip().endswith("(--force solves it anyway)") and not out.exists()
    assert (
        main(["solve", "--example", "torus-compression", "--out", str(out), "-q", "--force"]) == 0
    )
    err = capsys.readouterr().err
    assert "isochor: warning: a 3x3x3 lattice needs about " in err and "(--force)" in err
    assert out.exists()
