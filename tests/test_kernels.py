"""The optional compiled kernels (core/kernels/): the same numbers as the NumPy path, the
NumPy path wherever they are missing, off or broken, and never a wait for the compiler.

The tests of the compiled path wait for it (``kernels.ready``) and are skipped without
numba or with ``ISOCHOR_NO_JIT`` set; the fallback tests always run.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from isochor.core import kernels
from isochor.core import lattice as lat_mod
from isochor.core.kernels import cache as _jitcache
from isochor.core.lattice import Lattice
from isochor.core.scenario.examples import example_scenario
from isochor.core.scenario.problem import build
from isochor.core.scenario.shapes import sphere_levels, torus, torus_levels
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import solve
from isochor.core.volume import VolumeOperator, signed_volume


def close(a, b, rel=1e-12):
    """a equals b to ``rel`` of b's largest entry."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.abs(a - b).max() <= rel * max(np.abs(b).max(), 1e-300)


def skewed_lattice(shape):
    axes = [[2.0, 0.3, 0.0], [0.1, 1.5, 0.2], [0.0, -0.4, 1.0]]
    return Lattice(shape, (0.5, -1.0, 2.0), axes)


#: every count of innermost layers the kernels treat apart: 2 to 5 at once, 6 to 10 in groups
#: of 2 or 3 (6 and 9: groups of 3 only; 7, 8, 10: both)
SHAPES = [(2, 2, 2), (3, 3, 3), (4, 3, 4), (3, 4, 5), (5, 5, 5), (2, 3, 6), (10, 2, 7)]
SHAPES += [(8, 8, 8), (3, 2, 9), (2, 2, 10), (4, 9, 3)]


@pytest.mark.parametrize("shape", SHAPES)
def test_basis_matches_the_dense_and_factored_numpy_forms(compiled, shape, monkeypatch):
    rng = np.random.default_rng(sum(shape))
    lat = skewed_lattice(shape)
    p = 3000
    uvw = np.concatenate([rng.uniform(size=(p - 100, 3)), rng.uniform(-0.2, 1.2, (100, 3))])
    points = lat.origin + uvw @ lat.axes  # inside the lattice, a few outside
    nodes = lat.rest_nodes + rng.normal(scale=0.3, size=(lat.n_nodes, 3))
    g = rng.normal(size=(p, 3))
    default = lat.point_basis(points)
    monkeypatch.setattr(lat_mod, "DENSE_LIMIT", 0)
    factored = lat.point_basis(points)
    assert default.dense is not None and factored.dense is None
    fast_p, fast_g = default.apply(nodes), default.apply_transpose(g)
    assert fast_p.shape == (p, 3) and fast_p.flags.f_contiguous and fast_g.shape == nodes.shape
    with kernels.numpy_path():
        for basis in (default, factored):
            assert close(fast_p, basis.apply(nodes))
            assert close(fast_g, basis.apply_transpose(g))
            assert close(fast_g, basis.apply_transpose(np.ascontiguousarray(g)))


def test_a_basis_holds_only_its_coordinates_while_the_kernels_evaluate(compiled):
    """The NumPy path's tables are built on its first use, not before: the kernels read
    the lattice coordinates alone (24 bytes a point)."""
    rng = np.random.default_rng(5)
    lat = skewed_lattice((5, 5, 5))
    points = lat.origin + rng.uniform(size=(20000, 3)) @ lat.axes
    nodes = lat.rest_nodes + rng.normal(scale=0.2, size=(lat.n_nodes, 3))
    basis = lat.point_basis(points)
    fast = basis.apply(nodes)
    basis.apply_transpose(fast)
    assert basis.nbytes == 20000 * 3 * 8
    with kernels.numpy_path():
        assert close(fast, basis.apply(nodes))
    assert basis.nbytes > 20000 * 30 * 8  # the factored tables, kept from now on


