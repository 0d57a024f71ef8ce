"""Mesh files: read OBJ, PLY, STL and OFF into a clean closed :class:`TriMesh`, write results.

Reading (:func:`load_mesh`) goes through trimesh, then makes what the solver needs out of
what artists have:

1. polygons are triangulated (by trimesh's readers);
2. coincident vertices are welded by position (UV and normal seams, STL's repeated corners),
   within 1e-9 of the model size, so the weld does not depend on the model's units;
3. triangles with a repeated corner are dropped, and so are duplicate triangles (two
   copies of one triangle wound opposite ways cancel, like a double wall; same-way copies
   are kept once); unreferenced vertices are dropped;
4. the surface must be closed: every edge shared by exactly two triangles. Otherwise the
   file is refused, with the count of boundary edges (holes) and non-manifold edges. A
   pinched vertex (the paper's cow has one) is fine: only edges matter for the volume;
5. inconsistent winding is repaired by flipping the smaller side of every body (warning);
6. each body is turned to face outward, or inward for a cavity inside another body, so the
   signed volume is the solid's volume (warning when anything was flipped).

Any problem a file can have ends in one :class:`IsochorError` that names the file; trimesh's
own exceptions never reach the user.

Writing (:func:`save_mesh`): OBJ (``%.17g``, exact round trip), binary PLY with float64
vertices, or binary STL (float32 by the format), chosen by extension, written atomically.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from core.errors import IsochorError
from core.mesh import TriMesh
from core.scenario import atomic_write_bytes
from core.volume import signed_volume

READ_FORMATS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".off": "off"}
WRITE_FORMATS = (".obj", ".ply", ".stl")

#: vertices closer than this fraction of the model size are one vertex
WELD_TOLERANCE = 1e-9

#: above this many (point, triangle) pairs the cavity test is skipped (each body faces out)
NESTING_BUDGET = 50_000_000


@dataclass(frozen=True)
class LoadedMesh:
    """A model read from a file and made ready for the solver.

    Attributes
    ----------
    mesh : the closed, outward-wound, full-resolution triangle mesh
    warnings : what was repaired, one sentence each, for the user
    bodies : number of separate closed bodies (face-connected components)
    path : the file it came from
    """

    mesh: TriMesh
    warnings: list[str] = field(default_factory=list)
    bodies: int = 1
    path: Path | None = None

    @property
    def volume(self) -> float:
        """Enclosed volume (positive) of all bodies together."""
        return signed_volume(self.mesh.vertices, self.mesh.faces)


# -- reading ----------------------------------------------------------------------------------
def load_mesh(path: str | Path) -> LoadedMesh:
    """Read a closed triangle surface from an OBJ, PLY, STL or OFF file.

    Raises
    ------
    IsochorError
        The file is missing, unreadable, of an unknown format, holds no triangles, or its
        surface is not closed. The message starts with the file name.
    """
    path = Path(path)
    vertices, faces = _read_raw(path)
    try:
        mesh, warns, bodies = clean_closed_surface(vertices, faces)
    except IsochorError as exc:
        raise IsochorError(f"{path.name}: {exc}") from None
    return LoadedMesh(mesh, warns, bodies, path)


def load_levels(path: str | Path) -> tuple[list[TriMesh], list[str]]:
    """The level pyramid (coarse to fine, the last is the full mesh) and the load warnings.

    This is the :data:`core.scenario.LevelLoader` for models given by path.
    """
    from core.pyramid import build_pyramid  # noqa: PLC0415 (pyramid imports this module)

    loaded = load_mesh(path)
    return build_pyramid(loaded.mesh), list(loaded.warnings)


def _read_raw(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(m, 3) float64`` and triangles ``(f, 3) int64`` as the file holds them."""
    kind = READ_FORMATS.get(path.suffix.lower())
    if kind is None:
        known = ", ".join(s[1:].upper() for s in READ_FORMATS)
        raise IsochorError(
            f"{path.name}: unknown model format {path.suffix or '(no extension)'!r}; "
            f"Isochor reads {known}"
        )
    if not path.exists():
        raise IsochorError(f"{path}: no such file")
    if not path.is_file():
        raise IsochorError(f"{path}: not a file")
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise IsochorError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    if not data or data.isspace():
        raise IsochorError(f"{path.name}: the file is empty")
    import trimesh  # noqa: PLC0415 (heavy; only needed here)

    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            loaded = trimesh.load_mesh(io.BytesIO(data), file_type=kind, process=False)
            if isinstance(loaded, trimesh.Scene):
                loaded = loaded.to_mesh()
            vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), np.float64)
            faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), np.int64)
    except Exception as exc:  # noqa: BLE001 (trimesh raises many kinds on bad files)
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise IsochorError(
            f"{path.name}: not a readable {kind.upper()} file (damaged or truncated?): {detail}"
        ) from None
    if faces.size == 0:
        raise IsochorError(f"{path.name}: no triangles found (not a valid {kind.upper()} file, "
                           "or an empty mesh)")
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise IsochorError(f"{path.name}: not a triangle mesh")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise IsochorError(f"{path.name}: a face refers to a vertex that does not exist")
    if not np.all(np.isfinite(vertices[faces])):
        raise IsochorError(f"{path.name}: a vertex has a coordinate that is not a number")
    return vertices, faces


