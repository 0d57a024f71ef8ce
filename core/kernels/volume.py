"""Compiled volume kernels: :class:`core.volume.VolumeOperator`'s volume and gradient.

The gradient of the volume at vertex ``o`` is ``sum (P_j x P_k) / 6`` over the faces
``(o, j, k)`` around it (corners in winding order; see :mod:`core.volume`). Vertex by
vertex, with no scatter, so ranges of vertices run on separate threads and every sum has a
fixed order. The pairs ``(j, k)`` of a vertex are stored as *fans*: chains
``j0, k0 = j1, k1 = j2, ...`` where each pair's second vertex is the next one's first (a
closed manifold vertex of degree d is one chain of d + 1 vertices), so each neighbour is
read once and used in two cross products. A pair that continues no chain starts a new one:
open, non-manifold and badly wound meshes get one chain per run, and every pair is still
used exactly once, so the gradient is exact for any triangle set, like the NumPy path's.

Storage: ``ptr`` (m + 1) and ``seq`` (int32): the chains of vertex o are
``seq[ptr[o]:ptr[o + 1]]``, a chain starts at an entry ``-(j + 1)``.

The volume is ``sum_o P_o . grad_o / 3`` (each face's triple product three times); the
volume alone is the sum of the faces' triple products (:func:`face_volume_range`).
"""

from __future__ import annotations

import numpy as np

from .base import INLINE, KERNEL, REDUCE, njit
from .winding import half_solid_angle

#: the solid-angle term shared with the NumPy path, compiled into the winding kernel
_half_solid_angle = njit(**INLINE)(half_solid_angle)

#: the one vertex's walk, inlined (numba IR) into this kernel and the one-pass evaluation's
#: (:mod:`core.kernels.fused`)
_IN = {**INLINE, "inline": "always"}

#: vertices of one fan above which its pairs are sorted with argsort (else insertion sort)
_SMALL_FAN = 32


@njit(**KERNEL)
def build_fans(faces, n):
    """(ptr int64 (n + 1), seq int32) of the faces (f, 3) on n vertices; see the module."""
    f = faces.shape[0]
    count = np.zeros(n + 1, np.int64)
    for t in range(f):
        for c in range(3):
            count[faces[t, c] + 1] += 1
    first = np.cumsum(count)  # first[o]: where the pairs of vertex o start
    pj = np.empty(3 * f, np.int64)
    pk = np.empty(3 * f, np.int64)
    fill = first[:n].copy()
    for t in range(f):
        for c in range(3):
            o = faces[t, c]
            pj[fill[o]] = faces[t, (c + 1) % 3]
            pk[fill[o]] = faces[t, (c + 2) % 3]
            fill[o] += 1
    ptr = np.zeros(n + 1, np.int64)
    seq = np.empty(6 * f, np.int32)
    used = np.zeros(3 * f, np.bool_)
    at = 0
    for o in range(n):
        a, b = first[o], first[o + 1]
        d = b - a
        # the pairs of o sorted by their first vertex: order[0..d) indexes pj[a:b]
        if d > _SMALL_FAN:
            order = np.argsort(pj[a:b])
        else:
            order = np.empty(d, np.int64)
            for i in range(d):
                v = pj[a + i]
                h = i
                while h > 0 and pj[a + order[h - 1]] > v:
                    order[h] = order[h - 1]
                    h -= 1
                order[h] = i
        for s in range(d):
            cur = order[s]
            if used[a + cur]:
                continue
            seq[at] = -(pj[a + cur] + 1)
            at += 1
            while True:
                used[a + cur] = True
                nxt = pk[a + cur]
                seq[at] = nxt
                at += 1
                # the first unused pair whose first vertex is nxt (binary search, then scan)
                lo, hi = 0, d
                while lo < hi:
                    mid = (lo + hi) // 2
                    if pj[a + order[mid]] < nxt:
                        lo = mid + 1
                    else:
                        hi = mid
                cur = -1
                while lo < d and pj[a + order[lo]] == nxt:
                    if not used[a + order[lo]]:
                        cur = order[lo]
                        break
                    lo += 1
                if cur < 0:
                    break
        ptr[o + 1] = at
    return ptr, seq[:at].copy()


@njit(**KERNEL)
def fan_gradient_range(rows, cx, cy, cz, ptr, seq, grad, start, stop, total):
    """``grad[:, o]`` for the vertices ``start..stop`` of the (3, m) ``rows`` (about the
    centre ``c``); returns ``total`` plus their ``sum_o (P_o - c) . grad_o`` (added in
    vertex order, so ranges taken one after the other give one range's sum).

    A chain ``a_0, ..., a_e`` of vertex o adds ``sum_i a_i x a_(i+1)``, computed as
    ``sum_i d_i x d_(i+1) + (o - c) x (a_e - a_0)`` with ``d_i = a_i - o``: the same
    number, but the products are of edge-sized vectors (a vertex's gradient is a sum of
    products of radius-sized vectors about 1e5 times larger than itself on a
    million-triangle model), and a closed chain (``a_e = a_0``) has no second term at all.
    Two terms at a time, ``d_(2k) x d_(2k+1) + d_(2k+1) x d_(2k+2) = d_(2k+1) x (a_(2k+2)
    - a_(2k))``: half the cross products (the vertex's six faces take three), still of
    edge-sized vectors; an odd last term is added alone.
    """
    x, y, z = rows[0], rows[1], rows[2]
    gx, gy, gz = grad[0], grad[1], grad[2]
    for o in range(start, stop):
        px, py, pz = x[o], y[o], z[o]
        sx, sy, sz = _vertex(x, y, z, px, py, pz, cx, cy, cz, seq, ptr[o], ptr[o + 1])
        sx /= 6.0
        sy /= 6.0
        sz /= 6.0
        gx[o] = sx
        gy[o] = sy
        gz[o] = sz
        total += (px - cx) * sx + (py - cy) * sy + (pz - cz) * sz
    return total