def _meshes():
    """Closed, open, badly wound, non-manifold, a vertex of high degree, a triangle soup."""
    rng = np.random.default_rng(11)
    sphere = sphere_levels(4)[-1]
    v = sphere.vertices + rng.normal(scale=0.02, size=sphere.vertices.shape)
    f = sphere.faces
    flipped = f.copy()
    flip = rng.random(len(f)) < 0.2
    flipped[flip] = flipped[flip][:, ::-1]
    ring = 60  # a disk: vertex 0 has 60 faces around it
    t = np.linspace(0, 2 * np.pi, ring, endpoint=False)
    disk_v = np.concatenate([[[0, 0, 0.3]], np.stack([np.cos(t), np.sin(t), 0 * t], 1)])
    disk_f = np.array([[0, 1 + i, 1 + (i + 1) % ring] for i in range(ring)])
    soup_v = rng.normal(size=(300, 3))
    soup_f = rng.integers(0, 280, size=(900, 3))  # degenerate faces; vertices 280.. unused
    soup_f[:20, 1] = soup_f[:20, 0]
    return {
        "closed": (v, f),
        "far away": (v + 1e3, f),
        "open": (v, f[rng.random(len(f)) > 0.1]),
        "badly wound": (v, flipped),
        "non-manifold": (v, np.concatenate([f, f[:50], f[:30, ::-1]])),
        "high degree": (disk_v, disk_f),
        "soup": (soup_v, soup_f),
    }


@pytest.mark.parametrize("shape", [(3, 3, 3), (4, 3, 4), (3, 4, 5), (2, 3, 6)])
def test_determinants_match_the_jacobian_for_every_layer_count(compiled, shape):
    """det J and |J|_F^2 of the compiled fold check (one loop nest per innermost layer
    count up to 5, a loop a layer above) against the lattice's own Jacobian."""
    rng = np.random.default_rng(sum(shape))
    lat = skewed_lattice(shape)
    uvw = np.concatenate([rng.uniform(size=(2900, 3)), rng.uniform(-0.2, 1.2, (100, 3))])
    points = lat.origin + uvw @ lat.axes
    nodes = lat.rest_nodes + rng.normal(scale=0.2, size=(lat.n_nodes, 3))
    jac = lat.jacobian(points, nodes)
    grid = nodes.reshape(*shape, 3)
    det, norms = kernels.determinants(
        np.ascontiguousarray(uvw.T), grid, np.linalg.inv(lat.axes).T, frobenius=True
    )
    assert close(det, np.linalg.det(jac), 1e-10)
    assert close(norms, np.einsum("pij,pij->p", jac, jac), 1e-12)


@pytest.mark.parametrize("name", list(_meshes()))
def test_volume_and_gradient_match_numpy_on_any_triangle_set(compiled, name):
    v, f = _meshes()[name]
    op = VolumeOperator(f, len(v))
    center = v.mean(axis=0) + 0.01
    value, grad = op.value_and_gradient(v, center)
    alone, whole = op(v, center), signed_volume(v, f)
    assert grad.shape == v.shape and grad.flags.f_contiguous
    with kernels.numpy_path():
        value0, grad0 = op.value_and_gradient(v, center)
        alone0, whole0 = op(v, center), signed_volume(v, f)
    scale = max(abs(value0), 1e-3 * np.abs(v - center).max() ** 3)
    assert abs(value - value0) <= 1e-12 * scale
    assert abs(alone - alone0) <= 1e-12 * scale and abs(whole - whole0) <= 1e-12 * scale
    assert close(grad, grad0)
    # the gradient is exact: the corner formula, face by face
    a, b, c = (v[f[:, i]] - center for i in range(3))
    corner = np.zeros_like(v)
    for i, w in enumerate((np.cross(b, c), np.cross(c, a), np.cross(a, b))):
        np.add.at(corner, f[:, i], w / 6.0)
    assert close(grad, corner, 1e-11)


@pytest.mark.parametrize("name", list(_meshes()))
def test_the_one_pass_evaluation_gives_the_three_passes_numbers(compiled, name):
    """VolumeOperator.node_gradient (the basis, the fans and the transpose range by range)
    against basis.apply, value_and_gradient and apply_transpose: bit for bit on the
    compiled path, and the same call on the NumPy path within rounding."""
    v, f = _meshes()[name]
    lat = Lattice.around(v, (3, 4, 3))
    basis = lat.point_basis(v)
    op = VolumeOperator(f, len(v))
    nodes = lat.rest_nodes + np.random.default_rng(4).normal(scale=0.05, size=(lat.n_nodes, 3))
    center = v.mean(axis=0) + 0.01
    value, grad = op.node_gradient(basis, nodes, center)
    v0, g0 = op.value_and_gradient(basis.apply(nodes), center)
    assert value == v0 and np.array_equal(grad, basis.apply_transpose(g0))
    with kernels.numpy_path():
        v1, g1 = op.node_gradient(basis, nodes, center)
    assert abs(value - v1) <= 1e-12 * max(abs(v1), 1e-3) and close(grad, g1)


