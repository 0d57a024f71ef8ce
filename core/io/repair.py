"""Surface repair: make a closed, consistently wound, outward-facing solid of what artists have.

:func:`clean_closed_surface` runs the steps in order:

1. coincident vertices are welded by position (UV and normal seams, STL's repeated corners),
   within 1e-9 of the model size (at most 10^4 typical edges, so one stray far vertex does
   not weld the rest together), so the weld does not depend on the model's units. The
   file's separate objects (OBJ ``o``/``g``, STL ``solid``, glTF meshes) that are closed on
   their own are never welded to another object (:func:`weld_parts`). Welding is kept
   only where it keeps the surface manifold: when it would join solids (an edge of more
   than two triangles, two faces cancelling), the pieces the file's own vertex indices
   keep apart and that are closed on their own stay apart (many pieces in one object,
   touching at shared coordinates);
2. triangles with a repeated corner are dropped, and so are duplicate triangles (two
   copies of one triangle wound opposite ways cancel, like a double wall; same-way copies
   are kept once); unreferenced vertices are dropped;
3. non-manifold edges (more than two triangles) are split into manifold sheets (warning;
   :mod:`.caps`). A pinched vertex (the paper's cow has one) is fine: only edges matter;
4. inconsistent winding is repaired by flipping the smaller side of every body (warning),
   then every hole is capped virtually (:mod:`.caps`; the caps come after the model's own
   vertices and faces, and a warning says how many and how large);
5. each body is turned to face outward, or inward for a cavity inside another body, so the
   signed volume is the solid's volume (warning when anything was flipped; bodies that
   overlap are accepted with a warning that their common part counts twice; see
   :mod:`isochor.core.bodies`);
6. a surface whose volume is lost in rounding is flat and refused, and so is an open surface
   whose caps enclose nothing (a flat sheet, loose triangles: no solid to keep); a few
   vertices far from all the others (a damaged file) are accepted with a warning.

The topology helpers (:class:`EdgeReport`, :func:`body_labels`, ...) serve the level
pyramid too. Nothing here reads or writes files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..bodies import arrange, orient, tetra_volumes
from ..errors import IsochorError
from ..mesh import TriMesh
from .caps import CapSummary, areas, boundary_sides, cap_holes, split_non_manifold

#: vertices closer than this fraction of the model size are one vertex
WELD_TOLERANCE = 1e-9

#: a vertex farther than this many typical distances from the model's middle is "far"
FAR = 1000.0
#: the volume must be measurable to this relative precision wherever it is measured from
PRECISION = 1e-9
_MIX = np.uint64(0xBF58476D1CE4E5B9)  # an odd 64-bit multiplier (splitmix64's): row hashes


# -- cleaning ---------------------------------------------------------------------------------
def clean_closed_surface(
    vertices: np.ndarray, faces: np.ndarray, parts: np.ndarray | None = None
) -> tuple[TriMesh, list[str], int]:
    """Weld, drop degenerate and duplicate triangles, split non-manifold edges, cap holes,
    orient outward.

    Parameters
    ----------
    vertices : (m, 3) float64
    faces : (f, 3) int
    parts : (f,) int, the file's object of each triangle (OBJ ``o``/``g``, STL ``solid``,
        glTF mesh), or None: objects closed on their own are never welded to others

    Returns
    -------
    (mesh, warnings, bodies): the mesh carries the caps, if any, after its own vertices and
    faces (:attr:`TriMesh.cap_vertices`, :attr:`TriMesh.cap_faces`)

    Raises
    ------
    IsochorError
        No triangles, a surface that cannot be oriented, or no solid to keep (flat, a flat
        open sheet, loose triangles).
    """
    warns: list[str] = []
    welded = _weld_and_drop(vertices, faces, parts)
    if welded[4] or EdgeReport.of(welded[1], len(welded[0])).non_manifold:
        # the weld joins solids (edges of more than two triangles, faces that cancel):
        # keep apart the pieces the file's own indices keep apart, where each is closed
        pieces = _index_pieces(faces, parts)
        if pieces is not None:
            alone = _weld_and_drop(vertices, faces, pieces)
            if alone[2] and _joins(alone) < _joins(welded):
                welded = alone
                warns.append(
                    f"Kept {alone[2]} pieces apart that touch at shared coordinates (each "
                    "closed on its own: welding them would join solids along edges or faces)."
                )
                parts = None
    vertices, faces, apart, n_degenerate, n_duplicate = welded
    if apart and parts is not None:
        warns.append(
            f"Kept {apart} separate objects of the file apart (not welded where they touch)."
        )
    if n_degenerate:
        warns.append(f"Removed {n_degenerate} degenerate triangle(s) (a repeated corner).")
    if n_duplicate:
        warns.append(f"Removed {n_duplicate} duplicate triangle(s).")
    if len(faces) == 0:
        raise IsochorError("no triangles left after removing degenerate and duplicate ones")
    if n_degenerate or n_duplicate:  # (the weld keeps only the vertices in use)
        vertices, faces = compact(vertices, faces)
    report = EdgeReport.of(faces, len(vertices))
    if report.non_manifold:
        vertices, faces, cut = split_non_manifold(
            faces, vertices, report.counts, report.edge_of_corner
        )
        report = EdgeReport.of(faces, len(vertices))
        if report.non_manifold:
            raise IsochorError(
                f"the surface has {report.non_manifold} non-manifold edge(s) (shared by more "
                "than two triangles) that cannot be split into separate sheets"
            )
        warns.append(
            f"Split the surface into separate sheets along {cut} non-manifold edge(s) "
            "(edges shared by more than two triangles)."
        )
    faces, n_flipped = fix_winding(faces, report)
    if n_flipped:
        warns.append(
            f"Inconsistent winding repaired: {n_flipped} triangle(s) flipped to "
            "match their neighbours."
        )
        report = EdgeReport.of(faces, len(vertices))
    n_caps = n_cap_faces = 0
    labels, n_bodies = body_labels(faces, report)
    if report.boundary:
        sides, side_face = boundary_sides(faces, report.counts, report.edge_of_corner)
        points, cap_faces, loop_of_side, n_caps = cap_holes(vertices, faces, sides)
        n_cap_faces = len(cap_faces)
        vertices = np.concatenate([vertices, points])
        faces = np.concatenate([faces, cap_faces])
        # a cap joins the bodies around its loop (no new edge report needed)
        labels, n_bodies = _join_caps(labels, n_bodies, labels[side_face], loop_of_side, n_caps)
    arrangement = arrange(vertices, faces, labels, n_bodies)
    faces, turned_out, turned_in = orient(vertices, faces, labels, arrangement.depth)
    warns += _orientation_words(n_bodies, turned_out, turned_in)
    warns += overlap_words(vertices, faces, labels, n_bodies, arrangement)
    if not arrangement.checked:
        warns.append(
            f"{n_bodies} bodies: too large to check which lie inside or across others; "
            "each is taken as a separate solid facing outward."
        )
    # flat: the signed volume is lost in the rounding of the triangles' own volumes
    about_middle = tetra_volumes(vertices, faces, origin=np.median(vertices, axis=0))
    if n_caps:
        area = areas(vertices, faces)
        warns += _capped_words(labels, n_bodies, about_middle, area, len(faces) - n_cap_faces)
        own = len(faces) - n_cap_faces
        capped = CapSummary(n_caps, n_cap_faces, float(area[own:].sum()), float(area[:own].sum()))
        warns.insert(0, capped.sentence())
    volume = float(about_middle.sum())
    if not volume > 1e-9 * np.abs(about_middle).sum():
        raise IsochorError("the surface encloses no volume (it is flat): there is no solid to keep")
    far = far_vertices(vertices)
    # the lattice measures about the middle of the bounding box: a few far vertices move
    # it so far from the rest that the volume drowns in rounding there
    if far and abs(tetra_volumes(vertices, faces).sum() - volume) > PRECISION * volume:
        raise IsochorError(
            f"{far} vertex(es) lie so far from the rest (more than {FAR:g} times the model's "
            "typical size) that its volume cannot be measured precisely; a damaged file?"
        )
    if far:
        warns.append(
            f"{far} vertex(es) lie far from the rest, more than {FAR:g} times the model's "
            "typical size away (a damaged file?); the lattice is fitted around them too."
        )
    return TriMesh(vertices, faces, n_caps, n_cap_faces), warns, n_bodies


def _weld_and_drop(vertices, faces, parts):
    """(vertices, faces, closed parts kept apart, degenerate and duplicate triangles
    dropped): :func:`weld_parts`, then :func:`drop_degenerate` and :func:`drop_duplicates`."""
    vertices, faces, apart = weld_parts(vertices, faces, parts)
    faces, n_degenerate = drop_degenerate(faces)
    faces, n_duplicate = drop_duplicates(faces)
    return vertices, faces, apart, n_degenerate, n_duplicate


def _joins(welded) -> int:
    """How much a weld joined solids: its non-manifold edges and its cancelled triangles."""
    vertices, faces = welded[0], welded[1]
    return EdgeReport.of(faces, len(vertices)).non_manifold + welded[4] if len(faces) else 0


def _index_pieces(faces: np.ndarray, parts: np.ndarray | None) -> np.ndarray | None:
    """(f,) the piece of each triangle: triangles joined by edges of the file's own vertex
    indices, within the file's objects (``parts``); None for one piece."""
    labels, count = body_labels(faces)
    if count < 2:
        return None
    if parts is not None and len(parts) == len(faces):
        labels = np.unique(np.column_stack([parts, labels]), axis=0, return_inverse=True)[1]
    return np.asarray(labels).ravel()