# -- cleaning ---------------------------------------------------------------------------------
def clean_closed_surface(
    vertices: np.ndarray, faces: np.ndarray
) -> tuple[TriMesh, list[str], int]:
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
        raise IsochorError(f"the surface is not closed: {report.describe()}; Isochor needs a "
                           "closed surface (a solid) to measure a volume")
    faces, n_flipped = fix_winding(faces, report)
    if n_flipped:
        warns.append(f"Inconsistent winding repaired: {n_flipped} triangle(s) flipped to "
                     "match their neighbours.")
    labels, n_bodies = body_labels(faces, report)
    faces, inward = orient_bodies(vertices, faces, labels, n_bodies)
    if inward:
        what = ("The surface faced inward (negative volume)" if n_bodies == 1 else
                f"{inward} of {n_bodies} bodies faced the wrong way")
        warns.append(f"{what}; flipped to face outward.")
    volume = signed_volume(vertices, faces)
    if not volume > 1e-12 * np.ptp(vertices, axis=0).max() ** 3:
        raise IsochorError("the surface encloses no volume (it is flat)")
    return TriMesh(vertices, faces), warns, n_bodies


def weld(vertices: np.ndarray, faces: np.ndarray,
         tolerance: float = WELD_TOLERANCE) -> tuple[np.ndarray, np.ndarray]:
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
    bad = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (
        faces[:, 2] == faces[:, 0])
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
            parts.append(f"{self.non_manifold} non-manifold edge(s) (shared by more than two "
                         "triangles)")
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
    graph = sp.coo_matrix((np.ones(int(same.sum())), (on_edge[:-1][same], on_edge[1:][same])),
                          shape=(n, n))
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


def orient_bodies(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray,
                  n_bodies: int) -> tuple[np.ndarray, int]:
    """Turn every body so that the total signed volume is the solid's volume.

    A body inside an even number of others (usually none) faces outward; one inside an odd
    number (a cavity) faces inward. Returns (faces, number of bodies flipped).
    """
    center = (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    v = vertices - center
    tri = v[faces]
    per_face = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    volumes = np.bincount(labels, weights=per_face, minlength=n_bodies)
    depth = nesting_depth(v, faces, labels, n_bodies) if n_bodies > 1 else np.zeros(1, int)
    wanted = np.where(depth % 2 == 0, 1.0, -1.0)
    flip_body = volumes * wanted < 0
    if not flip_body.any():
        return faces, 0
    flip = flip_body[labels]
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(flip_body.sum())


def nesting_depth(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray,
                  n_bodies: int) -> np.ndarray:
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
        body = tri[order[starts[a]:starts[a + 1]]]
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
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
               + np.einsum("ij,ij->i", a, c) * lb + np.einsum("ij,ij->i", b, c) * la)
        out[i] = np.sum(np.arctan2(num, den)) / (2 * np.pi)
    return out


# -- writing ----------------------------------------------------------------------------------
def save_mesh(path: str | Path, mesh: TriMesh) -> None:
    """Write ``mesh`` as OBJ, PLY or STL (by the extension), atomically.

    OBJ keeps every digit (``%.17g``); PLY is binary with float64 vertices; STL is binary
    with float32 coordinates, as the format defines.

    Raises
    ------
    IsochorError
        An unsupported extension.
    OSError
        The folder does not exist or cannot be written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_FORMATS:
        known = ", ".join(s[1:].upper() for s in WRITE_FORMATS)
        raise IsochorError(f"{path.name}: cannot write {suffix or 'a file without extension'};"
                           f" use one of {known} (by the file extension)")
    atomic_write_bytes(path, mesh_bytes(mesh, suffix))


def mesh_bytes(mesh: TriMesh, suffix: str) -> bytes:
    """The file contents of ``mesh`` in the format of ``suffix`` (.obj, .ply or .stl)."""
    v, f = mesh.vertices, mesh.faces
    if suffix == ".obj":
        buf = io.BytesIO()
        buf.write(b"# written by Isochor\n")
        np.savetxt(buf, v, fmt="v %.17g %.17g %.17g")
        np.savetxt(buf, f + 1, fmt="f %d %d %d")
        return buf.getvalue()
    if suffix == ".ply":
        header = (
            "ply\nformat binary_little_endian 1.0\ncomment written by Isochor\n"
            f"element vertex {len(v)}\nproperty double x\nproperty double y\n"
            f"property double z\nelement face {len(f)}\n"
            "property list uchar int vertex_indices\nend_header\n"
        ).encode("ascii")
        rows = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
        rows["n"], rows["i"] = 3, f
        return header + v.astype("<f8").tobytes() + rows.tobytes()
    if suffix == ".stl":
        tri = v[f]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
        rows = np.zeros(len(f), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)),
                                       ("a", "<u2")])
        rows["n"], rows["v"] = normals, tri
        head = b"binary STL written by Isochor".ljust(80, b" ")
        return head + np.uint32(len(f)).tobytes() + rows.tobytes()
    raise IsochorError(f"cannot write {suffix!r} files")
