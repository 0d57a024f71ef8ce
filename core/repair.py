"""Surface repair: make a closed, consistently wound, outward-facing mesh of what artists have.

:func:`clean_closed_surface` runs the steps in order:

1. coincident vertices are welded by position (UV and normal seams, STL's repeated corners),
   within 1e-9 of the model size, so the weld does not depend on the model's units;
2. triangles with a repeated corner are dropped, and so are duplicate triangles (two
   copies of one triangle wound opposite ways cancel, like a double wall; same-way copies
   are kept once); unreferenced vertices are dropped;
3. the surface must be closed: every edge shared by exactly two triangles. Otherwise it is
   refused, with the count of boundary edges (holes) and non-manifold edges. A pinched
   vertex (the paper's cow has one) is fine: only edges matter for the volume;
4. inconsistent winding is repaired by flipping the smaller side of every body (warning);
5. each body is turned to face outward, or inward for a cavity inside another body, so the
   signed volume is the solid's volume (warning when anything was flipped).

The topology helpers (:class:`EdgeReport`, :func:`body_labels`, ...) serve the level
pyramid too. Nothing here reads or writes files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .errors import IsochorError
from .mesh import TriMesh
from .volume import face_volumes, signed_volume

#: vertices closer than this fraction of the model size are one vertex
WELD_TOLERANCE = 1e-9

#: above this many (point, triangle) pairs the cavity test is skipped (each body faces out)
NESTING_BUDGET = 50_000_000


# -- cleaning ---------------------------------------------------------------------------------
def clean_closed_surface(vertices: np.ndarray, faces: np.ndarray) -> tuple[TriMesh, list[str], int]:
    """Weld, drop degenerate and duplicate triangles, check closed, orient outward.

    Parameters
    ----------
    vertices : (m, 3) float64
    faces : (f, 3) int

    Returns
    -------
    (mesh, warnings, bodies)

    Raises
    ------
    IsochorError
        No triangles, an open surface, a surface that cannot be oriented, or no volume.
    """
    warns: list[str] = []
    vertices, faces = weld(vertices, faces)
    faces, n_degenerate = drop_degenerate(faces)
    faces, n_duplicate = drop_duplicates(faces)
    if n_degenerate:
        warns.append(f"Removed {n_degenerate} degenerate triangle(s) (a repeated corner).")
    if n_duplicate:
        warns.append(f"Removed {n_duplicate} duplicate triangle(s).")
    if len(faces) == 0:
        raise IsochorError("no triangles left after removing degenerate and duplicate ones")
    vertices, faces = compact(vertices, faces)
    report = EdgeReport.of(faces, len(vertices))
    if report.boundary or report.non_manifold:
        raise IsochorError(
            f"the surface is not closed: {report.describe()}; Isochor needs a "
            "closed surface (a solid) to measure a volume"
        )
    faces, n_flipped = fix_winding(faces, report)
    if n_flipped:
        warns.append(
            f"Inconsistent winding repaired: {n_flipped} triangle(s) flipped to "
            "match their neighbours."
        )
    labels, n_bodies = body_labels(faces, report)
    faces, inward = orient_bodies(vertices, faces, labels, n_bodies)
    if inward:
        what = (
            "The surface faced inward (negative volume)"
            if n_bodies == 1
            else f"{inward} of {n_bodies} bodies faced the wrong way"
        )
        warns.append(f"{what}; flipped to face outward.")
    volume = signed_volume(vertices, faces)
    if not volume > 1e-12 * np.ptp(vertices, axis=0).max() ** 3:
        raise IsochorError("the surface encloses no volume (it is flat)")
    return TriMesh(vertices, faces), warns, n_bodies


def weld(
    vertices: np.ndarray, faces: np.ndarray, tolerance: float = WELD_TOLERANCE
) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices closer than ``tolerance`` times the model size (per coordinate grid).

    Keeps the first vertex of each group and the file's vertex order (a model with nothing
    to weld keeps its vertex numbers); returns only referenced vertices.
    """
    mask = np.zeros(len(vertices), dtype=bool)
    mask[faces] = True
    used = np.flatnonzero(mask)
    v = vertices[used]
    lo = v.min(axis=0)
    size = float(np.ptp(v, axis=0).max())
    step = size * tolerance if size > 0 else 1.0
    keys = np.round((v - lo) / step).astype(np.int64)
    inverse, first, _ = group_rows(keys)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))  # groups in order of first appearance
    remap = np.empty(len(vertices), dtype=np.int64)
    remap[used] = rank[inverse]
    return v[np.sort(first)], remap[faces]


def drop_degenerate(faces: np.ndarray) -> tuple[np.ndarray, int]:
    """Drop triangles with a repeated corner index. Returns (faces, how many dropped).

    Zero-area triangles with three distinct corners stay: they are part of the surface's
    connectivity and add nothing to its volume.
    """
    bad = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    return faces[~bad], int(bad.sum())


