"""Blender's lattice bases (issue 26): the formula against an independent transcription of
Blender's Lattice modifier, closed forms, derivatives against finite differences, the
clamped outside behaviour, the compiled kernels against NumPy, the sparse solver paths, and
solves on dense B-spline lattices."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from isochor.core import kernels
from isochor.core import localbasis as lb
from isochor.core.errors import IsochorError
from isochor.core.goal.constraints import Level
from isochor.core.goal.folds import FoldGuard, jacobian_determinants
from isochor.core.goal.handles import Handle, handle_rows
from isochor.core.lattice import Lattice
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build
from isochor.core.scenario.shapes import sphere_levels
from isochor.core.solve.multilevel import EmbeddedSurface, solve
from isochor.core.solve.precondition import Curvature, dissection
from isochor.core.springs import SpringNetwork
from tests.numdiff import central_gradient
from tests.test_solver import _constrained_energy_check, run

LOCAL = ("linear", "cardinal", "catmull-rom", "bspline")

# -- an independent transcription of Blender's Lattice modifier, float64 ------------------
#: key_curve_position_weights (key.cc) as matrices: weight a = sum_p M[a, p] t^p
_FC = {"cardinal": 0.71, "catmull-rom": 0.5}


def _blender_matrix(kind: str) -> np.ndarray:
    if kind == "linear":
        return np.array([[0, 0, 0, 0], [1, -1, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]], float)
    if kind == "bspline":
        return np.array([[1, -3, 3, -1], [4, 0, -6, 3], [1, 3, 3, -3], [0, 0, 0, 1]]) / 6.0
    fc = _FC[kind]
    return np.array(
        [
            [0, -fc, 2 * fc, -fc],
            [1, 0, fc - 3, 2 - fc],
            [0, fc, 3 - 2 * fc, fc - 2],
            [0, 0, -fc, fc],
        ]
    )


def blender_deform(kinds, counts, matrix, points_world, nodes_world, outside=False):
    """Blender's ``BKE_lattice_deform_data_create`` + ``..._eval_co`` for a lattice object
    whose ``object_to_world`` is ``matrix`` (4x4) deforming a mesh object at the identity.
    ``nodes_world`` in Blender's point order (u fastest). A plain loop, as Blender runs it."""
    pu, pv, pw = counts
    latmat = np.linalg.inv(matrix)  # world -> lattice space
    imat3 = matrix[:3, :3]  # back: lattice-space vectors -> world

    def fd(res):  # calc_lat_fudu with the lattice object given (BKE_lattice_resize)
        return (-0.5, 1.0 / (res - 1)) if res > 1 else (0.0, 0.0)

    (fu, du), (fv, dv), (fw, dw) = fd(pu), fd(pv), fd(pw)
    local = (np.c_[nodes_world, np.ones(len(nodes_world))] @ latmat.T)[:, :3]
    if outside:  # outside_lattice (lattice.cc)
        local = local.copy()
        idx = lambda u, v, w: (w * pv + v) * pu + u  # noqa: E731
        for w in range(pw):
            for v in range(pv):
                for u in range(pu):
                    if 0 in (u, v, w) or u == pu - 1 or v == pv - 1 or w == pw - 1:
                        continue
                    f = u / (pu - 1)
                    vec = (1 - f) * local[idx(0, v, w)] + f * local[idx(pu - 1, v, w)]
                    f = v / (pv - 1)
                    vec = vec + (1 - f) * local[idx(u, 0, w)] + f * local[idx(u, pv - 1, w)]
                    f = w / (pw - 1)
                    vec = vec + (1 - f) * local[idx(u, v, 0)] + f * local[idx(u, v, pw - 1)]
                    local[idx(u, v, w)] = vec / 3.0
    data = np.empty_like(local)
    i = 0
    for w in range(pw):
        for v in range(pv):
            for u in range(pu):
                rest = np.array([fu + u * du, fv + v * dv, fw + w * dw])
                data[i] = imat3 @ (local[i] - rest)
                i += 1
    out = []
    for co in points_world:
        vec = (latmat @ np.r_[co, 1.0])[:3]
        t, base = [], []
        for c, (res, f0, d, kind) in enumerate(zip(counts, (fu, fv, fw), (du, dv, dw), kinds)):
            if res > 1:
                x = (vec[c] - f0) / d
                b = int(np.floor(x))
                x -= b
                t.append(_blender_matrix(kind) @ np.array([1.0, x, x * x, x**3]))
                base.append(b)
            else:
                t.append(np.array([0.0, 1.0, 0.0, 0.0]))
                base.append(0)
        (tu, tv, tw), (ui, vi, wi) = t, base
        res = np.array(co, dtype=float)
        for ww in range(wi - 1, wi + 3):
            idx_w = min(max(ww * pu * pv, 0), (pw - 1) * pu * pv)
            for vv in range(vi - 1, vi + 3):
                idx_v = min(max(vv * pu, 0), (pv - 1) * pu)
                for uu in range(ui - 1, ui + 3):
                    idx_u = min(max(uu, 0), pu - 1)
                    weight = tw[ww - wi + 1] * tv[vv - vi + 1] * tu[uu - ui + 1]
                    res += weight * data[idx_w + idx_v + idx_u]
        out.append(res)
    return np.array(out)