def _join_caps(labels, n_bodies, body_of_side, loop_of_side, n_loops):
    """Body labels of the capped mesh: each loop's cap faces joined to the bodies whose
    faces its rim runs along (bodies still numbered in order of their first face)."""
    graph = sp.coo_matrix(
        (np.ones(len(body_of_side)), (body_of_side, n_bodies + loop_of_side)),
        shape=(n_bodies + n_loops, n_bodies + n_loops),
    )
    _, comp = connected_components(graph, directed=False)
    return np.concatenate([comp[labels], comp[n_bodies + loop_of_side]]), int(comp.max()) + 1


def overlap_words(vertices, faces, labels, n_bodies: int, arrangement) -> list[str]:
    """One sentence per pair of overlapping bodies; two copies of one shape said so."""
    words: list[str] = []
    if not arrangement.overlaps:
        return words
    counts = np.bincount(labels, minlength=n_bodies)
    volumes = np.bincount(labels, weights=tetra_volumes(vertices, faces), minlength=n_bodies)

    def extent(body: int) -> np.ndarray:
        corners = vertices[faces[labels == body].ravel()]
        return corners.max(axis=0) - corners.min(axis=0)

    for a, b in arrangement.overlaps:
        copies = (
            counts[a] == counts[b]
            and abs(volumes[a] - volumes[b]) <= 1e-3 * abs(volumes[a])
            and np.allclose(extent(a), extent(b), rtol=0, atol=1e-3 * extent(a).max())
        )
        if copies:
            words.append(
                f"Bodies {a + 1} and {b + 1} (of {n_bodies}, in file order) are two overlapping "
                "copies of one shape: each is kept as a solid, and the volume counts the part "
                "they share twice."
            )
        else:
            words.append(
                f"Bodies {a + 1} and {b + 1} (of {n_bodies}, in file order) overlap: the volume "
                "counts the part they share twice."
            )
    return words


