"""Open surfaces closed virtually: manifold sheets and caps over their holes.

An artist's model is often open (the Stanford bunny's holes in its base, a teapot's
pieces, a cup open at its rim) or joins sheets along an edge. The volume Isochor keeps is
the volume of a closed solid, so:

- :func:`split_non_manifold` cuts the surface along its non-manifold edges (shared by more
  than two triangles) into manifold sheets: around such an edge the triangles are paired
  by angle, each with its neighbour that runs the edge the other way, and the vertices of
  the edge are repeated for each sheet (new vertices appended after the model's own);
- :func:`cap_holes` closes every boundary loop with a fan of triangles from the loop to one
  extra point (the loop's length-weighted centre), wound against the loop so the capped
  sheet is closed and consistently oriented. The cap points are appended after the
  model's own vertices and the cap faces after its own faces: the lattice maps a cap
  point like any vertex, so the volume and its gradient (the paper's Eq 7-13) are exact
  for the capped solid, and an export writes only the model's own vertices and faces.

Nothing here reads or writes files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components


@dataclass(frozen=True)
class CapSummary:
    """What capping did: how many holes, and how large the caps are next to the surface.

    Attributes
    ----------
    holes : boundary loops capped
    boundary_edges : edges on the rims of the holes
    cap_area : total area of the caps
    surface_area : area of the model's own surface
    """

    holes: int = 0
    boundary_edges: int = 0
    cap_area: float = 0.0
    surface_area: float = 0.0

    @property
    def ratio(self) -> float:
        """Cap area over the model's surface area."""
        return self.cap_area / self.surface_area if self.surface_area > 0 else 0.0

    def sentence(self) -> str:
        """One line for the user ('' when nothing was capped)."""
        if not self.holes:
            return ""
        return (
            f"Capped {self.holes} hole(s) ({self.boundary_edges} boundary edges; the caps are "
            f"{_percent(self.ratio)} of the surface's area): the volume kept is the volume "
            "inside the capped surface. The caps are never written to a file."
        )


def summary(mesh) -> CapSummary:
    """The :class:`CapSummary` of a cleaned :class:`~isochor.core.mesh.TriMesh` (from its
    cap counts: one cap point per hole, one cap face per boundary edge)."""
    if not mesh.cap_faces:
        return CapSummary()
    area = areas(mesh.vertices, mesh.faces)
    own = mesh.own_faces
    return CapSummary(
        mesh.cap_vertices, mesh.cap_faces, float(area[own:].sum()), float(area[:own].sum())
    )


def _percent(ratio: float) -> str:
    return f"{100 * ratio:.2g}%" if ratio >= 1e-4 else "under 0.01%"


def split_non_manifold(faces: np.ndarray, vertices: np.ndarray, counts, edge_of_corner):
    """Cut the surface along its non-manifold edges into manifold sheets.

    Around each edge with more than two triangles, the triangles are sorted by their angle
    about the edge and paired with an angular neighbour that runs the edge the other way
    (the two walls of one solid wedge); every other pair of triangles sharing an edge
    (exactly two on it) stays joined. Each vertex is then repeated once per fan of
    triangles joined around it (the first fan keeps the vertex's number, the others get
    new vertices appended at the end, in order).

    Parameters
    ----------
    faces : (f, 3) int
    vertices : (m, 3) float
    counts : (e,) triangles per undirected edge (:class:`~.repair.EdgeReport`)
    edge_of_corner : (f, 3) the edge of each face side

    Returns
    -------
    (vertices, faces, number of non-manifold edges cut)
    """
    n_faces = len(faces)
    edges = edge_of_corner.ravel()
    face = np.repeat(np.arange(n_faces), 3)
    side = np.tile(np.arange(3), n_faces)
    a = faces[face, side]
    b = faces[face, (side + 1) % 3]
    # pairs of triangles joined across an edge: (face, face, lower vertex, higher vertex)
    two = counts[edges] == 2
    order = np.argsort(edges[two], kind="stable")
    f2, a2, b2 = face[two][order], a[two][order], b[two][order]
    pair_f = [np.stack([f2[0::2], f2[1::2]], axis=1)]
    pair_v = [np.stack([np.minimum(a2[0::2], b2[0::2]), np.maximum(a2[0::2], b2[0::2])], axis=1)]
    many = np.flatnonzero(counts[edges] > 2)
    cut = 0
    # the sheets the manifold edges make: faces of one sheet pair first around an edge
    joined2 = sp.coo_matrix(
        (np.ones(len(pair_f[0])), (pair_f[0][:, 0], pair_f[0][:, 1])), shape=(n_faces, n_faces)
    )
    sheet = connected_components(joined2, directed=False)[1]
    if len(many):
        by_edge = many[np.argsort(edges[many], kind="stable")]
        starts = np.flatnonzero(np.r_[True, edges[by_edge][1:] != edges[by_edge][:-1]])
        cut = len(starts)
        for group in np.split(by_edge, starts[1:]):
            joined = _pair_around_edge(vertices, faces, face[group], a[group], b[group], sheet)
            if len(joined):
                pair_f.append(joined)
                lo, hi = min(a[group[0]], b[group[0]]), max(a[group[0]], b[group[0]])
                pair_v.append(np.tile([lo, hi], (len(joined), 1)))
    pf, pv = np.concatenate(pair_f), np.concatenate(pair_v)
    # corners (face, slot) joined when their faces are joined across an edge at that vertex
    # slot[p, j, k]: the slot of vertex pv[p, k] in face pf[p, j]
    slot = np.argmax(faces[pf][:, :, None, :] == pv[:, None, :, None], axis=3)
    rows, cols = [], []
    for k in range(2):
        rows.append(pf[:, 0] * 3 + slot[:, 0, k])
        cols.append(pf[:, 1] * 3 + slot[:, 1, k])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * n_faces, 3 * n_faces))
    _, fan = connected_components(graph, directed=False)
    corner_vertex = faces.ravel()
    # the first fan (lowest corner) of each vertex keeps its number; the others are new
    fans, first_corner = np.unique(fan, return_index=True)
    fan_vertex = corner_vertex[first_corner]
    order = np.lexsort((first_corner, fan_vertex))
    keeps = np.r_[True, fan_vertex[order][1:] != fan_vertex[order][:-1]]
    new_number = np.empty(len(fans), dtype=np.int64)
    new_number[order[keeps]] = fan_vertex[order[keeps]]
    extra = order[~keeps]
    extra = extra[np.argsort(first_corner[extra], kind="stable")]
    new_number[extra] = len(vertices) + np.arange(len(extra))
    lookup = np.empty(fan.max() + 1, dtype=np.int64)
    lookup[fans] = new_number
    out_faces = lookup[fan].reshape(-1, 3)
    out_vertices = np.concatenate([vertices, vertices[fan_vertex[extra]]])
    return out_vertices, out_faces, cut


