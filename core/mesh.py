"""A minimal immutable triangle mesh container shared by every core module."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True, eq=False)
class TriMesh:
    """A triangle mesh.

    Attributes
    ----------
    vertices : (m, 3) float64
    faces : (f, 3) int64, counter-clockwise seen from outside for a positive volume.
    cap_vertices, cap_faces : how many of the last vertices and faces are virtual caps
        over the holes of an open model (:mod:`isochor.core.io.caps`): part of the solid
        the solver keeps the volume of, never of the model written to a file
    """

    vertices: np.ndarray
    faces: np.ndarray
    cap_vertices: int = 0
    cap_faces: int = 0

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices must be (m, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"faces must be (f, 3), got {f.shape}")
        v.flags.writeable = False
        f.flags.writeable = False
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)

    @property
    def own_vertices(self) -> int:
        """How many vertices are the model's own (the first ones; caps come after)."""
        return self.n_vertices - self.cap_vertices

    @property
    def own_faces(self) -> int:
        """How many faces are the model's own (the first ones; caps come after)."""
        return self.n_faces - self.cap_faces

    @property
    def own(self) -> TriMesh:
        """The model's own surface, without the caps (itself when it has none)."""
        if not self.cap_faces and not self.cap_vertices:
            return self
        return TriMesh(self.vertices[: self.own_vertices], self.faces[: self.own_faces])

    def moved(self, vertices: np.ndarray) -> TriMesh:
        """The same mesh (faces and caps) with its vertices at ``vertices``."""
        return TriMesh(vertices, self.faces, self.cap_vertices, self.cap_faces)

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(3,) lowest and (3,) highest corner of the axis-aligned bounding box."""
        vt = np.ascontiguousarray(self.vertices.T)  # ~8x faster than axis=0 on (m, 3) rows
        return vt.min(axis=1), vt.max(axis=1)

    @property
    def extents(self) -> np.ndarray:
        """(3,) size of the axis-aligned bounding box."""
        lo, hi = self.bounds
        return hi - lo

    @property
    def center(self) -> np.ndarray:
        """(3,) centre of the axis-aligned bounding box."""
        lo, hi = self.bounds
        return (lo + hi) / 2

    @property
    def size(self) -> float:
        """The object size: the largest extent of the bounding box."""
        return float(self.extents.max())