def _to_blender_order(lattice: Lattice, nodes: np.ndarray) -> np.ndarray:
    """Isochor's node rows (i slowest) in Blender's point order (u fastest)."""
    out = nodes.reshape(*lattice.shape, 3).transpose(2, 1, 0, 3).reshape(-1, 3)
    assert np.array_equal(out, nodes[lb.blender_order(lattice.shape)])
    return out


def _frame(rng):
    """A sheared, rotated, offset lattice frame and its Blender object matrix."""
    axes = np.diag([2.0, 1.2, 0.8]) + 0.2 * rng.standard_normal((3, 3))
    origin = np.array([0.3, -1.0, 2.0])
    matrix = np.eye(4)
    matrix[:3, :3] = axes.T  # lattice-space unit steps along u, v, w are the rows of axes
    matrix[:3, 3] = origin + 0.5 * axes.sum(axis=0)  # lattice space is centred: -0.5..0.5
    return origin, axes, matrix


@pytest.mark.parametrize(
    "kinds, counts",
    [
        (("bspline",) * 3, (4, 4, 4)),
        (("catmull-rom",) * 3, (10, 6, 6)),
        (("cardinal",) * 3, (3, 5, 2)),
        (("linear",) * 3, (2, 7, 3)),
        (("bspline", "linear", "catmull-rom"), (6, 1, 5)),
        (("cardinal", "bspline", "linear"), (1, 64, 2)),
    ],
)
def test_the_basis_is_blenders_lattice_modifier(kinds, counts):
    rng = np.random.default_rng(sum(counts))
    origin, axes, matrix = _frame(rng)
    lattice = Lattice(counts, *lb.blender_frame(matrix), kinds)
    assert np.allclose(lattice.origin, origin) and np.allclose(lattice.axes, axes)
    # inside, on the faces, and outside the box (near and far)
    uvw = np.vstack(
        [rng.uniform(0, 1, (40, 3)), rng.uniform(-0.4, 1.4, (40, 3)), rng.uniform(-6, 7, (10, 3))]
    )
    uvw[:5, 0] = [0.0, 1.0, 0.5, 0.25, 1.0 / 3.0]
    points = origin + uvw @ axes
    nodes = lattice.rest_nodes + 0.1 * rng.standard_normal((lattice.n_nodes, 3))
    want = blender_deform(kinds, counts, matrix, points, _to_blender_order(lattice, nodes))
    size = lattice.size
    for path in ("numpy", "auto"):
        with kernels.numpy_path() if path == "numpy" else _Nothing():
            got = lattice.deform(points, nodes)
        assert np.abs(got - want).max() <= 1e-12 * size * 100


class _Nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_blenders_outside_option_derives_the_inner_nodes_from_the_faces():
    rng = np.random.default_rng(3)
    origin, axes, matrix = _frame(rng)
    kinds, counts = ("bspline", "catmull-rom", "linear"), (5, 4, 6)
    lattice = Lattice(counts, origin, axes, kinds, outside=True)
    nodes = lattice.rest_nodes + 0.1 * rng.standard_normal((lattice.n_nodes, 3))
    points = origin + rng.uniform(-0.2, 1.2, (60, 3)) @ axes
    want = blender_deform(
        kinds, counts, matrix, points, _to_blender_order(lattice, nodes), outside=True
    )
    assert np.abs(lattice.deform(points, nodes) - want).max() <= 1e-11 * lattice.size
    # the rest lattice is the identity; moving an inner node changes nothing
    assert np.abs(lattice.deform(points, lattice.rest_nodes) - points).max() < 1e-12
    inner = lattice.index(2, 1, 3)
    moved = nodes.copy()
    moved[inner] += 5.0
    assert np.array_equal(lattice.deform(points, moved), lattice.deform(points, nodes))
    # its effective place is the faces' blend
    assert not np.allclose(lattice.effective_nodes(nodes)[inner], nodes[inner])
    with pytest.raises(IsochorError, match="local basis"):
        Lattice(counts, origin, axes, "bernstein", outside=True)


