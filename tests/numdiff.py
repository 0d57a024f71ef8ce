"""Central finite differences for the gradient checks."""

import numpy as np


def central_gradient(f, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Gradient of the scalar ``f`` at ``x`` (any shape) by central differences."""
    x = np.asarray(x, dtype=np.float64)
    grad = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        p, m = x.copy(), x.copy()
        p[idx] += h
        m[idx] -= h
        grad[idx] = (f(p) - f(m)) / (2 * h)
    return grad


def check_vertex_gradient(op, verts: np.ndarray, grad: np.ndarray, rng, h: float = 1e-6):
    """``grad`` (the ``(m, 3)`` gradient of the volume operator ``op`` at ``verts``)
    against central differences at 8 random vertices, every coordinate."""
    for idx in rng.choice(len(verts), 8, replace=False):
        for c in range(3):
            vp, vm = verts.copy(), verts.copy()
            vp[idx, c] += h
            vm[idx, c] -= h
            fd = (op(vp) - op(vm)) / (2 * h)
            assert abs(fd - grad[idx, c]) <= 1e-6 * max(1.0, abs(grad[idx, c]))