#: a capped body whose volume is below this times its area^1.5 encloses nothing (a ball
#: has 0.094; a sheet capped flat has rounding)
FLAT_CAPPED = 1e-6


def _capped_words(labels, n_bodies, tetra, face_area, own_faces: int) -> list[str]:
    """Refuse when no capped body encloses a volume (a flat open sheet, loose triangles);
    a sentence for the flat open pieces among solid ones."""
    capped = np.zeros(n_bodies, dtype=bool)
    capped[labels[own_faces:]] = True
    volume = np.abs(np.bincount(labels, weights=tetra, minlength=n_bodies))
    rounding = np.bincount(labels, weights=np.abs(tetra), minlength=n_bodies)
    area = np.bincount(labels, weights=face_area, minlength=n_bodies)
    flat = capped & ((volume <= 1e-9 * rounding) | (volume <= FLAT_CAPPED * area**1.5))
    if flat.all():
        if n_bodies == 1:
            raise IsochorError(
                "the surface is a single flat open sheet: capping its hole encloses no "
                "volume, so there is no solid to keep"
            )
        raise IsochorError(
            f"the surface is {n_bodies} separate open pieces (loose triangles?), none of "
            "which encloses a volume when its holes are capped: there is no solid to keep"
        )
    if flat.any():
        return [
            f"{int(flat.sum())} open piece(s) enclose no volume even capped (flat sheets): "
            "they move with the model but hold no volume."
        ]
    return []