# -- closed forms ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", LOCAL)
def test_weights_are_a_partition_of_unity_inside_and_out(kind):
    rng = np.random.default_rng(1)
    lattice = Lattice((5, 3, 7), (0, 0, 0), np.eye(3), kind)
    uvw = rng.uniform(-3, 4, (300, 3))
    w, _ = lattice.weights(uvw)
    assert np.allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0, atol=1e-14)
    # a translation of every node moves every point by it
    shift = np.array([0.3, -2.0, 1.0])
    moved = lattice.deform(uvw, lattice.rest_nodes + shift)
    assert np.abs(moved - uvw - shift).max() < 1e-13


@pytest.mark.parametrize("kind", ["linear", "catmull-rom", "bspline"])
def test_linear_maps_are_reproduced_where_the_basis_has_it(kind):
    """An affine map of the nodes maps the points by it: in the whole box for the linear
    basis, away from the first and last cell for the cubics (their windows are clamped at
    the edges); the cardinal spline (tension 0.71) has no linear precision."""
    rng = np.random.default_rng(2)
    lattice = Lattice((6, 5, 7), (1.0, 0.0, -1.0), np.diag([2.0, 1.0, 3.0]), kind)
    inner = 0.0 if kind == "linear" else 1.0
    lo = inner / (np.array(lattice.shape) - 1)
    uvw = rng.uniform(lo, 1 - lo, (200, 3))
    points = lattice.origin + uvw @ lattice.axes
    a = np.array([[1.1, 0.2, 0.0], [0.0, 0.9, 0.3], [0.1, 0.0, 1.2]])
    b = np.array([0.5, -1.0, 2.0])
    got = lattice.deform(points, lattice.rest_nodes @ a.T + b)
    assert np.abs(got - (points @ a.T + b)).max() < 1e-12 * 10
    # the cardinal spline misses it by far more than rounding
    cardinal = lattice.like(basis="cardinal")
    miss = np.abs(cardinal.deform(points, lattice.rest_nodes @ a.T + b) - (points @ a.T + b))
    assert miss.max() > 1e-4


def test_far_outside_a_point_moves_with_the_nearest_face_or_corner():
    rng = np.random.default_rng(4)
    lattice = Lattice((4, 5, 6), (0, 0, 0), np.eye(3), "bspline")
    nodes = lattice.rest_nodes + 0.1 * rng.standard_normal((lattice.n_nodes, 3))
    d = (nodes - lattice.rest_nodes).reshape(4, 5, 6, 3)
    corner = np.array([[-9.0, 12.0, -7.0]])  # beyond the corner (0, 4, 0)
    assert np.allclose(lattice.deform(corner, nodes) - corner, d[0, 4, 0], atol=1e-14)
    face = np.array([[-20.0, 0.5, 0.5]])  # beyond the face i = 0: its nodes only
    w, _ = lattice.weights(face)
    support = lattice.grid_parameters()[w.toarray()[0] != 0]
    assert len(support) > 1 and np.all(support[:, 0] == 0)
    # between the two: the same as at the face itself (the window is clamped)
    at_face = np.array([[0.0, 0.5, 0.5]])
    beyond = np.array([[-0.5, 0.5, 0.5]])
    shift = lattice.deform(beyond, nodes) - beyond
    assert np.allclose(shift, lattice.deform(face, nodes) - face)
    assert not np.allclose(shift, lattice.deform(at_face, nodes) - at_face)


