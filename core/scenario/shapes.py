"""Built-in shapes with a parametric form, sampled uniformly level by level.

As in the paper (Sec 5, torus compression) each level samples the parameter domain twice as
finely in each direction as the last, so levels have about 4 times more triangles:

- torus: (u, v) grid on the two angles, 16, 64, 256, ... triangles. Alternate rings are
  staggered by half a step: an unstaggered 16-triangle torus grid has flat cross-sections
  and encloses no volume at all.
- sphere: the icosahedron subdivided 4-to-1 and projected, 20, 80, 320, ... triangles.
- club: the paper's rounded club, a sphere deformed by a fixed FFD (a long body that swells
  towards one end), sampled like the sphere.
- cup: an open container, one sheet of zero thickness (a flat bottom and a flared wall, open
  at its rim), the paper's "container whose capacity is given a priori": its rim is capped
  virtually (:mod:`isochor.core.io.caps`), so the volume kept is its capacity. 8 segments
  by 4 rings, doubling in each direction level by level.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from math import pi

import numpy as np

from ..errors import IsochorError
from ..lattice import Lattice
from ..mesh import TriMesh
from ..validate import number
from ..volume import signed_volume


def torus(nu: int, nv: int, major: float = 1.0, minor: float = 0.4) -> TriMesh:
    """A torus around the z axis with ``nu`` rings of ``nv`` vertices; ``2 nu nv`` triangles.

    Ring ``i`` sits at angle ``2 pi i / nu`` around the axis; its vertices are at tube angles
    ``2 pi (j + (i % 2) / 2) / nv`` (staggered), so ``nu`` must be even.
    """
    if nu % 2 or nu < 4 or nv < 2:
        raise ValueError("torus needs an even nu >= 4 and nv >= 2")
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    u = 2 * pi * i / nu
    v = 2 * pi * (j + 0.5 * (i % 2)) / nv
    ring = major + minor * np.cos(v)
    verts = np.stack([ring * np.cos(u), ring * np.sin(u), minor * np.sin(v)], -1).reshape(-1, 3)
    a, b = (x[:, :, None] for x in np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij"))
    here, up = (a % nu) * nv + b % nv, (a % nu) * nv + (b + 1) % nv
    nxt, nxt_up = ((a + 1) % nu) * nv + b % nv, ((a + 1) % nu) * nv + (b + 1) % nv
    even = a % 2 == 0  # ring a+1 is shifted by +1/2 relative to ring a (odd: a to a+1)
    first = np.where(
        even, np.concatenate([here, nxt, up], 2), np.concatenate([here, nxt_up, up], 2)
    )
    second = np.where(
        even, np.concatenate([up, nxt, nxt_up], 2), np.concatenate([here, nxt, nxt_up], 2)
    )
    faces = np.stack([first, second], axis=2).reshape(-1, 3)  # per (a, b): the two triangles
    return _outward(TriMesh(verts, faces))


def torus_levels(n_levels: int = 7, major: float = 1.0, minor: float = 0.4) -> list[TriMesh]:
    """16, 64, 256, ... triangles (``n_levels`` of them)."""
    return [torus(4 * 2**k, 2 * 2**k, major, minor) for k in range(n_levels)]


def torus_volume(major: float = 1.0, minor: float = 0.4) -> float:
    return 2 * pi**2 * major * minor**2


_ICO_T = (1 + 5**0.5) / 2
_ICO_V = np.array(
    [
        (-1, _ICO_T, 0),
        (1, _ICO_T, 0),
        (-1, -_ICO_T, 0),
        (1, -_ICO_T, 0),
        (0, -1, _ICO_T),
        (0, 1, _ICO_T),
        (0, -1, -_ICO_T),
        (0, 1, -_ICO_T),
        (_ICO_T, 0, -1),
        (_ICO_T, 0, 1),
        (-_ICO_T, 0, -1),
        (-_ICO_T, 0, 1),
    ],
    dtype=float,
)
_ICO_F = np.array(
    [
        (0, 11, 5),
        (0, 5, 1),
        (0, 1, 7),
        (0, 7, 10),
        (0, 10, 11),
        (1, 5, 9),
        (5, 11, 4),
        (11, 10, 2),
        (10, 7, 6),
        (7, 1, 8),
        (3, 9, 4),
        (3, 4, 2),
        (3, 2, 6),
        (3, 6, 8),
        (3, 8, 9),
        (4, 9, 5),
        (2, 4, 11),
        (6, 2, 10),
        (8, 6, 7),
        (9, 8, 1),
    ]
)


def _subdivide(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split every triangle in 4 at its edge midpoints (shared midpoints are shared)."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    uniq, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = len(verts) + inverse.reshape(3, -1).T  # (f, 3): midpoints of edges 01, 12, 20
    verts = np.concatenate([verts, (verts[uniq[:, 0]] + verts[uniq[:, 1]]) / 2])
    a, b, c = faces.T
    ab, bc, ca = mid.T
    faces = np.concatenate(
        [np.stack(t, 1) for t in [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]]
    )
    return verts, faces


def sphere_levels(n_levels: int = 6, radius: float = 1.0) -> list[TriMesh]:
    """Icospheres with 20, 80, 320, ... triangles."""
    v, f = _ICO_V / np.linalg.norm(_ICO_V[0]), _ICO_F
    out = []
    for _ in range(n_levels):
        out.append(_outward(TriMesh(radius * v, f)))
        v, f = _subdivide(v, f)
        v = v / np.linalg.norm(v, axis=1, keepdims=True)
    return out


def sphere_volume(radius: float = 1.0) -> float:
    return 4 / 3 * pi * radius**3


def club_lattice() -> tuple[Lattice, np.ndarray]:
    """The fixed FFD that turns the unit sphere into the rounded club: a 4x3x3 lattice
    whose nodes stretch x by 3 and widen the cross-section from 0.55 at the handle (x < 0)
    to 1.1 at the head (x > 0)."""
    lattice = Lattice((4, 3, 3), np.full(3, -1.0), 2.0 * np.eye(3))
    nodes = lattice.rest_nodes.copy()
    t = (nodes[:, 0] + 1) / 2  # 0 at the handle, 1 at the head
    width = 0.55 + 0.55 * t**1.5
    nodes[:, 0] *= 3.0
    nodes[:, 1:] *= width[:, None]
    return lattice, nodes


def club_levels(n_levels: int = 6) -> list[TriMesh]:
    """The rounded club sampled like the sphere: 20, 80, 320, ... triangles."""
    lattice, nodes = club_lattice()
    return [
        _outward(TriMesh(lattice.deform(m.vertices, nodes), m.faces))
        for m in sphere_levels(n_levels)
    ]


def cup(segments: int, rings: int, radius: float = 1.0) -> TriMesh:
    """An open cup around the z axis, open at the top (not capped): a flat bottom of radius
    ``0.7 radius`` and a wall flaring to ``radius`` at height ``1.6 radius``, ``rings`` rings
    of ``segments`` vertices on the profile (the bottom's centre apart), wound outward."""
    t = np.linspace(0.0, 1.0, rings + 1)[1:]  # the profile past the bottom's centre
    base = 0.35  # the first third of the profile is the bottom
    r = np.where(
        t <= base, 0.7 * t / base, 0.7 + 0.3 * np.clip((t - base) / (1 - base), 0, 1) ** 1.5
    )
    z = np.where(t <= base, 0.0, 1.6 * (t - base) / (1 - base))
    angle = 2 * pi * np.arange(segments) / segments
    ring = np.stack(
        [
            np.outer(r, np.cos(angle)),
            np.outer(r, np.sin(angle)),
            np.repeat(z, segments).reshape(rings, -1),
        ],
        axis=-1,
    ).reshape(-1, 3)
    verts = radius * np.vstack([[0.0, 0.0, 0.0], ring])
    idx = lambda a, b: 1 + a * segments + b % segments  # noqa: E731
    faces = [(0, idx(0, b + 1), idx(0, b)) for b in range(segments)]
    for a in range(rings - 1):
        for b in range(segments):
            faces += [(idx(a, b), idx(a, b + 1), idx(a + 1, b + 1))]
            faces += [(idx(a, b), idx(a + 1, b + 1), idx(a + 1, b))]
    return TriMesh(verts, np.array(faces))


def cup_levels(n_levels: int = 5, radius: float = 1.0) -> list[TriMesh]:
    """The open cup, its rim capped: 8 segments x 4 rings, doubled each level."""
    from ..io.repair import clean_closed_surface

    return [
        clean_closed_surface(*_arrays(cup(8 * 2**k, 4 * 2**k, radius)))[0] for k in range(n_levels)
    ]


def _arrays(mesh: TriMesh) -> tuple[np.ndarray, np.ndarray]:
    return np.array(mesh.vertices), np.array(mesh.faces)


def _outward(mesh: TriMesh) -> TriMesh:
    if signed_volume(mesh.vertices, mesh.faces) < 0:
        return TriMesh(mesh.vertices, mesh.faces[:, ::-1])
    return mesh


#: Most levels a built-in shape may have (the torus's 9th has about a million triangles).
MAX_LEVELS = 9
#: radii of the built-in shapes (in model units)
SIZE_RANGE = (1e-6, 1e6)

#: name -> (level builder, description)
BUILTINS: dict[str, tuple[Callable[..., list[TriMesh]], str]] = {
    "torus": (torus_levels, "torus, major radius 1, minor radius 0.4, axis z"),
    "sphere": (sphere_levels, "unit sphere (icosphere levels)"),
    "club": (club_levels, "the paper's rounded club: a sphere deformed by an FFD"),
    "cup": (cup_levels, "an open cup (one sheet, open at its rim): its capacity is kept"),
}


@lru_cache(maxsize=4)
def _levels(name: str, params: tuple) -> tuple[TriMesh, ...]:
    """The levels, made once per process and parameters (meshes are immutable): an
    example's lattice and its session both ask for them."""
    return tuple(BUILTINS[name][0](**dict(params)))


def builtin_levels(name: str, **params) -> list[TriMesh]:
    """The level pyramid of a built-in shape by name, coarse to fine."""
    if name not in BUILTINS:
        raise IsochorError(
            f"Unknown built-in shape {name!r}; the built-in shapes are {', '.join(BUILTINS)}."
        )
    for key, value in params.items():
        bounds = (1, MAX_LEVELS) if key == "n_levels" else SIZE_RANGE
        params[key] = number(value, f"model.{key}", bounds)
    n_levels = params.get("n_levels", 1)
    if n_levels != int(n_levels):
        raise IsochorError(f"model.n_levels: must be a whole number from 1 to {MAX_LEVELS}")
    if "n_levels" in params:
        params["n_levels"] = int(n_levels)
    if name == "torus" and params.get("minor", 0.4) >= params.get("major", 1.0):
        raise IsochorError(
            "model.minor: must be smaller than model.major (the torus would cut itself)"
        )
    try:
        return list(_levels(name, tuple(sorted(params.items()))))
    except TypeError as exc:
        raise IsochorError(f"Bad parameters for the built-in shape {name!r}: {exc}") from None
