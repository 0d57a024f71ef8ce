"""The solid-angle term of the generalised winding number (Van Oosterom and Strackee 1983),
written once for both paths: :func:`core.bodies.winding_numbers` calls it on arrays of
(point, triangle) pairs, the compiled kernel (:func:`core.kernels.volume.winding_range`) on
one pair at a time. Plain arithmetic and NumPy ufuncs only, so it runs unchanged in
either; no import of numba here (the NumPy path must not wait for it).
"""

from __future__ import annotations

import numpy as np


def half_solid_angle(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Half the signed solid angle of the triangle with corners ``a``, ``b``, ``c`` given
    relative to the point seen from (scalars or arrays of the same shape)."""
    la = np.sqrt(ax * ax + ay * ay + az * az)
    lb = np.sqrt(bx * bx + by * by + bz * bz)
    lc = np.sqrt(cx * cx + cy * cy + cz * cz)
    num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = (
        la * lb * lc
        + (ax * bx + ay * by + az * bz) * lc
        + (ax * cx + ay * cy + az * cz) * lb
        + (bx * cx + by * cy + bz * cz) * la
    )
    return np.arctan2(num, den)