def _orientation_words(n_bodies: int, turned_out: int, turned_in: int) -> list[str]:
    if n_bodies == 1 and turned_out:
        return ["The surface faced inward (negative volume); turned to face outward."]
    words = []
    if turned_out:
        words.append(f"{turned_out} of {n_bodies} bodies faced inward; turned to face outward.")
    if turned_in:
        words.append(
            f"{turned_in} cavit{'y' if turned_in == 1 else 'ies'} (a body inside another) "
            "faced outward; turned to face inward, so it is hollow."
        )
    return words


def far_vertices(vertices: np.ndarray) -> int:
    """How many vertices lie more than :data:`FAR` times the median distance from the
    median point: a stray vertex of a damaged file, not part of the shape."""
    distance = np.linalg.norm(vertices - np.median(vertices, axis=0), axis=1)
    typical = float(np.median(distance))
    if typical <= 0:
        return 0
    far = int(np.sum(distance > FAR * typical))
    return far if far <= max(1, len(vertices) // 100) else 0


def weld_parts(
    vertices: np.ndarray, faces: np.ndarray, parts: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`weld`, never joining a part that is closed on its own to another part (the
    file's separate objects; parts open on their own, like an OBJ's groups of one surface,
    are welded together as one). Returns (vertices, faces, closed parts kept apart: 0
    when keeping them apart changed nothing)."""
    if parts is None or len(parts) != len(faces) or np.all(parts == parts[0]):
        return (*weld(vertices, faces), 0)
    _, parts = np.unique(parts, return_inverse=True)
    v, f, label = _per_part(vertices, faces, parts)
    v, f = weld(v, f, labels=label)
    report = EdgeReport.of(f, len(v))
    bad = report.counts[report.edge_of_corner] != 2
    open_part = np.zeros(int(parts.max()) + 1, dtype=bool)
    open_part[parts[bad.any(axis=1)]] = True
    closed = np.flatnonzero(~open_part)
    if len(closed) < 1 or (len(closed) == 1 and not open_part.any()):
        return (*weld(vertices, faces), 0)
    group = np.where(open_part, -1, np.arange(len(open_part)))[parts]
    v, f, label = _per_part(vertices, faces, group)
    v, f = weld(v, f, labels=label)
    together = weld(vertices, faces)[0]
    return v, f, (len(closed) if len(v) > len(together) else 0)


def _per_part(vertices, faces, parts):
    """Vertices repeated for each part that uses them: (vertices, faces, part of each)."""
    key = faces.ravel().astype(np.int64) * (int(parts.max()) + 2) + (np.repeat(parts, 3) + 1)
    unique, inverse = np.unique(key, return_inverse=True)
    n = int(parts.max()) + 2
    return vertices[unique // n], inverse.reshape(-1, 3), unique % n


def weld(
    vertices: np.ndarray,
    faces: np.ndarray,
    tolerance: float = WELD_TOLERANCE,
    labels: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices closer than ``tolerance`` times the model size (per coordinate grid);
    with ``labels`` (one int per vertex), only vertices of the same label.

    Keeps the first vertex of each group and the file's vertex order (a model with nothing
    to weld keeps its vertex numbers); returns only referenced vertices.
    """
    mask = np.zeros(len(vertices), dtype=bool)
    mask[faces] = True
    used = np.flatnonzero(mask)
    v = vertices[used]
    vt = np.ascontiguousarray(v.T)  # (3, m): ~8x faster reductions than along axis 0
    lo, hi = vt.min(axis=1), vt.max(axis=1)
    # the model's size, but no more than 10^4 typical edges: one stray far vertex must not
    # make the weld swallow the whole model
    size = float((hi - lo).max())
    typical = float(np.median(_side_lengths(vertices, faces))) if len(faces) else 0.0
    if typical > 0:
        size = min(size, 1e4 * typical)
    step = size * tolerance if size > 0 else 1.0
    keys = np.round((v - lo) / step).astype(np.int64)
    if labels is not None:
        keys = np.column_stack([keys, np.asarray(labels, dtype=np.int64)[used]])
    if not any_repeated_row(keys):  # nothing to weld: keep every used vertex, in order
        remap = np.empty(len(vertices), dtype=np.int64)
        remap[used] = np.arange(len(used))
        return v, remap[faces]
    inverse, first, _ = group_rows(keys)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))  # groups in order of first appearance
    remap = np.empty(len(vertices), dtype=np.int64)
    remap[used] = rank[inverse]
    return v[np.sort(first)], remap[faces]


