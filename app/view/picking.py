"""Projection and picking maths for the 3D view: numpy only, tested headless.

The view does not use VTK's pickers: node positions are projected to the screen with the
camera's composite projection matrix and the nearest node within a radius wins. The same
projection turns a mouse position back into a world point (at a grabbed node's depth, on an
axis line, or on a plane), which is how a drag moves nodes under the cursor.

Coordinates: *widget pixels* have x to the right and y down, in logical (device-independent)
pixels, as Qt's mouse events give them. *Device pixels* (the renderer's) have y up and are
``devicePixelRatio`` times larger. Depth is the normalised device z (-1 near, 1 far).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A click within this many pixels of a node's centre picks it.
PICK_RADIUS = 12.0
#: Among nodes about equally near the cursor (within this many pixels), the front one wins.
PICK_TIE = 2.0


@dataclass(frozen=True)
class Projection:
    """World to widget pixels for one camera and window size.

    Attributes
    ----------
    matrix : (4, 4) world -> clip coordinates (the camera's composite projection)
    viewport : (x0, y0, width, height) of the renderer in device pixels, y up
    height : the widget's height in logical pixels
    dpr : device pixels per logical pixel
    """

    matrix: np.ndarray
    viewport: tuple[float, float, float, float]
    height: float
    dpr: float = 1.0

    def project(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Screen positions of world ``points``.

        Returns
        -------
        xy : (p, 2) widget pixels, y down
        depth : (p,) normalised device z
        visible : (p,) bool, in front of the camera
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        clip = np.c_[pts, np.ones(len(pts))] @ np.asarray(self.matrix).T
        w = clip[:, 3]
        visible = w > 1e-12
        ndc = clip[:, :3] / np.where(visible, w, 1.0)[:, None]
        x0, y0, vw, vh = self.viewport
        dx = x0 + (ndc[:, 0] + 1) / 2 * vw
        dy = y0 + (ndc[:, 1] + 1) / 2 * vh
        xy = np.c_[dx / self.dpr, self.height - 1 - dy / self.dpr]
        return xy, ndc[:, 2], visible

    def unproject(self, x: float, y: float, depth: float) -> np.ndarray:
        """(3,) world point under widget pixel (x, y) at normalised device ``depth``."""
        x0, y0, vw, vh = self.viewport
        dx, dy = x * self.dpr, (self.height - 1 - y) * self.dpr
        ndc = np.array([2 * (dx - x0) / vw - 1, 2 * (dy - y0) / vh - 1, depth, 1.0])
        p = np.linalg.solve(np.asarray(self.matrix), ndc)
        return p[:3] / p[3]

    def ray(self, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
        """(origin on the near plane, unit direction) of the line of sight through (x, y)."""
        near, far = self.unproject(x, y, -1.0), self.unproject(x, y, 1.0)
        d = far - near
        return near, d / np.linalg.norm(d)


def nearest(
    proj: Projection,
    points,
    x: float,
    y: float,
    radius: float = PICK_RADIUS,
    hidden=None,
    skip_hidden: bool = False,
) -> int:
    """Row of the point drawn nearest to (x, y) within ``radius`` pixels, or -1.

    Among points about equally near (within :data:`PICK_TIE` pixels of the nearest), the
    one in front wins, so a click on a node in front of another picks the front one.
    ``hidden``, a function of (k, 3) points giving (k,) bool (what the model hides), makes
    the visible points within the radius win over hidden ones; with ``skip_hidden`` a hidden
    point is never picked (a click that places a handle on the surface in front of it).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        return -1
    xy, depth, visible = proj.project(points)
    d = np.hypot(xy[:, 0] - x, xy[:, 1] - y)
    d[~visible] = np.inf
    near = np.flatnonzero(d <= radius)
    if len(near) and hidden is not None:
        behind = np.asarray(hidden(points[near]), dtype=bool)
        if skip_hidden or not behind.all():
            near = near[~behind]
    if len(near) == 0:
        return -1
    close = near[d[near] <= d[near].min() + PICK_TIE]
    return int(close[np.argmin(depth[close])])


def in_rect(
    proj: Projection, points, left: float, top: float, right: float, bottom: float
) -> np.ndarray:
    """Rows of the visible points drawn inside the widget rectangle (edges included)."""
    xy, _, visible = proj.project(points)
    inside = (
        (xy[:, 0] >= left)
        & (xy[:, 0] <= right)
        & (xy[:, 1] >= top)
        & (xy[:, 1] <= bottom)
        & visible
    )
    return np.flatnonzero(inside)


def drag_delta(
    proj: Projection,
    press: tuple[float, float],
    pos: tuple[float, float],
    anchor,
    depth: float,
    axis=None,
    plane: bool = False,
) -> np.ndarray | None:
    """The world displacement of a drag from widget pixel ``press`` to ``pos``.

    - no ``axis``: in the view plane through the grabbed point (``anchor`` at ``depth``),
      so the point stays under the cursor;
    - ``axis`` (a unit vector) and not ``plane``: along the axis line through ``anchor``,
      by the point of that line nearest to the line of sight;
    - ``axis`` and ``plane``: in the plane through ``anchor`` across ``axis``.

    Returns None when the move is not defined (the line of sight runs along the axis line,
    or parallel to the plane): keep the previous displacement then.
    """
    anchor = np.asarray(anchor, dtype=np.float64)
    if axis is None:
        return proj.unproject(*pos, depth) - proj.unproject(*press, depth)
    axis = np.asarray(axis, dtype=np.float64)
    if plane:
        a, b = _plane_hit(proj, press, anchor, axis), _plane_hit(proj, pos, anchor, axis)
        return None if a is None or b is None else b - a
    ta, tb = _line_parameter(proj, press, anchor, axis), _line_parameter(proj, pos, anchor, axis)
    return None if ta is None or tb is None else (tb - ta) * axis


def _plane_hit(proj, p, anchor, normal) -> np.ndarray | None:
    o, d = proj.ray(*p)
    den = d @ normal
    if abs(den) < 1e-6:
        return None
    return o + ((anchor - o) @ normal / den) * d


def _line_parameter(proj, p, anchor, axis) -> float | None:
    """Parameter t of the point ``anchor + t axis`` nearest to the line of sight at ``p``."""
    o, d = proj.ray(*p)
    w0 = anchor - o
    b = axis @ d
    den = 1 - b * b
    if den < 1e-6:
        return None
    return float((b * (d @ w0) - (axis @ w0)) / den)


def segment_distance(proj: Projection, a, b, x: float, y: float) -> float:
    """Pixel distance from widget pixel (x, y) to the world segment ``a``-``b`` as drawn
    (infinite when an end is behind the camera)."""
    xy, _, visible = proj.project(np.array([a, b], dtype=np.float64))
    if not visible.all():
        return float("inf")
    p, q = xy
    d = q - p
    length2 = float(d @ d)
    t = 0.0 if length2 == 0 else float(np.clip(((x, y) - p) @ d / length2, 0.0, 1.0))
    return float(np.hypot(*((x, y) - (p + t * d))))


def _screen_triangles(proj: Projection, vertices, faces):
    """The triangles as drawn: (f, 3, 2) widget pixels, (f, 3) depths, (f,) all visible."""
    xy, depth, visible = proj.project(vertices)
    faces = np.asarray(faces, dtype=np.int64)
    return xy[faces], depth[faces], visible[faces].all(axis=1)


def _covering(tri_xy, tri_depth, ok, x: float, y: float):
    """The triangles that cover pixel (x, y): their rows, barycentric weights (k, 3) and the
    depth there (k,)."""
    lo, hi = tri_xy.min(axis=1), tri_xy.max(axis=1)
    cand = np.flatnonzero(
        ok & (lo[:, 0] <= x) & (hi[:, 0] >= x) & (lo[:, 1] <= y) & (hi[:, 1] >= y)
    )
    if len(cand) == 0:
        return cand, np.zeros((0, 3)), np.zeros(0)
    t = tri_xy[cand]
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    v0, v1 = b - a, c - a
    v2 = np.array([x, y]) - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    good = np.abs(den) > 1e-12
    den = np.where(good, den, 1.0)
    wb = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    wc = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    wa = 1.0 - wb - wc
    eps = -1e-9
    inside = good & (wa >= eps) & (wb >= eps) & (wc >= eps)
    w = np.c_[wa, wb, wc][inside]
    depth = (w * tri_depth[cand[inside]]).sum(axis=1)
    return cand[inside], w, depth


def surface_hit(proj: Projection, vertices, faces, x: float, y: float):
    """The front triangle of a mesh drawn under widget pixel (x, y).

    Returns ``(face row, barycentric weights (3,), world point (3,))``, or None when the
    pixel shows no triangle. The weights are of the triangle's world corners, so the same
    weights on another embedding of the mesh (its rest shape) give the same surface point.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    rows, w2d, depth = _covering(*_screen_triangles(proj, vertices, faces), x, y)
    if len(rows) == 0:
        return None
    i = int(np.argmin(depth))
    face = faces[rows[i]]
    # screen weights -> world weights: intersect the line of sight with the triangle's plane
    o, d = proj.ray(x, y)
    a, b, c = vertices[face]
    n = np.cross(b - a, c - a)
    den = float(d @ n)
    if abs(den) > 1e-15 * max(1.0, float(np.linalg.norm(n))):
        p = o + ((a - o) @ n / den) * d
        m = np.c_[b - a, c - a]
        st, *_ = np.linalg.lstsq(m, p - a, rcond=None)
        w = np.array([1 - st[0] - st[1], st[0], st[1]])
    else:
        w = w2d[i]
    return int(rows[i]), w, w @ vertices[face]


def occluded(proj: Projection, points, vertices, faces, tolerance: float = 1e-5) -> np.ndarray:
    """(p,) bool: the points a mesh hides, i.e. a triangle drawn over the point's pixel lies
    in front of it (by more than ``tolerance`` in normalised depth)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    xy, depth, visible = proj.project(pts)
    tri = _screen_triangles(proj, vertices, faces)
    hidden = np.zeros(len(pts), dtype=bool)
    for r in np.flatnonzero(visible):
        _, _, d = _covering(*tri, xy[r, 0], xy[r, 1])
        hidden[r] = bool(len(d) and d.min() < depth[r] - tolerance)
    return hidden