def test_the_one_pass_evaluation_across_ranges_and_a_seam(compiled):
    """A torus of four ranges of vertices: each range applies the basis to a window about
    itself step by step, a fan may reach 399 vertices ahead (the seam's diagonals: past
    the window of the step before), and the seam's neighbours (a whole torus away) are
    far points; the same numbers as the three passes, on one thread or three, for one set
    of nodes after another (no point left over from the last call)."""
    mesh = torus(300, 200)
    assert mesh.n_vertices > 3 * kernels.CHUNK
    lat = skewed_lattice((4, 3, 5))
    basis = lat.point_basis(mesh.vertices)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)
    rng = np.random.default_rng(5)
    for threads in (1, 3, 3):
        nodes = lat.rest_nodes + rng.normal(scale=0.1, size=(lat.n_nodes, 3))
        v0, g0 = op.value_and_gradient(basis.apply(nodes), mesh.center)
        previous = kernels.set_threads(threads)
        try:
            value, grad = op.node_gradient(basis, nodes, mesh.center)
        finally:
            kernels.set_threads(previous)
        assert value == v0 and np.array_equal(grad, basis.apply_transpose(g0))
    plan = kernels.evaluation_plan(kernels.fans(mesh.faces, mesh.n_vertices))
    assert 0 < plan.window < 399 and len(plan.far) > 0  # the seam went far


def test_results_do_not_depend_on_the_thread_count(compiled):
    mesh = torus(256, 160)  # more points and faces than two ranges of work
    assert mesh.n_vertices > 2 * kernels.CHUNK
    lat = skewed_lattice((4, 3, 5))
    basis = lat.point_basis(mesh.vertices)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)
    nodes = lat.rest_nodes + np.random.default_rng(2).normal(scale=0.1, size=(lat.n_nodes, 3))
    runs = []
    for n in (1, 3):
        previous = kernels.set_threads(n)
        try:
            pts = basis.apply(nodes)
            v, g = op.value_and_gradient(pts, mesh.center)
            runs.append((pts, v, g, basis.apply_transpose(g), op(pts, mesh.center)))
        finally:
            kernels.set_threads(previous)
    for a, b in zip(*runs):
        assert np.array_equal(a, b)


def test_a_solve_ends_at_the_same_nodes_either_way(compiled):
    problem = build(example_scenario("torus-compression"))
    results = []
    for mode in ("numpy", "auto"):
        previous = kernels.set_mode(mode)
        try:
            results.append(
                run_to_end(
                    solve(problem.surface, problem.nodes, problem.fixed, options=problem.options)
                )
            )
        finally:
            kernels.set_mode(previous)
    size = problem.surface.lattice.size
    assert np.abs(results[0].nodes - results[1].nodes).max() <= 1e-9 * size


def test_a_failing_compiled_call_falls_back_to_numpy(compiled, monkeypatch):
    def broken(*args):
        raise RuntimeError("boom")

    fake = SimpleNamespace(
        apply_range=broken,
        transpose_range=broken,
        build_fans=broken,
        fan_gradient_range=broken,
        face_volume_range=broken,
        evaluation_range=broken,
    )
    mesh = sphere_levels(3)[-1]
    lat = Lattice.around(mesh.vertices, (3, 3, 3))
    basis = lat.point_basis(mesh.vertices)
    for name, value in (("kernels", fake), ("status", "ready"), ("reason", "")):
        monkeypatch.setattr(kernels._state, name, value)
    pts = basis.apply(lat.rest_nodes)
    assert kernels.status() == "failed: apply: RuntimeError: boom"
    assert close(pts, mesh.vertices, 1e-12)  # the NumPy path's answer
    assert kernels.ready(0) is False
    for name, value in (("kernels", fake), ("status", "ready"), ("reason", "")):
        monkeypatch.setattr(kernels._state, name, value)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)
    value, grad = op.node_gradient(basis, lat.rest_nodes)
    assert kernels.status().startswith("failed: ")
    assert abs(value - signed_volume(mesh.vertices, mesh.faces)) <= 1e-12 * abs(value)
    assert grad.shape == (lat.n_nodes, 3)


