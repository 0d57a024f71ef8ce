"""Which points of a regular grid lie inside a closed triangle mesh: signed ray crossings,
one ray per grid column.

The points of a regular grid share their columns, so one ray up each column (along the axis
with the most cells) labels the whole column: the winding number of a point is the sum of
the signs of the faces the ray crosses above it (+1 where the face's normal points along the
ray, -1 against it). Summed over every body this is the generalised winding number
(:func:`isochor.core.bodies.winding_numbers`) of a closed mesh, for cavities and nested or
overlapping bodies alike, at a cost of about (triangles x columns each covers) instead of
(points x triangles).

A ray through an edge or a vertex is made unambiguous by symbolic perturbation (Edelsbrunner
and Muecke's Simulation of Simplicity): the column's point ``(u, v)`` in the plane is taken
as ``(u + e, v + e**2)`` for an infinitesimal ``e``, so it lies on no edge line and every
edge it would touch is given to exactly one of its two triangles. Each edge's side test is
computed once per edge direction (its end points in lexicographic order), so the two
triangles of an edge see exactly opposite values, and it is trusted only where it exceeds
its rounding-error bound (Shewchuk's ``ccwerrboundA``) or is exactly zero (the point on the
edge's line, exactly: the perturbation decides). A column where some test is within the
bound falls back to the exact winding number of its points.
"""

from __future__ import annotations

import numpy as np

from .bodies import winding_numbers

#: Shewchuk's error bound of a 2 x 2 orientation determinant, relative to its terms' sum
ORIENT_BOUND = (3.0 + 16.0 * np.finfo(float).eps) * np.finfo(float).eps
#: (triangle, column) pairs per block
PAIR_BLOCK = 1 << 18


def grid_winding(
    vertices: np.ndarray, faces: np.ndarray, lo: np.ndarray, step: np.ndarray, cells
) -> np.ndarray:
    """Winding numbers of the cell centres ``lo + (i + 0.5) * step`` of a regular grid.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (t, 3) int, a closed (or capped) triangle mesh
    lo : (3,) the grid's lower corner
    step : (3,) cell sizes, > 0
    cells : three cell counts

    Returns
    -------
    (cells[0], cells[1], cells[2]) float: whole numbers (the signed crossings), except in
    columns where a ray met an edge within rounding: there the exact winding number
    """
    cells = tuple(int(c) for c in cells)
    lo, step = np.asarray(lo, dtype=np.float64), np.asarray(step, dtype=np.float64)
    out = np.zeros(cells)
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.intp).reshape(-1, 3)
    if min(cells) < 1 or len(faces) == 0:
        return out
    c = int(np.argmax(cells))  # rays along the longest columns: the fewest columns
    a, b = (c + 1) % 3, (c + 2) % 3  # (a, b, c) right-handed: ccw in (a, b) <=> normal along c
    centres = [lo[k] + (np.arange(cells[k]) + 0.5) * step[k] for k in range(3)]
    counts, doubtful = _crossings(vertices, faces, (a, b, c), centres)
    # counts[i, j, m]: signs of the crossings above m of the column's points (m = 0..nc)
    w = np.cumsum(counts[:, :, ::-1], axis=2)[:, :, ::-1][:, :, 1:]  # above point k
    out_abc = w.astype(np.float64)
    if doubtful.any():
        ii, jj = np.nonzero(doubtful)
        pts = np.empty((len(ii), cells[c], 3))
        pts[..., a] = centres[a][ii, None]
        pts[..., b] = centres[b][jj, None]
        pts[..., c] = centres[c][None, :]
        exact = winding_numbers(pts.reshape(-1, 3), vertices[faces])
        out_abc[ii, jj] = exact.reshape(len(ii), cells[c])
    # back to (x, y, z) order
    return np.ascontiguousarray(np.moveaxis(out_abc, (0, 1, 2), (a, b, c)))


