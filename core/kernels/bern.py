"""Bernstein polynomials for the compiled basis kernels (:mod:`core.kernels.basis`).

``B_i^d(t) = C(d, i) t^i (1 - t)^(d - i)``, the formula of :func:`core.lattice.bernstein`
(same products in the same order, powers by repeated multiplication: the values agree to
an ulp or two). One loop per degree, written out, so that the loop over the points
vectorises with the powers in registers (a loop over ``i`` inside would not). Degrees 1 to
9: a lattice has 2 to 10 nodes per axis.
"""

from __future__ import annotations

from .base import INLINE, njit


@njit(**INLINE)
def _bernstein(t, w, d, out):
    """``out[i, q] = B_i^d(t[q])`` for i = 0..d (d = 1..9), one vector loop per degree: the
    powers of t and 1 - t stay in registers."""
    if d == 1:
        o0, o1 = out[0], out[1]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            o0[q] = y
            o1[q] = x
    elif d == 2:
        o0, o1, o2 = out[0], out[1], out[2]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            y2 = y * y
            o0[q] = y2
            o1[q] = 2.0 * x * y
            o2[q] = x2
    elif d == 3:
        o0, o1, o2, o3 = out[0], out[1], out[2], out[3]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            y2 = y * y
            y3 = y2 * y
            o0[q] = y3
            o1[q] = 3.0 * x * y2
            o2[q] = 3.0 * x2 * y
            o3[q] = x3
    elif d == 4:
        o0, o1, o2, o3, o4 = out[0], out[1], out[2], out[3], out[4]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            x4 = x2 * x2
            y2 = y * y
            y3 = y2 * y
            y4 = y2 * y2
            o0[q] = y4
            o1[q] = 4.0 * x * y3
            o2[q] = 6.0 * x2 * y2
            o3[q] = 4.0 * x3 * y
            o4[q] = x4
    elif d == 5:
        o0, o1, o2, o3, o4 = out[0], out[1], out[2], out[3], out[4]
        o5 = out[5]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            x4 = x2 * x2
            x5 = x4 * x
            y2 = y * y
            y3 = y2 * y
            y4 = y2 * y2
            y5 = y4 * y
            o0[q] = y5
            o1[q] = 5.0 * x * y4
            o2[q] = 10.0 * x2 * y3
            o3[q] = 10.0 * x3 * y2
            o4[q] = 5.0 * x4 * y
            o5[q] = x5
    elif d == 6:
        o0, o1, o2, o3, o4 = out[0], out[1], out[2], out[3], out[4]
        o5, o6 = out[5], out[6]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            x4 = x2 * x2
            x5 = x4 * x
            x6 = x3 * x3
            y2 = y * y
            y3 = y2 * y
            y4 = y2 * y2
            y5 = y4 * y
            y6 = y3 * y3
            o0[q] = y6
            o1[q] = 6.0 * x * y5
            o2[q] = 15.0 * x2 * y4
            o3[q] = 20.0 * x3 * y3
            o4[q] = 15.0 * x4 * y2
            o5[q] = 6.0 * x5 * y
            o6[q] = x6
    elif d == 7:
        o0, o1, o2, o3, o4 = out[0], out[1], out[2], out[3], out[4]
        o5, o6, o7 = out[5], out[6], out[7]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            x4 = x2 * x2
            x5 = x4 * x
            x6 = x3 * x3
            x7 = x6 * x
            y2 = y * y
            y3 = y2 * y
            y4 = y2 * y2
            y5 = y4 * y
            y6 = y3 * y3
            y7 = y6 * y
            o0[q] = y7
            o1[q] = 7.0 * x * y6
            o2[q] = 21.0 * x2 * y5
            o3[q] = 35.0 * x3 * y4
            o4[q] = 35.0 * x4 * y3
            o5[q] = 21.0 * x5 * y2
            o6[q] = 7.0 * x6 * y
            o7[q] = x7
    elif d == 8:
        o0, o1, o2, o3, o4 = out[0], out[1], out[2], out[3], out[4]
        o5, o6, o7, o8 = out[5], out[6], out[7], out[8]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            x4 = x2 * x2
            x5 = x4 * x
            x6 = x3 * x3
            x7 = x6 * x
            x8 = x4 * x4
            y2 = y * y
            y3 = y2 * y
            y4 = y2 * y2
            y5 = y4 * y
            y6 = y3 * y3
            y7 = y6 * y
            y8 = y4 * y4
            o0[q] = y8
            o1[q] = 8.0 * x * y7
            o2[q] = 28.0 * x2 * y6
            o3[q] = 56.0 * x3 * y5
            o4[q] = 70.0 * x4 * y4
            o5[q] = 56.0 * x5 * y3
            o6[q] = 28.0 * x6 * y2
            o7[q] = 8.0 * x7 * y
            o8[q] = x8
    elif d == 9:
        o0, o1, o2, o3, o4 = out[0], out[1], out[2], out[3], out[4]
        o5, o6, o7, o8, o9 = out[5], out[6], out[7], out[8], out[9]
        for q in range(w):
            x = t[q]
            y = 1.0 - x
            x2 = x * x
            x3 = x2 * x
            x4 = x2 * x2
            x5 = x4 * x
            x6 = x3 * x3
            x7 = x6 * x
            x8 = x4 * x4
            x9 = x8 * x
            y2 = y * y
            y3 = y2 * y
            y4 = y2 * y2
            y5 = y4 * y
            y6 = y3 * y3
            y7 = y6 * y
            y8 = y4 * y4
            y9 = y8 * y
            o0[q] = y9
            o1[q] = 9.0 * x * y8
            o2[q] = 36.0 * x2 * y7
            o3[q] = 84.0 * x3 * y6
            o4[q] = 126.0 * x4 * y5
            o5[q] = 126.0 * x5 * y4
            o6[q] = 84.0 * x6 * y3
            o7[q] = 36.0 * x7 * y2
            o8[q] = 9.0 * x8 * y
            o9[q] = x9
    else:
        o0 = out[0]
        for q in range(w):
            o0[q] = 1.0
