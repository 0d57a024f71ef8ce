"""The mesh types a caller of the Python API may hand in, and how to give back the same
type with other vertex positions: ``(vertices, faces)`` arrays, a ``trimesh.Trimesh`` (or
alike) and a ``pyvista.PolyData``, handled through their own methods so that no VTK is
imported here."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .errors import IsochorError
from .io.formats import WRITE_FORMATS, listing
from .io.meshio import mesh_bytes
from .mesh import TriMesh


class CallerMesh:
    """A caller's mesh: its vertices and triangles for the solver, and how to give back
    the same type with other vertex positions."""

    def __init__(self, mesh: Any) -> None:
        self.original = mesh
        if hasattr(mesh, "vertices") and hasattr(mesh, "faces") and hasattr(mesh, "copy"):
            self.kind = "trimesh"  # trimesh.Trimesh (and alike): triangles already
            self.vertices = np.asarray(mesh.vertices, dtype=np.float64)
            self.faces = np.asarray(mesh.faces, dtype=np.int64)
        elif hasattr(mesh, "points") and hasattr(mesh, "triangulate"):
            self.kind = "pyvista"  # pyvista.PolyData: flat [n, i, j, k, ...] cells
            tri = mesh.triangulate()
            self.vertices = np.asarray(mesh.points, dtype=np.float64)
            self.faces = np.asarray(tri.faces, dtype=np.int64).reshape(-1, 4)[:, 1:]
        elif isinstance(mesh, Sequence) and len(mesh) == 2:
            self.kind = "arrays"
            try:
                self.vertices = np.asarray(mesh[0], dtype=np.float64)
                given = np.asarray(mesh[1])
                self.faces = given.astype(np.int64)
            except (TypeError, ValueError) as exc:
                raise IsochorError(
                    f"a mesh's vertices and faces must be arrays of numbers ({exc})"
                ) from None
            if given.size and not np.array_equal(self.faces, given):
                raise IsochorError("the faces must be whole vertex indices (an integer array)")
        else:
            raise IsochorError(
                "a mesh is (vertices, faces) arrays, a trimesh.Trimesh or a pyvista.PolyData"
                f"; got {type(mesh).__name__}"
            )
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise IsochorError(f"the vertices must be an (n, 3) array, got {self.vertices.shape}")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or len(self.faces) == 0:
            raise IsochorError(f"the faces must be an (f, 3) array, got {self.faces.shape}")
        if self.faces.min() < 0 or self.faces.max() >= len(self.vertices):
            raise IsochorError("a face refers to a vertex that does not exist")
        if not np.all(np.isfinite(self.vertices)):
            raise IsochorError("a vertex has a coordinate that is not a number")

    def like(self, vertices: np.ndarray) -> Any:
        """The caller's mesh type, with these vertex positions."""
        if self.kind == "arrays":
            return vertices, self.faces.copy()
        out = self.original.copy()
        if self.kind == "trimesh":
            out.vertices = vertices
        else:
            out.points = vertices
        return out

    def file_bytes(self, vertices: np.ndarray, path: Path) -> bytes:
        """The deformed mesh as the file ``path`` names: a trimesh writes itself (its UVs
        with it, where the format has room); other meshes as their triangles."""
        suffix = path.suffix.lower()
        if suffix not in WRITE_FORMATS:
            raise IsochorError(f"{path}: the file name must end in {listing(WRITE_FORMATS)}")
        if self.kind == "trimesh":
            return _as_bytes(self.like(vertices).export(file_type=suffix[1:]), path.name)
        return mesh_bytes(TriMesh(vertices, self.faces), suffix)


def _as_bytes(data: Any, name: str) -> bytes:
    if isinstance(data, dict):  # trimesh's .gltf: {file name: bytes}
        data = next(v for k, v in data.items() if k.endswith(".gltf"))
    return data if isinstance(data, bytes) else str(data).encode("utf-8")
