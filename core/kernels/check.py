"""The compiled kernels' self-check (:mod:`core.kernels`): each against NumPy on a tiny case
before they are used. ``e`` is :mod:`core.kernels` itself (passed in: no import
cycle)."""

from __future__ import annotations

from math import comb

import numpy as np


def self_check(k, e) -> str:
    """Compare the kernels with NumPy on a tiny case; '' when they agree."""

    rng = np.random.default_rng(7)
    shape = (3, 4, 2)
    uvw = rng.uniform(size=(3, 50))
    nodes = rng.normal(size=(24, 3))
    bases = [
        np.array([comb(d - 1, i) * u**i * (1 - u) ** (d - 1 - i) for i in range(d)])
        for d, u in zip(shape, uvw)
    ]
    dense = np.einsum("ip,jp,kp->ijkp", *bases).reshape(24, 50)
    got = e.apply(uvw, nodes, shape, k)
    g = rng.normal(size=(3, 50))
    back = e.apply_transpose(uvw, g, shape, k)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    pts = rng.normal(size=(4, 3))
    a, b, c = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
    exact = float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0
    corner = np.zeros((4, 3))  # dV/dP, corner by corner
    np.add.at(corner, faces[:, 0], np.cross(b, c) / 6.0)
    np.add.at(corner, faces[:, 1], np.cross(c, a) / 6.0)
    np.add.at(corner, faces[:, 2], np.cross(a, b) / 6.0)
    vol, grad = e.volume_gradient(e.fans(faces, 4, k), np.ascontiguousarray(pts.T), None, k)
    inside = np.array([[0.1, 0.1, 0.1], [5.0, 5.0, 5.0]]).T.copy()  # in and out of a tetra
    tetra = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    winds = e.winding_numbers(inside, np.ascontiguousarray(tetra[faces].transpose(1, 2, 0)), k)
    to_world = np.linalg.inv(np.diag([2.0, 1.0, 0.5]) + 0.1).T
    grid = nodes.reshape(3, 4, 2, 3)
    dets = e.determinants(uvw, grid, to_world, k)
    jac = (
        np.stack([np.einsum("ijkp,ijka->pa", d, grid) for d in derivatives(bases, shape, uvw)], -1)
        @ to_world
    )
    checks = {
        "det J": dets is not None and np.allclose(dets, np.linalg.det(jac), atol=1e-12),
        "winding": winds is not None and np.allclose(np.abs(winds), [1.0, 0.0], atol=1e-12),
        "apply": np.allclose(got, nodes.T @ dense, rtol=1e-12, atol=1e-12),
        "transpose": np.allclose(back, dense @ g.T, rtol=1e-12, atol=1e-12),
        "volume": abs(vol - exact) <= 1e-12 and np.allclose(grad.T, corner, atol=1e-12),
        "face volume": abs(e.face_volume(faces.T.copy(), pts.T.copy(), None, k) - exact) < 1e-12,
        **solver_checks(k, rng),
    }
    return ", ".join(name for name, ok in checks.items() if not ok)