def test_one_node_axes_and_node_count_limits():
    lattice = Lattice((1, 3, 64), (0, 0, 0), np.eye(3), "bspline")
    assert np.allclose(lattice.rest_nodes[:, 0], 0.5)
    nodes = lattice.rest_nodes.copy()
    nodes[:, 0] += 0.25  # the one node along x moves every point along x
    pts = np.random.default_rng(5).uniform(0, 1, (20, 3))
    assert np.allclose(lattice.deform(pts, nodes) - pts, [0.25, 0, 0])
    with pytest.raises(IsochorError, match="1 to 64"):
        Lattice((1, 3, 65), (0, 0, 0), np.eye(3), "bspline")
    with pytest.raises(IsochorError, match="2 to 10"):
        Lattice((1, 3, 3), (0, 0, 0), np.eye(3))
    with pytest.raises(IsochorError, match="cannot be mixed"):
        Lattice((3, 3, 3), (0, 0, 0), np.eye(3), ("bernstein", "bspline", "bspline"))
    with pytest.raises(IsochorError, match="Unknown lattice basis"):
        Lattice((3, 3, 3), (0, 0, 0), np.eye(3), "nurbs")
    assert Lattice((3, 3, 3), (0, 0, 0), np.eye(3), "B-Spline").basis == ("bspline",) * 3
    # Blender's frame of a lattice with one point along v: the unit extent, centred on it
    origin, axes = lb.blender_frame(np.eye(4), (-0.5, 0.0, -1.5), (0.5, 0.0, 1.5))
    assert np.allclose(origin, [-0.5, -0.5, -1.5]) and np.allclose(axes, np.diag([1, 1, 3]))


# -- derivatives -----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", LOCAL)
def test_key_derivatives_match_finite_differences(kind):
    f = np.linspace(0.01, 0.99, 23)
    h = 1e-6
    fd = (lb.key_weights(kind, f + h) - lb.key_weights(kind, f - h)) / (2 * h)
    assert np.abs(fd - lb.key_derivatives(kind, f)).max() < 1e-8


@pytest.mark.parametrize("kinds", [("bspline",) * 3, ("catmull-rom", "linear", "cardinal")])
def test_jacobian_and_its_determinant_match_finite_differences(kinds):
    rng = np.random.default_rng(6)
    lattice = Lattice((5, 4, 6), (0.2, 0.1, 0.0), np.diag([2.0, 1.0, 1.5]) + 0.1, kinds)
    nodes = lattice.rest_nodes + 0.05 * rng.standard_normal((lattice.n_nodes, 3))
    # away from the cells' faces, where the cubic pieces join (derivatives agree only to C1)
    uvw = (np.floor(rng.uniform(0, 4, (12, 3))) + rng.uniform(0.2, 0.8, (12, 3))) / 4
    uvw[:3] = uvw[:3] * 1.6 - 0.3  # some outside the box
    points = lattice.origin + uvw @ lattice.axes
    jac = lattice.jacobian(points, nodes)
    h = 1e-6
    for b in range(3):
        e = np.zeros(3)
        e[b] = h
        fd = (lattice.deform(points + e, nodes) - lattice.deform(points - e, nodes)) / (2 * h)
        assert np.abs(fd - jac[:, :, b]).max() < 1e-7
    dets = jacobian_determinants(lattice, points, nodes)
    assert np.allclose(dets, np.linalg.det(jac), atol=1e-12)
    with kernels.numpy_path():
        assert np.allclose(jacobian_determinants(lattice, points, nodes), dets, atol=1e-12)
    assert np.allclose(jacobian_determinants(lattice, points, lattice.rest_nodes), 1.0)


def test_volume_gradient_with_a_local_basis_matches_finite_differences():
    mesh = sphere_levels(3)[-1]
    lattice = Lattice.around(mesh.vertices, (4, 5, 4), 0.1, "bspline")
    level = Level(lattice, mesh, mesh.vertices.mean(axis=0))
    rng = np.random.default_rng(7)
    nodes = lattice.rest_nodes + 0.03 * rng.standard_normal((lattice.n_nodes, 3))
    _, grad = level.volume_and_gradient(nodes)
    rows = rng.choice(lattice.n_nodes, 6, replace=False)

    def volume_of(sub):
        x = nodes.copy()
        x[rows] = sub
        return level.volume_op(lattice.deform(mesh.vertices, x), level.center)

    fd = central_gradient(volume_of, nodes[rows], h=1e-6)
    assert np.abs(fd - grad[rows]).max() <= 1e-6 * max(1.0, np.abs(grad).max())
    with kernels.numpy_path():
        _, slow = level.volume_and_gradient(nodes)
    assert np.allclose(slow, grad, rtol=1e-10, atol=1e-12)