def _pair_around_edge(vertices, faces, group_faces, a, b, sheet) -> np.ndarray:
    """(k, 2) pairs of the triangles on one non-manifold edge that bound one wedge, each
    pair running the edge both ways: first two of one sheet (joined elsewhere by manifold
    edges: one solid's two walls), then angular neighbours about the edge (around the
    cycle), greedily; a triangle left over is cut off along the edge."""
    lo, hi = min(a[0], b[0]), max(a[0], b[0])
    p, q = vertices[lo], vertices[hi]
    axis = q - p
    axis = axis / (np.linalg.norm(axis) or 1.0)
    ref = np.eye(3)[int(np.argmin(np.abs(axis)))]
    u = np.cross(axis, ref)
    u /= np.linalg.norm(u) or 1.0
    w = np.cross(axis, u)
    tri = faces[group_faces]
    third = np.where((tri != lo) & (tri != hi), tri, -1).max(axis=1)
    d = vertices[third] - p
    order = [int(i) for i in np.argsort(np.arctan2(d @ w, d @ u), kind="stable")]
    forward = a < b
    k = len(order)
    free = set(order)
    pairs = []

    def take(i: int, j: int) -> None:
        if i in free and j in free and i != j and forward[i] != forward[j]:
            pairs.append((group_faces[i], group_faces[j]))
            free.difference_update((i, j))

    for step in range(1, k):  # one sheet's faces, nearest in angle first
        for n, i in enumerate(order):
            j = order[(n + step) % k]
            if sheet[group_faces[i]] == sheet[group_faces[j]]:
                take(i, j)
    for n, i in enumerate(order):  # then angular neighbours
        take(i, order[(n + 1) % k])
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def cap_holes(vertices: np.ndarray, faces: np.ndarray, boundary_sides: np.ndarray):
    """Close every boundary loop with a fan from one cap point.

    Parameters
    ----------
    vertices : (m, 3)
    faces : (f, 3), consistently wound
    boundary_sides : (k, 2) the boundary edges as their one triangle runs them (a -> b)

    Returns
    -------
    (cap points (h, 3), cap faces (k, 3) numbered after the m vertices, loop of each cap
    face, number of loops h)

    The loops are the connected pieces of the boundary edges (two loops touching at a
    vertex share one cap: still closed, each edge capped once the other way).
    """
    a, b = boundary_sides[:, 0], boundary_sides[:, 1]
    m = len(vertices)
    graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m))
    _, label = connected_components(graph, directed=False)
    loop_of_edge = label[a]
    _, loop_of_edge = np.unique(loop_of_edge, return_inverse=True)
    n_loops = int(loop_of_edge.max()) + 1
    length = np.linalg.norm(vertices[b] - vertices[a], axis=1)
    mid = (vertices[a] + vertices[b]) / 2
    weight = np.bincount(loop_of_edge, weights=length, minlength=n_loops)
    points = np.stack(
        [
            np.bincount(loop_of_edge, weights=length * mid[:, c], minlength=n_loops)
            for c in range(3)
        ],
        axis=1,
    )
    plain = (
        np.stack(
            [np.bincount(loop_of_edge, weights=mid[:, c], minlength=n_loops) for c in range(3)],
            axis=1,
        )
        / np.bincount(loop_of_edge, minlength=n_loops)[:, None]
    )
    points = np.where(weight[:, None] > 0, points / np.where(weight > 0, weight, 1)[:, None], plain)
    cap_faces = np.stack([b, a, m + loop_of_edge], axis=1)
    return points, cap_faces, loop_of_edge, n_loops


def boundary_sides(faces: np.ndarray, counts: np.ndarray, edge_of_corner: np.ndarray):
    """The face sides on edges with one triangle: ((k, 2) a -> b as their triangle runs
    them, (k,) that triangle)."""
    on_boundary = counts[edge_of_corner] == 1
    f, s = np.nonzero(on_boundary)
    return np.stack([faces[f, s], faces[f, (s + 1) % 3]], axis=1), f


def areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) triangle areas."""
    a = vertices[faces[:, 0]]
    n = np.cross(vertices[faces[:, 1]] - a, vertices[faces[:, 2]] - a)
    return np.sqrt(np.einsum("ij,ij->i", n, n)) / 2
