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
        **solver_checks(k, e, rng),
    }
    return ", ".join(name for name, ok in checks.items() if not ok)


def solver_checks(k, e, rng) -> dict[str, bool]:
    """The solver's kernels against their NumPy formulas: two springs on three nodes (one
    stretched, one compressed), and the memory and the two-loop recursion over a ring of
    four pairs that has wrapped around and dropped a pair of negative curvature, with
    each kind of start matrix."""
    from .pairs import Pairs
    from .precondition import Product

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
    springs = e.springs(x, starts, ends, rest, 1.0, k)
    pairs, compiled_pairs = Pairs(4, 5), Pairs(4, 5)
    x0 = np.zeros(5)
    for i in range(7):  # wraps around the ring; the last pair is dropped (s.y < 0)
        s = rng.normal(size=5)
        y = (-1 if i == 6 else 1) * s + 0.1 * rng.normal(size=5)
        pairs.push(s, x0, y, x0)
        compiled_pairs.stored(e.push_pair(compiled_pairs, s, x0, y, x0, k))
    g = rng.normal(size=5)
    spd = np.eye(5) + 0.1 * np.ones((5, 5))
    h0s = {"scaled": None, "matrix": Product(spd), "product": spd.__matmul__}
    return {
        "pairs": compiled_pairs.head == pairs.head
        and np.allclose(compiled_pairs.rho, pairs.rho, rtol=1e-12)
        and np.allclose(compiled_pairs.s, pairs.s),
        **{
            f"two-loop ({name})": np.allclose(
                e.two_loop(pairs, g.copy(), h0, k), pairs.direction(g.copy(), h0), atol=1e-12
            )
            for name, h0 in h0s.items()
        },
        "springs": springs is not None
        and np.isclose(springs[0], 0.5 * np.sum((length - rest) ** 2), rtol=1e-12)
        and np.allclose(springs[1], grad, atol=1e-12),
        "spring hessian": np.allclose(e.spring_hessian(x, starts, ends, rest, 1.0, k), hess),
    }


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