def test_the_fold_guard_and_the_handles_on_a_local_basis_match_finite_differences():
    rng = np.random.default_rng(8)
    lattice = Lattice((5, 4, 4), (0, 0, 0), np.eye(3), "bspline", outside=True)
    samples = rng.uniform(0.05, 0.95, (40, 3))
    guard = FoldGuard(lattice, samples, margin=2.0, weight=1.0)  # every sample within it
    nodes = lattice.rest_nodes + 0.05 * rng.standard_normal((lattice.n_nodes, 3))
    value, grad = guard.value_and_gradient(nodes)
    assert value > 0
    assert np.allclose(guard.determinants(nodes), jacobian_determinants(lattice, samples, nodes))
    rows = rng.choice(lattice.n_nodes, 5, replace=False)

    def penalty(sub):
        x = nodes.copy()
        x[rows] = sub
        return guard.value_and_gradient(x)[0]

    fd = central_gradient(penalty, nodes[rows], h=1e-6)
    assert np.abs(fd - grad[rows]).max() < 1e-6
    gn = guard.gauss_newton(nodes)
    assert gn.shape == (3 * lattice.n_nodes,) * 2 and np.allclose(gn, gn.T)
    assert np.linalg.eigvalsh(gn).min() > -1e-9
    # the handles: linear equations rows . X = b that the deformation meets
    at = lattice.origin + rng.uniform(0.1, 0.9, (2, 3))
    handles = [Handle(tuple(a), tuple(p)) for a, p in zip(at, lattice.deform(at, nodes))]
    eq, b = handle_rows(lattice, handles)
    assert np.allclose(np.einsum("hna,na->h", eq, nodes), b, atol=1e-12)


# -- the kernels and the sparse paths ------------------------------------------------------
def test_compiled_kernels_agree_with_the_numpy_path():
    if not kernels.ready(120):
        pytest.skip(f"compiled kernels not available: {kernels.status()}")
    rng = np.random.default_rng(9)
    lattice = Lattice((7, 3, 9), (0, 0, 0), np.eye(3), ("bspline", "linear", "cardinal"))
    uvw = rng.uniform(-0.5, 1.5, (lb.BLOCK + 77, 3))
    basis = lattice.point_basis(uvw)
    nodes = lattice.rest_nodes + 0.1 * rng.standard_normal((lattice.n_nodes, 3))
    g = np.asfortranarray(rng.standard_normal(uvw.shape))
    fast = basis.apply(nodes), basis.apply_transpose(g)
    with kernels.numpy_path():
        slow = basis.apply(nodes), basis.apply_transpose(g)
    assert np.abs(fast[0] - slow[0]).max() < 1e-13
    assert np.abs(fast[1] - slow[1]).max() < 1e-11
    # the transpose is the adjoint of apply's linear part
    d = rng.standard_normal(nodes.shape)
    lin = basis.apply(lattice.rest_nodes + d) - uvw
    assert np.isclose(np.sum(lin * g), np.sum(d * fast[1]), rtol=1e-12)


def test_sparse_springs_hessian_and_curvature_equal_the_dense_ones(monkeypatch):
    import isochor.core.solve.precondition as precondition
    import isochor.core.springs as springs_module

    lattice = Lattice((5, 4, 3), (0, 0, 0), np.eye(3), "bspline")
    net = SpringNetwork.for_lattice(lattice.shape, lattice.rest_nodes)
    rng = np.random.default_rng(10)
    x = lattice.rest_nodes + 0.05 * rng.standard_normal((lattice.n_nodes, 3))
    dense = net.hessian(x)
    monkeypatch.setattr(springs_module, "SPARSE_VARIABLES", 10)
    sparse = net.hessian(x)
    assert sp.issparse(sparse) and np.allclose(sparse.toarray(), dense, atol=1e-14)
    keep = np.arange(12, 3 * lattice.n_nodes)  # the first 4 nodes fixed
    a = dense[np.ix_(keep, keep)]
    order = np.argsort(rng.random(len(keep)))
    dense_c = Curvature(a)
    sparse_c = Curvature(sp.csr_matrix(a), order)
    assert sparse_c.sparse and sparse_c.ok
    b = rng.standard_normal(len(keep))
    want = dense_c.solve(b)  # float32 factors: a preconditioner, not an exact solve
    assert np.linalg.norm(sparse_c.solve(b) - want) <= 1e-3 * np.linalg.norm(want)
    order = dissection((5, 4, 3))
    assert sorted(order) == list(range(60))
    # whole nodes: the blocks' third of the trace, exact where the blocks are isotropic
    monkeypatch.setattr(precondition, "NODE_FACTOR", 10)
    graph = sp.csr_matrix(net.hessian(x)[0::3, 0::3] + np.eye(lattice.n_nodes))
    iso = sp.kron(graph, sp.identity(3), format="csr")
    nodes_order = np.repeat(3 * order, 3) + np.tile(np.arange(3), len(order))
    node_c = Curvature(iso, nodes_order, whole_nodes=True)
    b = rng.standard_normal((3 * lattice.n_nodes, 2))
    want = np.linalg.solve(iso.toarray(), b)
    assert node_c.sparse and np.linalg.norm(node_c.solve(b) - want) <= 1e-4 * np.linalg.norm(want)
    # on the springs' anisotropic blocks it is an approximation, still positive definite
    approx = Curvature(sp.csr_matrix(dense + 1e-3 * np.eye(len(dense))), None, whole_nodes=True)
    v = rng.standard_normal(len(dense))
    assert approx.sparse and float(v @ approx.solve(v)) > 0