def solver_checks(k, rng) -> dict[str, bool]:
    """The solver's kernels (:mod:`core.kernels.solver`, called as :mod:`core.kernels.step`
    calls them) against their NumPy formulas: two springs on three nodes (one stretched,
    one compressed), the memory and the two-loop recursion over a ring of four pairs that
    has wrapped around and dropped a pair of negative curvature, with each kind of start
    matrix, and the inverse of a positive definite matrix and the refusal of an
    indefinite one."""
    from .pairs import Pairs

    x = rng.normal(size=(3, 3))
    starts, ends, rest = np.array([0, 1]), np.array([1, 2]), np.array([0.1, 50.0])
    d = x[ends] - x[starts]
    length = np.linalg.norm(d, axis=1)
    force = ((length - rest) / length)[:, None] * d
    grad = np.zeros((3, 3))
    np.add.at(grad, ends, force)
    np.add.at(grad, starts, -force)
    hess = np.zeros((9, 9))
    for a, b, v, l0, l1 in zip(starts, ends, d, rest, length):
        u = np.outer(v, v) / l1**2
        block = u + max(0.0, 1.0 - l0 / l1) * (np.eye(3) - u)
        for p, q, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
            hess[3 * p : 3 * p + 3, 3 * q : 3 * q + 3] += sign * block
    got_grad, got_hess = np.empty((3, 3)), np.empty((9, 9))
    energy = k.spring_energy_gradient(x, starts, ends, rest, 1.0, got_grad)
    k.spring_hessian(x, starts, ends, rest, 1.0, got_hess)
    pairs, compiled = Pairs(4, 5), Pairs(4, 5)
    x0 = np.zeros(5)
    for i in range(7):  # wraps around the ring; the last pair is dropped (s.y < 0)
        s = rng.normal(size=5)
        y = (-1 if i == 6 else 1) * s + 0.1 * rng.normal(size=5)
        pairs.push(s, x0, y, x0)
        compiled.stored(
            k.push_pair(s, x0, y, x0, compiled.s, compiled.y, compiled.rho, compiled.head)
        )
    g = rng.normal(size=5)
    spd = np.eye(5) + 0.1 * np.ones((5, 5))
    ring = (compiled.s, compiled.y, compiled.rho, compiled.head, compiled.count, compiled.alphas)
    directions = {}
    for name, matrix in (("scaled", np.zeros((0, 0))), ("matrix", spd)):
        out = np.empty(5)
        g_max, slope = k.two_loop(g, *ring, matrix, np.empty(5), out)
        directions[name] = out, g_max, slope, None if name == "scaled" else spd.__matmul__
    q = g.copy()  # a start matrix applied outside the kernels, between the two loops
    k.two_loop_first(q, *ring)
    q = spd @ q
    k.two_loop_second(q, *ring)
    directions["product"] = -q, np.abs(g).max(), g @ -q, spd.__matmul__
    inverse, refused = np.empty((5, 5)), np.empty((5, 5))
    return {
        "pairs": compiled.head == pairs.head
        and np.allclose(compiled.rho, pairs.rho, rtol=1e-12)
        and np.allclose(compiled.s, pairs.s),
        **{
            f"two-loop ({name})": _same_direction(got, pairs.direction(g.copy(), h0), g)
            for name, (*got, h0) in directions.items()
        },
        "springs": np.isclose(energy, 0.5 * np.sum((length - rest) ** 2), rtol=1e-12)
        and np.allclose(got_grad, grad, atol=1e-12),
        "spring hessian": np.allclose(got_hess, hess),
        "spd inverse": k.spd_inverse(spd, 1e-6, inverse)
        and np.allclose(inverse @ spd, np.eye(5), atol=1e-5)
        and not k.spd_inverse(spd - 2 * np.eye(5), 1e-6, refused),
    }


def _same_direction(got, d, g) -> bool:
    """A compiled ``(d, max |g|, g . d)`` against the NumPy recursion's ``d``."""
    return (
        np.allclose(got[0], d, atol=1e-12)
        and got[1] == np.abs(g).max()
        and np.isclose(got[2], g @ d, rtol=1e-12)
    )


def derivatives(bases, shape, uvw):
    """d/du, d/dv, d/dw of the tensor basis (l, m, n, p), for the self-check."""

    out = []
    for axis in range(3):
        d, t = shape[axis] - 1, uvw[axis]
        low = [comb(d - 1, i) * t**i * (1 - t) ** (d - 1 - i) for i in range(d)]
        deriv = np.array(
            [d * ((low[i - 1] if i > 0 else 0) - (low[i] if i < d else 0)) for i in range(d + 1)]
        )
        parts = [deriv if a == axis else bases[a] for a in range(3)]
        out.append(np.einsum("ip,jp,kp->ijkp", *parts))
    return out