@njit(**_IN)
def _plus_cross(sx, sy, sz, ax, ay, az, bx, by, bz):
    """``s + a x b``: the one cross product the fans add, coordinate by coordinate (the
    fans' walk and the one-pass evaluation's regular vertex alike)."""
    return sx + (ay * bz - az * by), sy + (az * bx - ax * bz), sz + (ax * by - ay * bx)


def _walk(x, y, z, px, py, pz, cx, cy, cz, seq, a, b):
    """6 times the gradient at the vertex ``p`` whose chains are ``seq[a:b]`` (see
    :func:`fan_gradient_range`), of the points ``x, y, z`` about the centre ``c``."""
    sx, sy, sz = 0.0, 0.0, 0.0
    t = a
    while t < b:  # every vertex's entries start with a chain
        first = -seq[t] - 1
        last = first
        # e: the chain's entry of even place reached so far (not relative to o)
        ex, ey, ez = x[first], y[first], z[first]
        t += 1
        while t < b:
            r = seq[t]
            if r < 0:  # the next chain starts
                break
            t += 1
            hx, hy, hz = x[r] - px, y[r] - py, z[r] - pz  # d of odd place
            q = seq[t] if t < b else -1
            if q >= 0:  # two terms: d_odd x (a_even' - a_even)
                t += 1
                nx, ny, nz = x[q], y[q], z[q]
                ux, uy, uz = nx - ex, ny - ey, nz - ez
                sx, sy, sz = _plus_cross(sx, sy, sz, hx, hy, hz, ux, uy, uz)
                ex, ey, ez = nx, ny, nz
                last = q
            else:  # the chain's last term alone: d_even x d_odd
                ax, ay, az = ex - px, ey - py, ez - pz
                sx, sy, sz = _plus_cross(sx, sy, sz, ax, ay, az, hx, hy, hz)
                ex, ey, ez = x[r], y[r], z[r]
                last = r
                break
        if last != first:  # an open chain: (o - c) x (a_e - a_0)
            dx, dy, dz = ex - x[first], ey - y[first], ez - z[first]
            ox, oy, oz = px - cx, py - cy, pz - cz
            sx, sy, sz = _plus_cross(sx, sy, sz, ox, oy, oz, dx, dy, dz)
    return sx, sy, sz


#: :func:`_walk` inlined into the fans' kernel (its loop is the kernel's whole work: called,
#: the 1M torus's fans took 14 ms instead of 11.5), and called from the one-pass
#: evaluation's (:mod:`core.kernels.fused`), where it is the rare path (the kernel stays
#: smaller; as fast as with it inlined, within the noise)
_vertex = njit(**_IN)(_walk)
_vertex_called = njit(**INLINE)(_walk)


@njit(**REDUCE)
def face_volume_range(rows, cx, cy, cz, f0, f1, f2, start, stop):
    """``sum a . (b x c)`` over the faces ``start..stop`` (corners f0, f1, f2) of the (3, m)
    ``rows`` about the centre."""
    x, y, z = rows[0], rows[1], rows[2]
    total = 0.0
    for t in range(start, stop):
        i, j, k = f0[t], f1[t], f2[t]
        ax, ay, az = x[i] - cx, y[i] - cy, z[i] - cz
        bx, by, bz = x[j] - cx, y[j] - cy, z[j] - cz
        qx, qy, qz = x[k] - cx, y[k] - cy, z[k] - cz
        total += ax * (by * qz - bz * qy) + ay * (bz * qx - bx * qz) + az * (bx * qy - by * qx)
    return total


@njit(**KERNEL)
def winding_range(points, corners, out, start, stop):
    """``out[q]`` for the points ``start..stop`` of the (3, p) ``points``: the generalised
    winding number over the triangles ``corners`` (3 corners, 3 coordinates, t), the
    solid-angle term of :func:`core.bodies.winding_numbers` (:mod:`core.kernels.winding`),
    triangle by triangle in the same order."""
    t = corners.shape[2]
    a, b, c = corners[0], corners[1], corners[2]
    for q in range(start, stop):
        px, py, pz = points[0, q], points[1, q], points[2, q]
        total = 0.0
        for f in range(t):
            total += _half_solid_angle(
                a[0, f] - px, a[1, f] - py, a[2, f] - pz,
                b[0, f] - px, b[1, f] - py, b[2, f] - pz,
                c[0, f] - px, c[1, f] - py, c[2, f] - pz,
            )  # fmt: skip
        out[q] = total / (2.0 * np.pi)