# -- the scenario ----------------------------------------------------------------------------
def test_scenario_lattice_basis_reads_writes_and_names_its_errors():
    doc = {
        "model": {"builtin": "sphere", "n_levels": 3},
        "lattice": {"nodes": [12, 3, 1], "basis": ["bspline", "linear", "catmull-rom"]},
    }
    sc = Scenario.from_dict(doc)
    assert sc.lattice_basis == ("bspline", "linear", "catmull-rom") and not sc.lattice_outside
    again = Scenario.from_dict(sc.to_dict())
    assert again.lattice_basis == sc.lattice_basis and again.lattice_nodes == (12, 3, 1)
    one = Scenario.from_dict({**doc, "lattice": {"nodes": [4, 4, 4], "basis": "bspline"}})
    assert one.to_dict()["lattice"]["basis"] == "bspline"
    plain = Scenario.from_dict({**doc, "lattice": {"nodes": [3, 3, 3]}})
    assert "basis" not in plain.to_dict()["lattice"]  # old files stay as they were
    bad = [
        ({"nodes": [12, 3, 3]}, "lattice.nodes: each axis needs 2 to 10"),
        ({"nodes": [3, 3, 65], "basis": "linear"}, "lattice.nodes: each axis needs 1 to 64"),
        ({"nodes": [3, 3, 3], "basis": "spline"}, "lattice.basis: Unknown"),
        ({"nodes": [3, 3, 3], "basis": ["bspline"]}, "lattice.basis: A lattice basis is one"),
        ({"nodes": [3, 3, 3], "outside": True}, "lattice.outside: needs a local basis"),
        ({"nodes": [3, 3, 3], "basis": "linear", "outside": 1}, "lattice.outside: must be"),
    ]
    for lat, message in bad:
        with pytest.raises(IsochorError, match=message):
            Scenario.from_dict({**doc, "lattice": lat})


