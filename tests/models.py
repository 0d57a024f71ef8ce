"""The shared test models (``../shared/models`` next to the repository) and small synthetic
meshes, for the mesh-file, pyramid, scenario and command-line tests.

Tests that need a shared model call :func:`model`, which skips the test cleanly when the
folder (or the file) is not there.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isochor.core.mesh import TriMesh
from isochor.core.scenario.shapes import club_levels, sphere_levels

MODELS = Path(__file__).resolve().parents[2] / "shared" / "models"

#: closed, consistently wound models that load and solve: name -> (triangles, bodies)
CLOSED = {
    "cow.obj": (5804, 1),
    "spot_triangulated.obj": (5856, 1),
    "bunny_watertight.obj": (59664, 1),
    "kitten.obj": (5000, 1),
    "fertility.obj": (9000, 1),
    "torus_knot_quads.obj": (2880, 1),
}

#: open surfaces that open with their holes capped or their objects kept apart:
#: name -> (boundary edges, non-manifold edges) when welded as one (SOURCES.md)
OPEN = {
    "teapot.obj": (160, 0),
    "stanford_bunny.obj": (223, 0),
    "stanford_bunny_flipped_vtk.ply": (223, 0),
    "two_objects.obj": (0, 3),
}

#: surfaces with no solid to keep, refused: name -> what the message says
REFUSED = {"soup.stl": "no solid to keep"}


def model(name: str) -> Path:
    """Path of a shared model; skips the calling test when it is not available."""
    path = MODELS / name
    if not path.is_file():
        pytest.skip(f"../shared/models not found: {path}")
    return path


def available(name: str) -> Path | None:
    """Path of a shared model, or None when it is not there (for optional use)."""
    path = MODELS / name
    return path if path.is_file() else None


def trimesh_volume(path: Path) -> float:
    """The volume trimesh measures for a file, independently of isochor.core.io.meshio."""
    import trimesh

    mesh = trimesh.load_mesh(str(path), process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return float(mesh.volume)


def icosphere(level: int = 4, radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> TriMesh:
    """Outward icosphere with 20 * 4**level triangles."""
    m = sphere_levels(level + 1, radius)[-1]
    return TriMesh(m.vertices + np.asarray(center, dtype=float), m.faces)


def club(level: int = 5) -> TriMesh:
    """The paper's rounded club as a plain mesh (20 * 4**level triangles)."""
    return club_levels(level + 1)[-1]


def uv_sphere(n_lat: int = 32, n_lon: int = 64, radius: float = 1.0) -> TriMesh:
    """Latitude-longitude sphere with poles: the kind of input fast-simplification has been
    seen to fold (a 384-triangle level at 27% of the volume)."""
    theta = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    verts = np.concatenate([[[0, 0, 1]], ring.reshape(-1, 3), [[0, 0, -1]]]) * radius
    idx = lambda i, j: 1 + i * n_lon + (j % n_lon)  # noqa: E731
    south = len(verts) - 1
    faces = [(0, idx(0, j), idx(0, j + 1)) for j in range(n_lon)]
    for i in range(n_lat - 2):
        for j in range(n_lon):
            faces += [
                (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)),
                (idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)),
            ]
    faces += [(south, idx(n_lat - 2, j + 1), idx(n_lat - 2, j)) for j in range(n_lon)]
    return TriMesh(verts, np.array(faces))


def joined(*meshes: TriMesh) -> TriMesh:
    """One mesh holding all the given meshes as separate bodies."""
    offsets = np.cumsum([0] + [m.n_vertices for m in meshes[:-1]])
    return TriMesh(
        np.concatenate([m.vertices for m in meshes]),
        np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
    )


#: the unit cube, outward wound: 8 corners and 12 triangles
CUBE_VERTICES = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
CUBE_FACES = np.array(
    [
        [0, 2, 1],
        [0, 3, 2],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [1, 2, 6],
        [1, 6, 5],
        [2, 3, 7],
        [2, 7, 6],
        [3, 0, 4],
        [3, 4, 7],
    ]
)


def box(extents=(1.0, 1.0, 1.0)) -> TriMesh:
    """An axis-aligned box with a corner at the origin, outward wound (12 triangles)."""
    return TriMesh(CUBE_VERTICES * np.asarray(extents, dtype=float), CUBE_FACES)