def _child(code: str, **env) -> str:
    """Run code in a fresh interpreter (the installed package), return its stdout."""
    full = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    full.pop(kernels.ENV_OFF, None)
    full.update(env)
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
        env=full,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc.stdout


EVALUATE = textwrap.dedent("""
    from isochor.core import kernels
    from isochor.core.lattice import Lattice
    from isochor.core.scenario.shapes import torus
    from isochor.core.volume import VolumeOperator
    mesh = torus(64, 48)
    lat = Lattice.around(mesh.vertices, (3, 3, 3))
    basis = lat.point_basis(mesh.vertices)
    op = VolumeOperator(mesh.faces, mesh.n_vertices)
    def evaluate():
        v, g = op.value_and_gradient(basis.apply(lat.rest_nodes), mesh.center)
        return v, basis.apply_transpose(g)
""")


def test_without_numba_the_numpy_path_runs():
    out = _child(
        "import sys\nsys.modules['numba'] = None  # import numba fails\n"
        + EVALUATE
        + "v, g = evaluate()\n"
        "print(kernels.ready(60), kernels.status(), repr(v))\n"
    )
    assert out.startswith("False off: numba does not import"), out
    mesh = torus(64, 48)
    assert float(out.split()[-1]) == pytest.approx(signed_volume(mesh.vertices, mesh.faces))


def test_the_environment_variable_switches_the_kernels_off():
    out = _child(
        EVALUATE + "evaluate()\nimport sys\n"
        "print(kernels.ready(60), kernels.status(), 'numba' in sys.modules)\n",
        ISOCHOR_NO_JIT="1",
    )
    assert out.split() == ["False", "off:", "ISOCHOR_NO_JIT", "is", "set", "False"], out


def test_the_first_evaluation_does_not_wait_for_the_compiler():
    """A slow compiler (here: a stand-in that finishes only when the test lets it, after the
    evaluation has returned) never delays an evaluation: they take the NumPy path until it
    is done, then the compiled one. An evaluation that waited would return only after the
    stand-in gave up waiting and had set its kernels. (How long the first evaluation of a
    fresh process takes while the real kernels load: the benchmark's Display rate row.)"""
    out = _child(
        textwrap.dedent("""
        import threading
        from isochor.core import kernels
        let_finish = threading.Event()
        def slow_load():
            let_finish.wait(60)
            kernels._state.kernels = 'stand-in'
        kernels._load = slow_load
        """)
        + EVALUATE
        + textwrap.dedent("""
        evaluate()
        print(kernels.status(), kernels._state.kernels)
        let_finish.set()
        print(kernels.ready(30), kernels._state.kernels)
        """)
    )
    assert out.split() == ["loading", "None", "True", "stand-in"], out


def test_numba_caches_in_a_user_folder(tmp_path):
    pytest.importorskip("numba")
    code = "import os\nfrom isochor.core.kernels import base\nprint(os.environ['NUMBA_CACHE_DIR'])"
    env = {"XDG_CACHE_HOME": str(tmp_path), "NUMBA_CACHE_DIR": ""}
    folder = _child(code, **env).strip()
    assert folder.startswith(str(tmp_path / "isochor" / "numba")), folder
    assert _child(code, NUMBA_CACHE_DIR=str(tmp_path / "mine")).strip() == str(tmp_path / "mine")


def test_the_cache_key_covers_every_kernel_source(tmp_path):
    """numba checks only the time stamp of the file that defines a kernel, so the cache
    folder is named by a hash of the kernel sources: each listed source exists, every
    module that compiles a function is listed, and editing one changes the key."""
    import shutil

    from isochor.core.kernels import base

    folder = Path(base.__file__).resolve().parent
    missing = [name for name in base.SOURCES if not (folder / name).is_file()]
    assert not missing, f"SOURCES names files that do not exist: {missing}"
    compiling = {f.name for f in folder.glob("*.py") if "njit(" in f.read_text()}
    assert compiling - {"base.py"} and compiling <= set(base.SOURCES), compiling
    for name in base.SOURCES:
        shutil.copy(folder / name, tmp_path / name)
    assert base.source_key(tmp_path) == base.source_key()
    keys = {base.source_key()}
    for name in base.SOURCES:
        text = (tmp_path / name).read_text()
        (tmp_path / name).write_text(text + "\n# edited\n")
        keys.add(base.source_key(tmp_path))
        (tmp_path / name).write_text(text)
    assert len(keys) == len(base.SOURCES) + 1  # each edit makes a new folder
    (tmp_path / base.SOURCES[0]).unlink()
    assert base.source_key(tmp_path) not in keys