def drop_duplicates(faces: np.ndarray) -> tuple[np.ndarray, int]:
    """Drop repeated triangles (same three corners). Returns (faces, how many dropped).

    Copies wound opposite ways cancel in pairs (an internal double wall adds nothing to the
    volume and would make its edges non-manifold); what is left of one orientation is kept
    once.
    """
    if len(faces) == 0:
        return faces, 0
    key = np.sort(faces, axis=1)
    inverse, _, counts = group_rows(key)
    if np.all(counts == 1):
        return faces, 0
    # even permutations of the sorted corners wind one way (+1), odd ones the other (-1)
    order = np.argsort(faces, axis=1)
    parity = np.where(np.isin(order @ np.array([9, 3, 1]), (5, 15, 19)), 1, -1)
    net = np.bincount(inverse, weights=parity).astype(np.int64)
    # keep, per group, the first triangle wound the way the group's majority is
    winner = np.flatnonzero(parity == np.sign(net)[inverse])
    _, pick = np.unique(inverse[winner], return_index=True)
    keep = np.zeros(len(faces), dtype=bool)
    keep[winner[pick]] = True
    return faces[keep], int(len(faces) - keep.sum())


def group_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Equal rows of an ``(k, c)`` int array: (group of each row, first row of each group,
    rows per group), groups in lexicographic order. Faster than ``np.unique(axis=0)``."""
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    new = np.ones(len(rows), dtype=bool)
    new[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    group = np.cumsum(new) - 1
    inverse = np.empty(len(rows), dtype=np.int64)
    inverse[order] = group
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(rows)))
    return inverse, order[starts], counts


def compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop vertices no triangle uses, renumbering the faces."""
    mask = np.zeros(len(vertices), dtype=bool)
    mask[faces] = True
    remap = np.cumsum(mask) - 1
    return vertices[mask], remap[faces].astype(np.int64)


# -- topology ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class EdgeReport:
    """How the triangles of a mesh share their edges.

    Attributes
    ----------
    edge_of_corner : (f, 3) int, the undirected edge of each face side (side 0 = corners 0-1)
    forward : (f, 3) bool, True when the side runs from the lower to the higher vertex index
    counts : (e,) int, triangles on each undirected edge
    balance : (e,) int, sides running forward minus sides running backward, per edge
    """

    edge_of_corner: np.ndarray
    forward: np.ndarray
    counts: np.ndarray
    balance: np.ndarray

    @classmethod
    def of(cls, faces: np.ndarray, n_vertices: int) -> EdgeReport:
        a = faces
        b = np.roll(faces, -1, axis=1)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        keys = (lo * np.int64(n_vertices) + hi).ravel()
        _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
        forward = a < b
        sign = np.where(forward, 1, -1).ravel()
        balance = np.bincount(inverse.ravel(), weights=sign, minlength=len(counts))
        return cls(inverse.reshape(faces.shape), forward, counts, balance.astype(np.int64))

    @property
    def boundary(self) -> int:
        """Edges on one triangle only (the rims of holes)."""
        return int(np.sum(self.counts == 1))

    @property
    def non_manifold(self) -> int:
        """Edges shared by more than two triangles."""
        return int(np.sum(self.counts > 2))

    @property
    def unbalanced(self) -> int:
        """Edges not run as often one way as the other: the surface is not a closed cycle,
        so its volume depends on where it is measured from."""
        return int(np.sum(self.balance != 0))

    def describe(self) -> str:
        parts = [f"{self.boundary} boundary edge(s) (holes)"]
        if self.non_manifold:
            parts.append(
                f"{self.non_manifold} non-manifold edge(s) (shared by more than two triangles)"
            )
        return " and ".join(parts)


