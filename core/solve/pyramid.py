"""The level pyramid of a loaded mesh: QEM simplification, checked level by level.

:func:`build_pyramid` simplifies the full mesh with fast-simplification (Garland-Heckbert
quadric error metrics, the [GH97] the paper uses for the club and the cow) down to about
``min_faces`` triangles, each level about ``ratio`` times coarser than the next. Each level
is simplified from the previous (finer) good level, so a 1M-triangle mesh takes seconds.

fast-simplification can return broken meshes (holes, folds, a UV sphere at 27% of its
volume), so every level is checked and a level that fails is simplified again with a
slightly larger target; when that fails too the pyramid stops there (fewer, finer levels:
slower, never wrong). A level passes when, body by body,

* it is a closed surface: every edge is run as often one way as the other by its
  triangles, with no boundary. This is exactly what makes the signed volume and its
  gradient well defined (independent of the origin). QEM sometimes pinches two sheets
  along an edge (four triangles on one edge, two each way); such a level still encloses
  a well-defined volume and is kept;
* its volume is within ``volume_tolerance(n)`` of the full body's. Measured on the shared
  models (cow, spot, bunny, kitten, fertility, torus, torus knot, armadillo), QEM loses about
  ``10 / n`` of the volume at ``n`` triangles: 0.6% at 1450, 2.7% at 362, 10% at 90, 50%
  at 22. The bound allows four times that, at least 5% and at most 25%: a honest coarse
  level passes, a folded one (or a torus reduced to a flat ring) does not;
* no vertex lies more than 5% of the model size outside the full mesh's bounding box
  (QEM's optimal vertex positions stay within 2.5% on the shared models).

Bodies (face-connected components) are simplified one by one with proportional targets, so
a small body never vanishes; a body too small to simplify (fewer than ``4 * MIN_BODY``
triangles) is kept whole. Simplification runs on coordinates normalised to the unit box,
because fast-simplification's collapse thresholds are absolute: the pyramid of a model
scaled by 1000 is the same pyramid scaled by 1000.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import contextmanager

import numpy as np

from ..io.repair import EdgeReport, balanced, body_labels, compact, drop_degenerate, drop_duplicates
from ..mesh import TriMesh
from ..volume import signed_volume

#: fewest triangles a simplified body may have
MIN_BODY = 8
#: how far outside the full mesh's bounding box a level's vertex may be, / model size
MAX_OUTSIDE = 0.05
#: retries of a failed level: target = factor * the first target
RETRY_FACTORS = (1.25, 1.6)

# fast-simplification keeps its mesh in global C++ state: one simplification at a time
_LOCK = threading.Lock()


def volume_tolerance(n_faces: int) -> float:
    """Largest relative volume loss accepted for a level of ``n_faces`` triangles."""
    return float(min(0.25, max(0.05, 40.0 / max(n_faces, 1))))


def build_pyramid(
    mesh: TriMesh,
    min_faces: int = 16,
    ratio: float = 4.0,
    notes: list[str] | None = None,
    bodies: int | None = None,
    progress: Callable[[float], None] | None = None,
) -> list[TriMesh]:
    """Levels coarse to fine for the multi-level solve; the last is ``mesh`` itself.

    Parameters
    ----------
    mesh : a closed, outward-wound mesh (as :func:`isochor.core.io.meshio.load_mesh` returns)
    min_faces : no level has fewer triangles than this (about: the coarsest has
        ``min_faces`` to ``ratio * min_faces``)
    ratio : triangle ratio between neighbouring levels
    notes : when given, gets one line per rejected level (why), for benchmarks and tests
    bodies : the number of bodies when known (as the cleaning counted them); 1 saves
        looking for them again
    progress : called with the share of the work done (0 to 1) after each level (about:
        a level costs in proportion to the triangles it starts from)
    """
    lo, hi = mesh.bounds
    center, size = mesh.center, mesh.size
    if not size > 0:
        return [mesh]
    unit = TriMesh((mesh.vertices - center) / size, mesh.faces)
    parts = [unit] if bodies == 1 else split_bodies(unit)
    checks = [_BodyCheck(b, (lo - center) / size, (hi - center) / size) for b in parts]
    levels = [mesh]
    current = parts
    while True:
        n = sum(b.n_faces for b in current)
        if n / ratio < min_faces:
            break
        coarser = _coarser(current, checks, ratio, notes)
        if coarser is None or sum(b.n_faces for b in coarser) > n / 2:
            break
        levels.append(_join(coarser, center, size))
        current = coarser
        if progress is not None:
            progress(1.0 - levels[-1].n_faces / max(mesh.n_faces, 1))
    return levels[::-1]


def split_bodies(mesh: TriMesh) -> list[TriMesh]:
    """The face-connected components of ``mesh``, each with its own compact vertices."""
    labels, n = body_labels(mesh.faces)
    if n == 1:
        return [mesh]
    return [TriMesh(*compact(mesh.vertices, mesh.faces[labels == b])) for b in range(n)]


class _BodyCheck:
    """The references a simplified body is checked against."""

    def __init__(self, body: TriMesh, lo: np.ndarray, hi: np.ndarray) -> None:
        self.volume = signed_volume(body.vertices, body.faces)
        self.lo, self.hi = lo - MAX_OUTSIDE, hi + MAX_OUTSIDE

    def problem(self, cand: TriMesh) -> str | None:
        """Why ``cand`` is not a good level of this body, or None."""
        if not balanced(cand.faces, cand.n_vertices):
            report = EdgeReport.of(cand.faces, cand.n_vertices)
            return f"not closed ({report.boundary} boundary, {report.unbalanced} unbalanced edges)"
        if np.any(cand.vertices < self.lo) or np.any(cand.vertices > self.hi):
            return "a vertex far outside the model's bounding box"
        v = signed_volume(cand.vertices, cand.faces)
        loss = abs(v - self.volume) / abs(self.volume)
        if loss > volume_tolerance(cand.n_faces):
            return f"volume off by {100 * loss:.1f}%"
        return None


def _coarser(
    bodies: list[TriMesh], checks: list[_BodyCheck], ratio: float, notes: list[str] | None
) -> list[TriMesh] | None:
    """The next coarser level, body by body, or None when a body cannot be simplified."""
    out = []
    for body, check in zip(bodies, checks):
        target = max(round(body.n_faces / ratio), MIN_BODY)
        if target >= body.n_faces or body.n_faces < 4 * MIN_BODY:
            out.append(body)
            continue
        good = None
        for factor in (1.0, *RETRY_FACTORS):
            t = round(target * factor)
            if t >= body.n_faces:
                break
            cand = simplify(body, t)
            why = check.problem(cand) if cand is not None else "nothing left"
            if why is None:
                good = cand
                break
            if notes is not None:
                notes.append(f"{body.n_faces} -> {t} triangles rejected: {why}")
        if good is None:
            return None
        out.append(good)
    return out


def simplify(mesh: TriMesh, target: int) -> TriMesh | None:
    """QEM-simplify ``mesh`` to about ``target`` triangles; tidy the result (drop
    degenerate and cancelling triangles and unused vertices). None if nothing is left."""
    import fast_simplification  # compiled extension: imported on the first use

    with _LOCK, _writable(mesh.vertices) as vertices, _writable(mesh.faces) as corners:
        points, faces = fast_simplification.simplify(vertices, corners, target_count=int(target))
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    faces, _ = drop_degenerate(faces)
    faces, _ = drop_duplicates(faces)
    if len(faces) < 4:
        return None
    return TriMesh(*compact(np.asarray(points, dtype=np.float64), faces))


@contextmanager
def _writable(a: np.ndarray):
    """``a`` writable for the extension, which takes writable arrays only and reads them
    into its own: a frozen array that owns its data is unfrozen for the call (copies of
    the finest level's vertices and faces took 26 bytes a triangle at the peak), any
    other copied."""
    if a.flags.writeable or not (a.flags.owndata and a.flags.c_contiguous):
        yield a if a.flags.writeable else np.array(a)
        return
    a.flags.writeable = True
    try:
        yield a
    finally:
        a.flags.writeable = False


def _join(bodies: list[TriMesh], center: np.ndarray, size: float) -> TriMesh:
    """One mesh of all bodies, back in world coordinates."""
    offsets = np.cumsum([0] + [b.n_vertices for b in bodies[:-1]])
    vertices = np.concatenate([b.vertices for b in bodies]) * size + center
    faces = np.concatenate([b.faces + o for b, o in zip(bodies, offsets)])
    return TriMesh(vertices, faces)
