"""A minimal immutable triangle mesh container shared by every core module."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class TriMesh:
    """A triangle mesh.

    Attributes
    ----------
    vertices : (m, 3) float64
    faces : (f, 3) int64, counter-clockwise seen from outside for a positive volume.
    """

    vertices: np.ndarray
    faces: np.ndarray

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
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def extents(self) -> np.ndarray:
        """(3,) size of the axis-aligned bounding box."""
        return np.ptp(self.vertices, axis=0)

    @property
    def size(self) -> float:
        """The object size: the largest extent of the bounding box."""
        return float(self.extents.max())