# -- solves ----------------------------------------------------------------------------------
def _dense_problem(shape, kind="bspline", n_levels=4):
    scenario = Scenario(
        {"builtin": "sphere", "n_levels": n_levels}, lattice_nodes=shape, lattice_basis=(kind,) * 3
    )
    problem = build(scenario)
    lattice = problem.surface.lattice
    fixed = problem.fixed.copy()
    fixed[lattice.grid_parameters()[:, 2] == 0] = True  # the bottom layer
    nodes = problem.nodes.copy()
    top = lattice.index(shape[0] // 2, shape[1] // 2, shape[2] - 1)
    nodes[top, 2] += 0.2 * lattice.size
    fixed[top] = True
    return problem, nodes, fixed


@pytest.mark.parametrize("shape", [(6, 6, 6), (11, 10, 10)])
def test_a_dense_bspline_lattice_solve_meets_the_volume_at_a_constrained_minimum(shape):
    """6x6x6 takes the dense curvature, 11x10x10 (3300 coordinates) the sparse one."""
    problem, nodes, fixed = _dense_problem(shape)
    surface = problem.surface
    _, result = run(solve(surface, nodes, fixed))
    assert result.converged, result.message
    assert abs(result.rel_volume_error) <= problem.options.tol_volume
    assert np.array_equal(result.nodes[fixed.any(axis=1)], nodes[fixed.any(axis=1)])
    moved = np.abs(result.nodes - nodes).max(axis=1)
    assert moved[~fixed.any(axis=1)].max() > 1e-3 * surface.size  # the free nodes worked
    problem = replace(problem, fixed=fixed)
    _constrained_energy_check(problem, result, np.random.default_rng(11))


def test_session_and_deform_take_the_basis():
    import isochor

    levels = sphere_levels(3)
    mesh = (levels[-1].vertices, levels[-1].faces)
    s = isochor.Session(mesh, lattice=(5, 5, 5), basis="catmull-rom")
    assert s.lattice.basis == ("catmull-rom",) * 3
    s.move((4, 2, 2), by=(0.3, 0.0, 0.0))
    s.pin((0, 2, 2))
    assert s.solve().converged
    assert s.report["lattice_basis"] == ["catmull-rom"] * 3
    out = isochor.deform(mesh, (3, 1, 3), basis=("linear", "bspline", "linear"), moves={})
    assert out.converged
    with pytest.raises(IsochorError, match="lattice.basis"):
        isochor.Session(mesh, lattice=(3, 3, 3), basis="nurbs")


def test_surface_levels_with_a_local_basis_evaluate_as_the_lattice_deforms():
    mesh = sphere_levels(2)[-1]
    lattice = Lattice.around(mesh.vertices, (6, 6, 6), 0.05, "bspline")
    surface = EmbeddedSurface(lattice, sphere_levels(2))
    rng = np.random.default_rng(12)
    nodes = lattice.rest_nodes + 0.02 * rng.standard_normal((lattice.n_nodes, 3))
    full = surface.level(len(surface.levels) - 1)
    want = lattice.deform(mesh.vertices, nodes)
    assert np.allclose(full.basis.apply(nodes), want, atol=1e-14)


def test_a_live_frame_on_a_dense_local_lattice_moves_the_nodes_near_the_drag_only():
    from isochor.core.solve.multilevel import LIVE_REACH

    problem, nodes, fixed = _dense_problem((11, 10, 10))
    _, start = run(solve(problem.surface, nodes, fixed))
    lattice = problem.surface.lattice
    top = lattice.index(5, 5, 9)
    x = np.array(start.nodes)
    x[top] += 0.01 * lattice.size
    _, frame = run(solve(problem.surface, x, fixed, live=True))
    assert frame.converged and frame.preview
    assert abs(frame.rel_volume_error) <= problem.options.tol_volume
    moved = np.abs(frame.nodes - x).max(axis=1) > 0
    ijk = np.indices(lattice.shape).reshape(3, -1).T
    reach = np.abs(ijk - ijk[top]).max(axis=1)
    assert moved.any() and reach[moved].max() <= LIVE_REACH
    # the solve when the drag ends moves the others too
    _, release = run(solve(problem.surface, np.array(frame.nodes), fixed, near=True))
    assert release.converged
    far = np.abs(release.nodes - frame.nodes).max(axis=1) > 0
    assert reach[far].max() > LIVE_REACH


def test_the_command_line_solves_on_another_basis_and_names_a_bad_one(tmp_path, capsys):
    from isochor.app.cli.main import main

    report = tmp_path / "report.json"
    out = tmp_path / "out.ply"
    args = ["solve", "--example", "torus-compression", "-q", "--report", str(report)]
    assert main([*args, "--basis", "bspline", "--out", str(out)]) == 0
    doc = json.loads(report.read_text())
    assert doc["lattice_basis"] == ["bspline"] * 3 and doc["converged"]
    assert out.stat().st_size > 0
    report.unlink()
    out.unlink()
    capsys.readouterr()
    assert main([*args, "--basis", "bspline,nurbs,linear", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--basis bspline,nurbs,linear: Unknown lattice basis 'nurbs'" in err[0]
    assert not report.exists() and not out.exists()  # nothing written
    # Blender's "Outside" option: with a local basis, and refused (one line) on Bernstein
    assert main([*args, "--basis", "bspline", "--outside", "--out", str(out)]) == 0
    doc = json.loads(report.read_text())
    assert doc["lattice_outside"] is True and doc["converged"]
    report.unlink()
    out.unlink()
    capsys.readouterr()
    assert main([*args, "--outside", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--outside: needs a local basis" in err[0], err
    assert not report.exists() and not out.exists()


def _layer_pushed(n: int, push: float):
    """A uv sphere (8k vertices) in an n^3 B-spline lattice, the bottom layer pinned and the
    whole top layer pushed down ``push`` of the lattice's height (fixed there)."""
    trimesh = pytest.importorskip("trimesh")
    from isochor import Session

    s = Session(trimesh.creation.uv_sphere(count=(64, 64)), lattice=(n, n, n), basis="bspline")
    lattice = s.lattice
    row = lattice.grid_parameters()[:, 1]
    s.fixed[row == 0] = True
    top = row == row.max()
    s.nodes[top, 1] -= push * np.ptp(lattice.rest_nodes[:, 1])
    s.fixed[top] = True
    return s


def test_a_whole_layer_pushed_through_a_dense_lattice_converges_unfolded():
    """The top layer of a 16^3 lattice pushed down a quarter of the height (through three
    layers of free nodes). The fold guard's samples come from a level with at least
    ``PROBE_PER_CELL`` triangles a cell: with the old 1000 (3175 samples for 3375 cells)
    det J fell from the guard's margin to -0.025 between them and the result was folded."""
    from isochor.core.solve.surface import PROBE_PER_CELL

    s = _layer_pushed(16, 0.25)
    surface = s.problem.surface
    assert surface.lattice_cells == 15**3
    assert surface.fold_guard(0.05).n_points >= PROBE_PER_CELL * 15**3 / 2  # a vertex a cell
    start = surface.springs.energy(s.nodes) / surface.size**2
    fixed_rows = s.fixed.any(axis=1)
    pushed = s.nodes[fixed_rows].copy()
    result = s.solve()
    assert result.converged, result.message
    assert abs(result.rel_volume_error) <= s.problem.options.tol_volume
    assert not result.folds.folded and result.folds.min_det > 0
    assert np.array_equal(result.nodes[fixed_rows], pushed)
    assert result.energy < start  # the free nodes took up the push


@pytest.mark.parametrize("kinds", [("bspline",) * 3, ("linear", "cardinal", "catmull-rom")])
def test_compiled_determinants_agree_with_the_numpy_path_to_their_rounding_bound(kinds):
    """The kernel sums the tensor product's derivatives separably (w, then v, then u), the
    NumPy path the 64 products at once: both are sums of 64 products of three weights and a
    displacement, so each entry of ``ju`` differs by at most ``2 * 12 u * S`` (``S`` the sum
    of the products' magnitudes, 12 roundings on the longer path: 3 products, 4 + 4 + 4
    additions; u = 2^-53) and det J, to first order, by ``sum |cof| |dJ|`` plus the
    rounding of the determinant itself (at most ``16 u`` of the columns' lengths' product,
    Hadamard)."""
    if not kernels.ready(120):
        pytest.skip(f"compiled kernels not available: {kernels.status()}")
    rng = np.random.default_rng(17)
    lattice = Lattice((9, 5, 7), (0, 0, 0), np.diag([2.0, 1.0, 1.5]), kinds)
    uvw_t = np.ascontiguousarray(rng.uniform(-0.2, 1.2, (3, 3000)))
    disp = 0.05 * rng.standard_normal((lattice.n_nodes, 3))
    to_world = np.linalg.inv(lattice.axes).T
    fast, squares = kernels.local_determinants(
        uvw_t, lb.codes(kinds), disp, lattice.shape, to_world, frobenius=True
    )
    with kernels.numpy_path():
        slow = lb.determinants(kinds, lattice.shape, uvw_t, disp, to_world)
    jac = lb.world_jacobians(kinds, lattice.shape, uvw_t, disp, to_world)
    rows, _, deriv = lb.windows(kinds, lattice.shape, uvw_t)
    s = np.einsum("epk,pka->epa", np.abs(deriv), np.abs(disp)[rows])  # (e, p, a)
    u = np.finfo(float).eps / 2
    d_jac = 24 * u * np.einsum("epa,eb->pab", s, np.abs(to_world))  # (p, a, b)
    cof = np.linalg.det(jac)[:, None, None] * np.linalg.inv(jac).transpose(0, 2, 1)
    columns = np.prod(np.linalg.norm(jac, axis=1), axis=1)
    bound = np.sum(np.abs(cof) * d_jac, axis=(1, 2)) + 16 * u * columns
    assert np.all(np.abs(fast - slow) <= bound)
    assert np.allclose(squares, np.sum(jac * jac, axis=(1, 2)), rtol=1e-13)