def _side_lengths(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) length of each triangle's side 0-1: ``np.linalg.norm``'s numbers, faster."""
    vt = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)
    d = vt.take(faces[:, 1], axis=1) - vt.take(faces[:, 0], axis=1)
    return np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


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
    if not any_repeated_row(key):
        return faces, 0
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


def any_repeated_row(rows: np.ndarray) -> bool:
    """Whether two rows of a ``(k, c)`` int array may be equal: they share a 64-bit hash
    (one sort, much faster than :func:`group_rows`, which the callers then use to be sure)."""
    u = np.asarray(rows, dtype=np.int64).view(np.uint64)
    h = np.zeros(len(rows), dtype=np.uint64)
    for j in range(u.shape[1]):
        h ^= u[:, j]
        h *= _MIX
        h ^= h >> np.uint64(31)
    h = np.sort(h)
    return bool(np.any(h[1:] == h[:-1]))


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
        """The report of ``faces``; edges numbered in (lower, higher) vertex order."""
        forward, lo, hi, sign, n = _sides(faces, n_vertices)
        inverse, counts = _number_edges(lo, hi, n)
        balance = np.bincount(inverse, weights=sign, minlength=len(counts))
        return cls(inverse.reshape(forward.shape), forward, counts, balance.astype(np.int64))

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


def _sides(faces: np.ndarray, n_vertices: int):
    """The sides of the triangles: (forward (f, 3), lower and higher vertex, +-1 for forward
    or backward, and the number of vertices (at least ``n_vertices``)), flat, side by side."""
    a = np.asarray(faces).reshape(-1, 3)
    n = max(int(n_vertices), int(a.max(initial=-1)) + 1)
    small = np.int32 if max(n, a.size) < 2**31 - 1 else np.int64  # scipy's index type
    a = a.astype(small, copy=False)
    b = np.roll(a, -1, axis=1)
    forward = a < b
    sign = np.where(forward, small(1), small(-1)).ravel()
    return forward, np.minimum(a, b).ravel(), np.maximum(a, b).ravel(), sign, n


def _number_edges(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(number of each (lo, hi) pair among the distinct pairs in (lo, hi) order, how often
    each distinct pair occurs). A sparse matrix's counting sort: several times faster than
    sorting the pairs (``np.unique`` of ``lo * n + hi``), with the same numbers."""
    if len(lo) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    # to CSR, repeated entries summed; canonical = sorted by (row, column), one entry each
    table = sp.coo_array((np.ones(len(lo), dtype=lo.dtype), (lo, hi)), shape=(n, n)).tocsr()
    table.sum_duplicates()
    counts = table.data.astype(np.int64)
    table.data = np.arange(1, table.nnz + 1, dtype=lo.dtype)
    return (np.asarray(table[lo, hi]).ravel() - 1).astype(np.int64), counts


def balanced(faces: np.ndarray, n_vertices: int) -> bool:
    """Whether every edge is run as often one way as the other by the triangles: a closed
    surface (no boundary, nothing unbalanced in :class:`EdgeReport`), told without
    numbering the edges (one sparse sum of +-1 per directed side)."""
    _, lo, hi, sign, n = _sides(faces, n_vertices)
    return not sp.coo_array((sign, (lo, hi)), shape=(n, n)).tocsr().data.any()


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
    n = len(faces)
    face = np.repeat(np.arange(n, dtype=np.int32 if n < 2**31 else np.int64), 3)
    lowest = np.full(len(report.counts), n, dtype=face.dtype)
    np.minimum.at(lowest, edges, face)  # the lowest-numbered triangle on each edge...
    # ...and every other triangle on the edge joined to it
    other = lowest[edges]
    join = other != face
    graph = sp.coo_matrix((np.ones(int(join.sum())), (face[join], other[join])), shape=(n, n))
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
    if report.unbalanced == 0 or not np.any(report.balance[report.counts >= 2]):
        return faces, 0  # (a hole's rim is run one way only: that needs no flip)
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
