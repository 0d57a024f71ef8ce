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