def _face_pairs(report: EdgeReport) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every edge with exactly two triangles: (face a, face b, same direction?)."""
    edges = report.edge_of_corner.ravel()
    faces = np.repeat(np.arange(report.edge_of_corner.shape[0]), 3)
    forward = report.forward.ravel()
    two = report.counts[edges] == 2
    order = np.argsort(edges[two], kind="stable")
    f, d = faces[two][order], forward[two][order]
    return f[0::2], f[1::2], d[0::2] == d[1::2]


def body_labels(faces: np.ndarray, report: EdgeReport | None = None) -> tuple[np.ndarray, int]:
    """(f,) body index of every triangle, and the number of bodies: triangles joined by
    shared edges (any number per edge); a shared vertex alone does not join two bodies."""
    report = report or EdgeReport.of(faces, int(faces.max()) + 1)
    edges = report.edge_of_corner.ravel()
    order = np.argsort(edges, kind="stable")
    on_edge = np.repeat(np.arange(len(faces)), 3)[order]
    same = edges[order][1:] == edges[order][:-1]  # neighbours in this order share an edge
    n = len(faces)
    graph = sp.coo_matrix(
        (np.ones(int(same.sum())), (on_edge[:-1][same], on_edge[1:][same])), shape=(n, n)
    )
    count, labels = connected_components(graph, directed=False)
    return labels, int(count)


def count_bodies(mesh: TriMesh) -> int:
    """Number of separate closed bodies (face-connected components) of a closed mesh."""
    return body_labels(mesh.faces)[1]


def fix_winding(faces: np.ndarray, report: EdgeReport) -> tuple[np.ndarray, int]:
    """Make neighbouring triangles wind the same way, flipping the fewest per body.

    Every triangle gets two states (kept, flipped); a shared edge links the states that
    agree. The two states of one triangle in one component means a non-orientable surface.

    Returns
    -------
    (faces, number flipped)

    Raises
    ------
    IsochorError
        The surface cannot be oriented (a Moebius-like surface).
    """
    if report.unbalanced == 0:
        return faces, 0
    a, b, same = _face_pairs(report)
    n = len(faces)
    # state s of face f is node f + s*n; same direction on a shared edge = one of them flips
    rows = np.concatenate([a, a + n])
    cols = np.concatenate([np.where(same, b + n, b), np.where(same, b, b + n)])
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * n, 2 * n))
    _, comp = connected_components(graph, directed=False)
    keep_state, flip_state = comp[:n], comp[n:]
    if np.any(keep_state == flip_state):
        raise IsochorError("the surface cannot be oriented (it has no inside and outside)")
    # per body, the two state-components; flip the faces in the smaller class
    flip = keep_state > flip_state
    labels, n_bodies = body_labels(faces, report)
    flips_per_body = np.bincount(labels, weights=flip, minlength=n_bodies)
    size_per_body = np.bincount(labels, minlength=n_bodies)
    invert = flips_per_body > size_per_body / 2
    flip ^= invert[labels]
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(flip.sum())


def orient_bodies(
    vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray, n_bodies: int
) -> tuple[np.ndarray, int]:
    """Turn every body so that the total signed volume is the solid's volume.

    A body inside an even number of others (usually none) faces outward; one inside an odd
    number (a cavity) faces inward. Returns (faces, number of bodies flipped).
    """
    volumes = np.bincount(labels, weights=face_volumes(vertices, faces), minlength=n_bodies)
    if n_bodies > 1:
        depth = nesting_depth(vertices, faces, labels, n_bodies)
    else:
        depth = np.zeros(1, dtype=np.int64)
    wanted = np.where(depth % 2 == 0, 1.0, -1.0)
    flip_body = volumes * wanted < 0
    if not flip_body.any():
        return faces, 0
    flip = flip_body[labels]
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(flip_body.sum())


def nesting_depth(
    vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray, n_bodies: int
) -> np.ndarray:
    """(bodies,) how many other bodies contain each body (by the winding number of one
    triangle centre of the body). Zero everywhere when the test would be too costly."""
    depth = np.zeros(n_bodies, dtype=np.int64)
    tri = vertices[faces]
    lo = np.full((n_bodies, 3), np.inf)
    hi = np.full((n_bodies, 3), -np.inf)
    np.minimum.at(lo, labels, tri.min(axis=1))
    np.maximum.at(hi, labels, tri.max(axis=1))
    first = np.unique(labels, return_index=True)[1]
    probe = tri[first].mean(axis=1)  # (bodies, 3): one triangle centre per body
    inside = np.all((lo[None] <= lo[:, None]) & (hi[:, None] <= hi[None]), axis=2)
    np.fill_diagonal(inside, False)  # inside[b, a]: box of b within box of a
    pairs = np.argwhere(inside)
    counts = np.bincount(labels, minlength=n_bodies)
    if counts[pairs[:, 1]].sum() > NESTING_BUDGET:
        return depth
    order = np.argsort(labels, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)])
    for a in np.unique(pairs[:, 1]):
        inner = pairs[pairs[:, 1] == a, 0]
        body = tri[order[starts[a] : starts[a + 1]]]
        w = winding_numbers(probe[inner], body)
        depth[inner[np.abs(w) > 0.5]] += 1
    return depth


def winding_numbers(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Generalised winding number of each point with respect to a closed triangle set.

    Parameters
    ----------
    points : (p, 3)
    triangles : (t, 3, 3) corner positions

    Returns
    -------
    (p,) about +-1 inside, 0 outside (sign = the triangles' orientation)
    """
    out = np.empty(len(points))
    for i, p in enumerate(points):  # solid angles, Van Oosterom and Strackee (1983)
        a, b, c = (triangles[:, k] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("ij,ij->i", a, b) * lc
            + np.einsum("ij,ij->i", a, c) * lb
            + np.einsum("ij,ij->i", b, c) * la
        )
        out[i] = np.sum(np.arctan2(num, den)) / (2 * np.pi)
    return out
