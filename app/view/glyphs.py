"""The lattice nodes as glyphs: a shape per role and a size that follows the lattice density.
GUI thread only (VTK).

- free and held nodes: spheres (sky blue, bluish green);
- pinned nodes: cubes (vermillion);
- nodes pinned on some axes: diamonds (reddish purple);
- moved nodes: spheres with a ring around them (orange);
- the selection: a yellow ring around each selected node, whatever its shape.

Glyph sizes are world sizes, a fraction of the node spacing (:func:`glyph_size`), so an 8x8x8
lattice draws small nodes that leave the model visible. One ``vtkGlyph3DMapper`` draws all
nodes; a frame only moves its input points (``poly.points[:] = ...``).
"""

from __future__ import annotations

import functools

import numpy as np
import pyvista as pv
from vtkmodules.vtkRenderingCore import vtkActor, vtkGlyph3DMapper

from . import style

#: glyph index per role shape (the ``shape`` point array of the nodes)
SPHERE, CUBE, DIAMOND, RINGED = 0, 1, 2, 3
#: a node's diameter as a fraction of the widest node spacing ...
SPACING_FRACTION = 0.13
#: ... but at most this fraction of the lattice's size (a 2x2x2 lattice has wide spacing)
SIZE_FRACTION = 0.04
#: the selection ring's outer and inner diameters over a node's
HALO, GAP = 1.9, 1.45


def glyph_size(lattice) -> float:
    """World diameter of a node glyph: a fraction of the node spacing, so denser lattices
    draw smaller nodes."""
    lengths = np.linalg.norm(np.asarray(lattice.axes), axis=1)
    # the widest spacing: a flat lattice (a torus) has one short axis that says little
    # about how crowded the view is
    spacing = max(length / (n - 1) for length, n in zip(lengths, lattice.shape))
    return float(min(SPACING_FRACTION * spacing, SIZE_FRACTION * lattice.size))


@functools.cache
def _sources() -> tuple[pv.PolyData, ...]:
    """Unit-diameter glyph shapes, indexed by :data:`SPHERE` ... :data:`RINGED`; made once
    (the mappers only read them): a rebuild of the scene does not make them again."""
    # few triangles: a node is ~10 pixels wide, and a software renderer draws every one
    sphere = pv.Sphere(radius=0.5, theta_resolution=9, phi_resolution=6)
    cube = pv.Cube(x_length=0.82, y_length=0.82, z_length=0.82).triangulate()
    diamond = pv.PolyData(
        np.array(
            [[0.62, 0, 0], [-0.62, 0, 0], [0, 0.62, 0], [0, -0.62, 0], [0, 0, 0.62], [0, 0, -0.62]]
        ),
        np.array(
            [3, 0, 2, 4, 3, 2, 1, 4, 3, 1, 3, 4, 3, 3, 0, 4]
            + [3, 2, 0, 5, 3, 1, 2, 5, 3, 3, 1, 5, 3, 0, 3, 5]
        ),
    )
    core = pv.Sphere(radius=0.36, theta_resolution=10, phi_resolution=7)
    ring = pv.ParametricTorus(ringradius=0.58, crosssectionradius=0.09, u_res=18, v_res=5)
    ringed = core.append_polydata(ring.triangulate())
    out = []
    for s in (sphere, cube, diamond, ringed):
        s.point_data.clear()
        # sharp edges stay sharp (a cube is not a blob)
        out.append(
            s.compute_normals(split_vertices=True, feature_angle=40, auto_orient_normals=True)
        )
    return tuple(out)


def glyph_actor(poly: pv.PolyData, sources, size: float) -> vtkActor:
    """An actor drawing ``sources[0]`` (or the source a ``shape`` index picks) of world
    diameter ``size`` at every point of ``poly``."""
    mapper = vtkGlyph3DMapper()
    mapper.SetInputData(poly)
    for i, s in enumerate(sources):
        mapper.SetSourceData(i, s)
    mapper.SetScaling(True)
    mapper.SetScaleModeToNoDataScaling()
    mapper.SetScaleFactor(size)
    mapper.OrientOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.PickableOff()
    return actor


def node_actor(poly: pv.PolyData, size: float) -> vtkActor:
    """The nodes: ``poly`` has the point arrays ``rgb`` (uint8 colours) and ``shape``."""
    actor = glyph_actor(poly, _sources(), size)
    mapper = actor.GetMapper()
    assert isinstance(mapper, vtkGlyph3DMapper)  # glyph_actor's
    mapper.SetSourceIndexArray("shape")
    mapper.SetSourceIndexing(True)
    mapper.SetScalarModeToUsePointFieldData()
    mapper.SelectColorArray("rgb")
    mapper.SetColorModeToDirectScalars()
    mapper.ScalarVisibilityOn()
    prop = actor.GetProperty()
    prop.SetAmbient(0.25)
    prop.SetDiffuse(0.8)
    prop.SetSpecular(0.3)
    prop.SetSpecularPower(25)
    return actor


def halo_actor(poly: pv.PolyData, size: float, ring: bool = True) -> vtkActor:
    """The selection: a yellow ring around each point of ``poly``, drawn as the back of a
    larger sphere behind the node; ``ring=False``: the dark gap inside the ring (a smaller
    back), so the node's own shape and colour stand out on it."""
    sphere = pv.Sphere(radius=0.5, theta_resolution=20, phi_resolution=14)
    actor = glyph_actor(poly, [sphere], (HALO if ring else GAP) * size)
    actor.GetMapper().ScalarVisibilityOff()
    prop = actor.GetProperty()
    color = style.SELECTED if ring else style.BACKGROUND_BOTTOM
    prop.SetColor(*(c / 255 for c in style.hex_to_rgb(color)))
    prop.FrontfaceCullingOn()
    prop.LightingOff()
    return actor


def role_shapes(pin_axes: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """(n,) uint8: each node's glyph by role (a moved node's ring wins over its pins)."""
    moved = np.asarray(moved, bool)
    pins = np.asarray(pin_axes, bool).reshape(len(moved), -1)
    shape = np.full(len(moved), SPHERE, dtype=np.uint8)
    shape[pins.any(axis=1)] = DIAMOND
    shape[pins.all(axis=1)] = CUBE
    shape[moved] = RINGED
    return shape
