"""The memory of L-BFGS (:mod:`isochor.core.solve.lbfgs`): the newest correction pairs and the
two-loop recursion over them, on the NumPy path. The compiled path
(:func:`isochor.core.kernels.step.two_loop`, :func:`isochor.core.kernels.step.push_pair`) works on
the same arrays.
"""

from __future__ import annotations

import numpy as np


class Pairs:
    """The L-BFGS correction pairs ``s = x_new - x``, ``y = g_new - g``: the newest
    ``memory`` of them, rows of two arrays used as a ring (the newest at ``head - 1``),
    with ``rho = 1 / s.y``."""

    def __init__(self, memory: int, n: int) -> None:
        self.s, self.y = np.empty((memory, n)), np.empty((memory, n))
        self.rho, self.alphas = np.empty(memory), np.empty(memory)
        self.head = self.count = 0

    def forget(self) -> None:
        """Drop every pair: the next direction is steepest descent (a restart)."""
        self.count = 0

    def push(self, x_new, x, g_new, g) -> None:
        """Keep the pair ``(x_new - x, g_new - g)`` when its curvature ``s.y`` is positive
        beyond rounding."""
        s, y = x_new - x, g_new - g
        sy = float(s @ y)
        kept = sy > 1e-12 * np.sqrt(float(s @ s) * float(y @ y))
        if kept:
            r = self.head
            self.s[r], self.y[r], self.rho[r] = s, y, 1.0 / sy
        self.stored(kept)

    def stored(self, kept: bool) -> None:
        """A pair was written at ``head`` (``kept``) or dropped."""
        if kept:
            self.head = (self.head + 1) % len(self.rho)
            self.count = min(self.count + 1, len(self.rho))

    def start(self, q: np.ndarray, h0) -> np.ndarray:
        """The recursion's middle: ``h0(q)``, or ``q`` times the newest pair's scaling."""
        if h0 is not None:
            return np.array(h0(q), dtype=np.float64)
        if self.count:
            r = (self.head - 1) % len(self.rho)
            q *= (self.s[r] @ self.y[r]) / (self.y[r] @ self.y[r])
        return q

    def direction(self, q: np.ndarray, h0=None) -> np.ndarray:
        """The L-BFGS search direction ``-H q`` (``q`` is overwritten), ``h0`` the start
        matrix's product or None for the scaled identity."""
        rows = [(self.head - 1 - i) % len(self.rho) for i in range(self.count)]  # newest first
        for i, r in enumerate(rows):
            self.alphas[i] = self.rho[r] * (self.s[r] @ q)
            q -= self.alphas[i] * self.y[r]
        q = self.start(q, h0)
        for i, r in reversed(list(enumerate(rows))):
            q += (self.alphas[i] - self.rho[r] * (self.y[r] @ q)) * self.s[r]
        return -q