def test_winding_numbers_match_numpy(compiled):
    """The fold guard's interior samples: the same winding numbers either way, inside,
    outside and near the surface of a torus (a hole) and an open triangle set."""
    from isochor.core.bodies import winding_numbers

    rng = np.random.default_rng(9)
    mesh = torus_levels(3)[-1]
    pts = rng.uniform(-1.5, 1.5, size=(700, 3)) * [1, 1, 0.5]
    pts[:50] = mesh.vertices[:50] * 1.0001  # about half on the surface
    for tri in (mesh.vertices[mesh.faces], mesh.vertices[mesh.faces[::2]]):
        fast = winding_numbers(pts, tri)
        with kernels.numpy_path():
            slow = winding_numbers(pts, tri)
        assert close(fast, slow, 1e-12)
    inside = winding_numbers(pts, mesh.vertices[mesh.faces])
    assert np.any(np.abs(inside) > 0.9) and np.any(np.abs(inside) < 0.1)


def test_one_compiling_child_at_a_time(tmp_path, monkeypatch):
    """Several programs started at once with an empty cache (command-line runs, the test
    suite's subprocesses): the first takes the lock and compiles, the others wait for its
    marker instead of compiling the same kernels again; a stale lock is taken over."""
    import threading
    import time

    marker = tmp_path / "compiled-x"
    lock = tmp_path / "compiled-x.lock"
    assert _jitcache.take(lock) and not _jitcache.take(lock)  # held by "another process"

    def compile_again(*args, **kwargs):
        raise AssertionError("a second child compiled while the first held the lock")

    monkeypatch.setattr("subprocess.run", compile_again)
    threading.Timer(0.8, marker.touch).start()  # the other process's child finishes
    t0 = time.monotonic()
    _jitcache.compile_in_child(marker, kernels.__name__)
    assert marker.exists() and 0.7 <= time.monotonic() - t0 < 30

    old = time.time() - 2 * _jitcache.COMPILE_LIMIT  # a lock left by a killed process
    os.utime(lock, (old, old))
    assert not _jitcache.held(lock) and _jitcache.take(lock) and _jitcache.held(lock)


def test_a_one_shot_command_loads_numba_only_for_a_big_model():
    """``isochor solve`` on an example (65k triangles at most) never imports numba; the
    policy says which sizes wait for it; without the one-shot setting a large evaluation
    starts the kernels by itself (the window and the API)."""
    from tests.fresh import run_fresh

    code = textwrap.dedent(
        """
        import os
        os.environ.pop("ISOCHOR_NO_JIT", None)
        from isochor.app.cli.main import main
        rc = main(["solve", "--example", "club-compression", "-q"])
        from isochor.core import kernels
        print("RC", rc, kernels.status())
        """
    )
    proc, loaded = run_fresh(code, extra=frozenset({"numba"}))
    assert "RC 0 idle" in proc.stdout, proc.stderr
    assert "numba" not in loaded
    assert not kernels.worth(kernels.WORTH_TRIANGLES - 1) and kernels.worth(kernels.WORTH_TRIANGLES)
    code = textwrap.dedent(
        """
        import os
        os.environ.pop("ISOCHOR_NO_JIT", None)
        from isochor.core import kernels
        previous = kernels.set_autostart(False)
        kernels.active(10**6)
        held = kernels.status()
        kernels.set_autostart(previous)
        kernels.active(10**6)
        print("STATES", held, kernels.status())
        """
    )
    proc, _ = run_fresh(code)
    held, after = proc.stdout.split("STATES ")[1].split()[:2]
    assert held == "idle" and after != "idle", proc.stderr  # loading (or failed: no numba)