def _crossings(vertices, faces, axes, centres):
    """Signed crossings per column and height bucket, and which columns are in doubt."""
    a, b, c = axes
    na, nb, nc = len(centres[a]), len(centres[b]), len(centres[c])
    counts = np.zeros((na, nb, nc + 1), dtype=np.int64)
    doubtful = np.zeros((na, nb), dtype=bool)
    u, v, z = vertices[:, a], vertices[:, b], vertices[:, c]
    tri_u, tri_v = u[faces], v[faces]
    # the columns each triangle's box covers (exactly: by the columns' own coordinates)
    i0 = np.searchsorted(centres[a], tri_u.min(axis=1), "left")
    i1 = np.searchsorted(centres[a], tri_u.max(axis=1), "right")
    j0 = np.searchsorted(centres[b], tri_v.min(axis=1), "left")
    j1 = np.searchsorted(centres[b], tri_v.max(axis=1), "right")
    ni, nj = np.maximum(i1 - i0, 0), np.maximum(j1 - j0, 0)
    per = ni * nj
    edges = _edges(vertices, faces, a, b)
    flat = counts.reshape(-1)
    ends = np.cumsum(per)
    start = 0
    while start < len(faces):
        base = int(ends[start - 1]) if start else 0
        stop = max(int(np.searchsorted(ends, base + PAIR_BLOCK, "right")), start + 1)
        sel = slice(start, stop)
        n = per[sel]
        t = np.repeat(np.arange(start, stop), n)
        if len(t):
            k = np.arange(len(t)) - np.repeat(np.cumsum(n) - n, n)
            ci = i0[t] + k % ni[t]
            cj = j0[t] + k // np.maximum(ni[t], 1)
            pu, pv = centres[a][ci], centres[b][cj]
            hit, sign, heights, doubt = _pierce(edges, t, pu, pv, z[faces[t]])
            if doubt.any():
                doubtful[ci[doubt], cj[doubt]] = True
            above = np.searchsorted(centres[c], heights[hit], "left")  # points below it
            col = (ci[hit] * nb + cj[hit]) * (nc + 1) + above
            flat += np.bincount(col, weights=sign[hit], minlength=flat.size).astype(np.int64)
        start = stop
    return counts, doubtful


def _edges(vertices, faces, a, b):
    """Per triangle and edge (v0 v1, v1 v2, v2 v0): its start point and direction in the
    (a, b) plane with the end points in lexicographic order, and +1 or -1 for the
    triangle's own direction (so both triangles of an edge compute the same numbers)."""
    out = []
    for e in range(3):
        p, q = faces[:, e], faces[:, (e + 1) % 3]
        vp, vq = vertices[p], vertices[q]
        # q before p lexicographically (x, then y, then z): the edge is run from q
        diff = vq != vp
        first = np.argmax(diff, axis=1)
        rows = np.arange(len(faces))
        swap = vq[rows, first] < vp[rows, first]
        start = np.where(swap[:, None], vq, vp)
        end = np.where(swap[:, None], vp, vq)
        out.append(
            (
                start[:, a],
                start[:, b],
                end[:, a] - start[:, a],
                end[:, b] - start[:, b],
                np.where(swap, -1.0, 1.0),
            )
        )
    return out


def _pierce(edges, t, pu, pv, tz):
    """Whether the perturbed ray at ``(pu, pv)`` crosses triangle ``t`` (per pair), the
    crossing's sign and height, and whether a side test was within rounding."""
    signs, values, sure = [], [], []
    for su, sv, du, dv, own in edges:
        su, sv, du, dv, own = su[t], sv[t], du[t], dv[t], own[t]
        left, right = du * (pv - sv), dv * (pu - su)
        value = left - right
        bound = ORIENT_BOUND * (np.abs(left) + np.abs(right))
        certain = (np.abs(value) > bound) | (bound == 0)
        # exactly on the edge's line: the perturbation (u + e, v + e^2) decides
        tie = np.where(dv != 0, -np.sign(dv), np.sign(du))
        s = np.where(value != 0, np.sign(value), tie) * own
        signs.append(s)
        values.append(value * own)
        sure.append(certain)
    s0, s1, s2 = signs
    c0, c1, c2 = sure
    certain_all = c0 & c1 & c2
    # a doubtful test matters unless two trusted ones already disagree (then: no crossing)
    differ = (c0 & c1 & (s0 != s1)) | (c1 & c2 & (s1 != s2)) | (c0 & c2 & (s0 != s2))
    doubt = ~certain_all & ~differ
    hit = (s0 == s1) & (s1 == s2) & (s0 != 0) & certain_all
    e0, e1, e2 = values  # e0 = side of v0 v1: the weight of v2, and so on
    total = e0 + e1 + e2
    safe = np.where(total != 0, total, 1.0)
    heights = (e1 * tz[:, 0] + e2 * tz[:, 1] + e0 * tz[:, 2]) / safe
    hit &= total != 0
    return hit, s0, heights, doubt
