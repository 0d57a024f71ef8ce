"""What a solve holds besides the pinned nodes, as constraints on one pyramid level: functions
of the node positions (the :class:`~isochor.core.goal.spec.Goal` says which).

The paper keeps one number, the total signed volume. A goal may instead keep

* the volume of every solid body (``preserve="per-body"``: the parts of an assembly keep
  their proportions). A body is a closed shell together with the cavities directly inside
  it (by :func:`isochor.core.bodies.arrange`), so a hollow part keeps its material volume;
* the centre of mass of the solid (``keep_centroid``, the paper's future work): three more
  constraints ``M(X) - V(X) C0 = 0``, where ``M`` is the first moment (exact for the
  triangle mesh, :class:`isochor.core.volume.MomentOperator`). With the volume held at
  ``t V0`` this is exactly ``C = C0``, and unlike ``M / V`` it is a polynomial in the nodes.

Every constraint is normalised so that ``|c_i| <= tol_volume`` means it is met:

* a volume by ``min(1, t) |V0|``: the error is measured against the original volume and,
  for a shrinking target, against the target too (a target of 1% of the volume must not
  pass with 50% of the target missing);
* the centroid by ``CENTROID_SCALE * t |V0| * size``: met means the centre of mass moved by
  at most ``CENTROID_SCALE * tol_volume`` of the object's size.

Each level measures against its own rest values (the paper's Eq 27), so a coarse level's
discretisation error does not show up as a constraint violation.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..bodies import arrange, tetra_volumes
from ..io.repair import body_labels, compact
from ..lattice import Lattice, PointBasis
from ..localbasis import LocalPointBasis
from ..mesh import TriMesh
from ..volume import MomentOperator, VolumeOperator, locality_order
from .spec import Goal

#: the centroid is held to this fraction of the volume tolerance, in object sizes
CENTROID_SCALE = 0.1
#: a level with at least this many triangles keeps its basis and operators in
#: :func:`isochor.core.volume.locality_order` (see :class:`Level`)
LOCALITY_TRIANGLES = 100_000


@dataclass(frozen=True)
class Bodies:
    """The solid bodies of the full mesh: which shell (face-connected component) belongs
    to which body, and each body's rest volume."""

    solid_of_shell: np.ndarray  #: (shells,) int
    shell_centers: np.ndarray  #: (shells, 3) mean vertex of each shell, to match levels
    solid_of_face: np.ndarray  #: (faces,) int, the body of each face of the full mesh
    volumes: np.ndarray  #: (bodies,) rest volume of each body (its shells' sum)

    @classmethod
    def of(cls, mesh: TriMesh, count: int | None = None) -> Bodies:
        """The bodies of ``mesh``; ``count``, when loading already counted them: one body
        needs no labelling of faces, nor any containment test."""
        if count == 1:
            one = np.zeros(1, dtype=np.intp)
            used = mesh.vertices if mesh.n_vertices else np.zeros((1, 3))
            bodies = cls(one, used.mean(axis=0)[None], np.zeros(mesh.n_faces, np.intp), one)
            return replace(bodies, volumes=bodies.measure(mesh.vertices, mesh.faces))
        labels, n = body_labels(mesh.faces)
        depth = arrange(mesh.vertices, mesh.faces, labels, n).inside
        solid = np.arange(n)
        for s in range(n):  # a cavity (odd depth) belongs to its innermost container
            d = int(depth[s].sum())
            if d % 2 == 1:
                parents = [p for p in np.flatnonzero(depth[s]) if int(depth[p].sum()) == d - 1]
                solid[s] = parents[0] if parents else s
        _, solid = np.unique(solid, return_inverse=True)
        centers = np.array(
            [compact(mesh.vertices, mesh.faces[labels == s])[0].mean(axis=0) for s in range(n)]
        )
        bodies = cls(solid, centers, solid[labels], np.zeros(0))
        return replace(bodies, volumes=bodies.measure(mesh.vertices, mesh.faces))

    def measure(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(bodies,) volume of each body of the full mesh with these vertex positions
        (:func:`isochor.core.bodies.tetra_volumes`: the numbers of
        :func:`isochor.core.volume.face_volumes`, three times faster)."""
        vols = tetra_volumes(vertices, faces)
        return np.bincount(
            self.solid_of_face, weights=vols, minlength=self.solid_of_shell.max() + 1
        )

    @property
    def count(self) -> int:
        return len(self.volumes)


class _Part:
    """One shell of a level: its own basis and volume operator."""

    def __init__(self, lattice: Lattice, vertices: np.ndarray, faces: np.ndarray) -> None:
        self.basis: PointBasis | LocalPointBasis = lattice.point_basis(vertices)
        self.op = VolumeOperator(faces, len(vertices))


class Level:
    """What one pyramid level needs for fast evaluations, computed once; the parts that
    only some goals use (shells, first moment) on first use.

    A big level (:data:`LOCALITY_TRIANGLES`) keeps its basis, volume and moment operators
    over its vertices in :func:`isochor.core.volume.locality_order` (``order``; the faces
    renumbered to match): the volume's gathers stay in the caches. Only :meth:`deform`
    gives points, in the mesh's own order."""

    def __init__(
        self,
        lattice: Lattice,
        mesh: TriMesh,
        center: np.ndarray,
        rest_volume: float | None = None,
    ) -> None:
        self.lattice, self.mesh, self.center = lattice, mesh, center
        self.triangles = mesh.n_faces
        self.order: np.ndarray | None = None
        #: the faces over the basis's points (the mesh's own faces, or renumbered)
        self.faces = mesh.faces
        vertices = mesh.vertices
        if mesh.n_faces >= LOCALITY_TRIANGLES:
            self.order = order = locality_order(mesh.faces, mesh.n_vertices)
            # int32: the renumbered faces cost 12 bytes a triangle, not 24
            place = np.empty(len(order), np.int32 if len(order) < 2**31 else np.int64)
            place[order] = np.arange(len(order))
            self.faces, vertices = place[mesh.faces], mesh.vertices[order]
            del place
        self.basis: PointBasis | LocalPointBasis = lattice.point_basis(vertices)
        self.volume_op = VolumeOperator(self.faces, mesh.n_vertices)
        # the rest lattice's FFD is the identity: the level's own vertices, not the basis
        # applied to the rest nodes (the same volume to rounding, without a pass of the
        # basis over the level: the full mesh's costs a first solve 1-3 ms); a volume
        # measured before (the full mesh's, when its surface was made) is taken as it is
        # (another pass of the volume: 1 ms of the torus examples' first solve)
        if rest_volume is None:
            rest_volume = self.volume_op(vertices, center)
        self.rest_volume = float(rest_volume)
        del vertices
        self._last: tuple[bytes | None, float] = (None, 0.0)
        self._parts: tuple[list[_Part], np.ndarray] | None = None
        self._rest_bodies: np.ndarray | None = None

    def deform(self, nodes: np.ndarray) -> np.ndarray:
        """(m, 3) the level's vertices moved by ``nodes``, in the mesh's order."""
        points = self.basis.apply(nodes)
        if self.order is None:
            return points
        out = np.empty_like(points)
        out[self.order] = points
        return out

    def local(self, nodes: np.ndarray) -> np.ndarray:
        """The level's deformed vertices relative to ``center``: the basis applied to the
        nodes relative to it (the same points, as the basis sums to 1). A model far from
        the origin (1e14 away, 1 across) keeps its digits: applied to the nodes
        themselves, every point would be rounded at the offset's scale first."""
        return self.basis.apply(np.asarray(nodes, dtype=np.float64) - self.center)

    def volume(self, nodes: np.ndarray) -> float:
        # One-entry memo: the stopping test and the result ask the full mesh for the
        # volume of the same nodes, and on a big mesh that is the costliest call there is.
        # The solver's last evaluation fills it too (:meth:`volume_and_gradient`): a
        # level's end asks for the volume where its last step was evaluated.
        key = np.asarray(nodes, dtype=np.float64).tobytes()
        last = self._last
        if last[0] == key:
            return last[1]
        v = self.volume_op(self.local(nodes))
        self._last = (key, v)
        return v

    def parameters(self) -> np.ndarray:
        """(3, m) the lattice coordinates of the level's vertices, in the mesh's order."""
        uvw = self.basis.uvw
        if self.order is None:
            return uvw
        out = np.empty_like(uvw)
        out[:, self.order] = uvw
        return out

    def knows(self, nodes: np.ndarray) -> bool:
        """Whether the volume at ``nodes`` is at hand (the memo of :meth:`volume`)."""
        return self._last[0] == np.asarray(nodes, dtype=np.float64).tobytes()

    def volume_of(self, nodes: np.ndarray, points: np.ndarray) -> float:
        """The volume at ``nodes`` from the level's vertices moved by them, relative to
        ``center`` ((3, m) in the mesh's order), made elsewhere (the fold check's pass,
        :meth:`isochor.core.goal.folds.FoldCheck.survey`); :meth:`volume` at the same nodes
        then reads it."""
        rows = points if self.order is None else points[:, self.order]
        v = self.volume_op(np.asarray(rows, dtype=np.float64).T)
        self._last = (np.asarray(nodes, dtype=np.float64).tobytes(), v)
        return v

    def volume_and_gradient(self, nodes: np.ndarray) -> tuple[float, np.ndarray]:
        """The volume and its gradient to the nodes (one compiled pass where it can:
        :meth:`core.volume.VolumeOperator.node_gradient`, the same numbers)."""
        nodes = np.asarray(nodes, dtype=np.float64)
        v, dv = self.volume_op.node_gradient(self.basis, nodes - self.center)
        self._last = (nodes.tobytes(), v)
        return v, dv

    def parts(self, bodies: Bodies) -> tuple[list[_Part], np.ndarray]:
        """The level's shells and the body each belongs to (matched to the full mesh's
        shells by order, or by nearest centre where simplification changed their number)."""
        if self._parts is None:
            labels, n = body_labels(self.mesh.faces)
            shells = [compact(self.mesh.vertices, self.mesh.faces[labels == s]) for s in range(n)]
            if n == len(bodies.solid_of_shell):
                owner = bodies.solid_of_shell
            else:
                centers = np.array([v.mean(axis=0) for v, _ in shells])
                gap = np.linalg.norm(centers[:, None] - bodies.shell_centers[None], axis=2)
                owner = bodies.solid_of_shell[np.argmin(gap, axis=1)]
            self._parts = ([_Part(self.lattice, v, f) for v, f in shells], owner)
        return self._parts

    def body_volumes(self, nodes: np.ndarray, bodies: Bodies) -> np.ndarray:
        parts, owner = self.parts(bodies)
        vols = [p.op(p.basis.apply(nodes - self.center)) for p in parts]
        return np.bincount(owner, weights=vols, minlength=bodies.count)

    def rest_body_volumes(self, bodies: Bodies) -> np.ndarray:
        """Each body's volume on this level at rest, computed once (every solve's
        constraints on this level start from it)."""
        if self._rest_bodies is None:
            self._rest_bodies = self.body_volumes(self.lattice.rest_nodes, bodies)
        return self._rest_bodies

    @cached_property
    def moment_op(self) -> MomentOperator:
        return MomentOperator(self.faces, self.mesh.n_vertices)

    @cached_property
    def rest_centroid(self) -> np.ndarray:
        """Centre of mass at rest, relative to ``center``."""
        v = self.mesh.vertices if self.order is None else self.mesh.vertices[self.order]
        m, _ = self.moment_op.value_and_gradient(v, self.center)
        return m / self.rest_volume

    def moment_and_gradient(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First moment about ``center`` (3,) and its gradient (3, nodes, 3)."""
        m, dm = self.moment_op.value_and_gradient(self.local(nodes))
        return m, np.stack([self.basis.apply_transpose(d) for d in dm])


class Constraints:
    """The goal's constraints on one level: ``c(X)`` (m,) and ``dc/dX`` (m, nodes, 3),
    normalised as the module notes say.

    Parameters
    ----------
    level : the pyramid level
    goal : what to hold
    bodies : the full mesh's bodies (for ``per-body``)
    v_full : the full mesh's rest volume (the reference of every normalisation)
    size : object size
    extra : linear constraints that hold on every level alike (the handles,
        :class:`isochor.core.goal.handles.HandleSystem`: ``count``, ``values(X)``, ``jacobian``)
    """

    def __init__(
        self,
        level: Level,
        goal: Goal,
        bodies: Bodies | None,
        v_full: float,
        size: float,
        extra=None,
    ) -> None:
        self.level, self.goal, self.bodies, self.extra = level, goal, bodies, extra
        t = goal.target_ratio
        if goal.preserve == "per-body" and bodies is not None:
            self.targets = t * level.rest_body_volumes(bodies)
            self.scales = min(1.0, t) * np.abs(bodies.volumes)
        else:
            self.targets = np.array([t * level.rest_volume])
            self.scales = np.array([min(1.0, t) * abs(v_full)])
        self.centroid_scale = CENTROID_SCALE * t * abs(v_full) * size
        self.own = len(self.targets) + (3 if goal.keep_centroid else 0)
        self.count = self.own + (extra.count if extra is not None else 0)

    def values(self, nodes: np.ndarray) -> np.ndarray:
        lvl = self.level
        if self.goal.preserve == "per-body" and self.bodies is not None:
            vols = lvl.body_volumes(nodes, self.bodies)
        else:
            vols = np.array([lvl.volume(nodes)])
        out = [(vols - self.targets) / self.scales]
        if self.goal.keep_centroid:
            m, _ = lvl.moment_and_gradient(nodes)
            out.append((m - vols.sum() * lvl.rest_centroid) / self.centroid_scale)
        if self.extra is not None:
            out.append(self.extra.values(nodes))
        return np.concatenate(out)

    def values_and_jacobian(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lvl = self.level
        if self.goal.preserve == "per-body" and self.bodies is not None:
            parts, owner = lvl.parts(self.bodies)
            vols = np.zeros(self.bodies.count)
            dvols = np.zeros((self.bodies.count, *nodes.shape))
            for part, b in zip(parts, owner):
                v, dp = part.op.node_gradient(part.basis, nodes - lvl.center)
                vols[b] += v
                dvols[b] += dp
        else:
            v, dv = lvl.volume_and_gradient(nodes)
            vols, dvols = np.array([v]), dv[None]
        c = [(vols - self.targets) / self.scales]
        dc = [dvols / self.scales[:, None, None]]
        if self.goal.keep_centroid:
            m, dm = lvl.moment_and_gradient(nodes)
            c0 = lvl.rest_centroid
            c.append((m - vols.sum() * c0) / self.centroid_scale)
            dv_total = dvols.sum(axis=0)
            dc.append((dm - c0[:, None, None] * dv_total[None]) / self.centroid_scale)
        if self.extra is not None:
            c.append(self.extra.values(nodes))
            dc.append(self.extra.jacobian)
        return np.concatenate(c), np.concatenate(dc)
