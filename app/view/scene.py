"""The actors of the 3D view: the deformed model, its ghost, the lattice, the selection, the
axis guide. GUI thread only.

:class:`Scene` adds its actors to a pyvista plotter once per model or lattice
(:meth:`Scene.build`) and afterwards only updates their points in place
(``poly.points[:] = ...``): a frame never adds or removes an actor.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv

from . import style
from .glyphs import glyph_size, halo_actor, node_actor, role_shapes
from .meshprep import DisplayPrep
from .modelview import ModelView
from .modelview import cells as _cells
from .modelview import rgb as _rgb


class Scene:
    """The actors of one model in one lattice, on one plotter."""

    def __init__(self, plotter) -> None:
        self.plotter = plotter
        self.actors: dict[str, object] = {}
        self.nodes = np.zeros((0, 3))
        self.selection = np.zeros(0, dtype=int)
        self.size = 1.0  #: the model's size (the largest extent of its bounding box)
        self.model = ModelView(plotter)  #: the model: the full mesh, or its proxy
        self.show_lattice = True
        self.show_diagonals = True
        self._offered: DisplayPrep | None = None  # computed off the GUI thread for a build

    @property
    def built(self) -> bool:
        return "model" in self.actors

    @property
    def smooth(self) -> bool:
        return self.model.smooth

    @property
    def volume(self) -> float:
        """Signed volume of the model at the nodes drawn: the full mesh's (measured), or
        while the proxy is drawn its estimate (:attr:`volume_estimated`)."""
        return self.model.volume

    @property
    def volume_estimated(self) -> bool:
        return self.model.estimated

    @property
    def folded(self) -> int:
        return self.model.folded

    def model_points(self) -> np.ndarray:
        """(m, 3) the full mesh's vertices at the nodes drawn (deformed), also while the
        proxy is on screen: what picking uses."""
        return self.model.points()

    def model_faces(self) -> np.ndarray:
        """(f, 3) the model's triangles (the full mesh's)."""
        return self.model.faces()

    def bounds(self) -> np.ndarray:
        """(2, 3) lowest and highest corner of the model at the nodes drawn."""
        return self.model.bounds()

    def offer(self, prep: DisplayPrep | None) -> None:
        """What the next :meth:`build` may draw the model from, when it was computed for
        its surface and nodes (:class:`~isochor.app.view.meshprep.DisplayPrep`, made off the
        GUI thread); otherwise the build computes it itself."""
        self._offered = prep

    def build(self, surface, nodes: np.ndarray, pin_axes, moved, held=None) -> None:
        """Replace every actor for a new model or lattice (not called per frame)."""
        p = self.plotter
        if self.model.proxy is not None:  # (the model may have drawn a coarser one since)
            self.actors["proxy"] = self.model.proxy.actor
        for actor in self.actors.values():
            p.remove_actor(actor, render=False)
        self.actors.clear()
        self.size = float(surface.size)
        self.nodes = np.array(nodes, dtype=np.float64)
        self.selection = np.zeros(0, dtype=int)

        prep, self._offered = self._offered, None
        if prep is None or not prep.fits(surface, self.nodes):
            prep = DisplayPrep.of(surface, self.nodes)
        rest = self.model.ghost_mesh(surface)
        ghost = pv.PolyData(np.array(rest.vertices), prep.ghost_cells)
        self.actors["ghost"] = p.add_mesh(
            ghost,
            color=style.GHOST,
            opacity=0.28,
            show_scalar_bar=False,
            render=False,
            pickable=False,
            name="ghost",
        )
        self.actors["ghost"].SetVisibility(False)

        self.model.build(surface, self.nodes, self.model.smooth, prep)
        self.actors["model"] = self.model.full.actor
        if self.model.proxy is not None:
            self.actors["proxy"] = self.model.proxy.actor

        edges = np.asarray(surface.springs.edges)
        lattice = surface.lattice
        ijk = np.stack(np.unravel_index(np.arange(lattice.n_nodes), lattice.shape), axis=1)
        axis_edge = np.abs(ijk[edges[:, 0]] - ijk[edges[:, 1]]).sum(axis=1) == 1
        self._springs_axis = pv.PolyData(self.nodes.copy(), lines=_cells(edges[axis_edge]))
        self._springs_diag = pv.PolyData(self.nodes.copy(), lines=_cells(edges[~axis_edge]))
        self.actors["diag"] = p.add_mesh(
            self._springs_diag,
            color=style.SPRING_DIAGONAL,
            line_width=1.0,
            lighting=False,
            render=False,
            pickable=False,
            name="diag",
        )
        self.actors["axis"] = p.add_mesh(
            self._springs_axis,
            color=style.SPRING_AXIS,
            line_width=2.0,
            lighting=False,
            render=False,
            pickable=False,
            name="axis",
        )

        self.node_size = glyph_size(lattice)
        self._nodes_poly = pv.PolyData(self.nodes.copy())
        self._nodes_poly.point_data["rgb"] = np.zeros((len(self.nodes), 3), dtype=np.uint8)
        self._nodes_poly.point_data["shape"] = np.zeros(len(self.nodes), dtype=np.uint8)
        self.actors["nodes"] = node_actor(self._nodes_poly, self.node_size)
        p.add_actor(self.actors["nodes"], render=False, pickable=False, name="nodes")
        self._sel_poly = pv.PolyData(np.zeros((1, 3)))
        self.actors["selected"] = halo_actor(self._sel_poly, self.node_size)
        p.add_actor(self.actors["selected"], render=False, pickable=False, name="selected")
        self.actors["selected_gap"] = halo_actor(self._sel_poly, self.node_size, ring=False)
        p.add_actor(self.actors["selected_gap"], render=False, pickable=False, name="sel-gap")
        for name in ("selected", "selected_gap"):
            self.actors[name].SetVisibility(False)
        self._mirror = pv.Plane(i_resolution=1, j_resolution=1)
        self.actors["mirror"] = p.add_mesh(
            self._mirror,
            color=style.GUIDE,
            opacity=0.13,
            lighting=False,
            render=False,
            pickable=False,
            name="mirror",
        )
        self.actors["mirror"].SetVisibility(False)
        # two segments: an axis lock draws one (twice), a plane lock the plane's two axes
        self._guide = pv.PolyData(np.zeros((4, 3)), lines=np.array([2, 0, 1, 2, 2, 3]))
        self.actors["guide"] = p.add_mesh(
            self._guide,
            color=style.GUIDE,
            line_width=2.5,
            lighting=False,
            render=False,
            pickable=False,
            name="guide",
        )
        self.actors["guide"].SetVisibility(False)

        self.set_roles(pin_axes, moved, held)
        self._apply_visibility()

    def set_frame(self, nodes: np.ndarray, moving: bool = False) -> None:
        """Move the lattice and the model to new node positions; while ``moving`` a big
        model is drawn as its proxy (:mod:`isochor.app.view.modelview`)."""
        self.nodes = np.array(nodes, dtype=np.float64)
        self._nodes_poly.points[:] = self.nodes
        self._nodes_poly.Modified()
        self._springs_axis.points[:] = self.nodes
        self._springs_diag.points[:] = self.nodes
        self.model.draw(self.nodes, moving)
        self._update_selection()

    def set_roles(self, pin_axes: np.ndarray, moved: np.ndarray, held=None) -> None:
        """Colour the nodes by role: free, held by the far-side anchor, pinned on some
        axes, pinned, moved. ``pin_axes`` is (n, 3) bool (or (n,): all axes)."""
        moved = np.asarray(moved, bool)
        pins = np.asarray(pin_axes, bool).reshape(len(moved), -1)
        rgb = np.empty((len(moved), 3), dtype=np.uint8)
        rgb[:] = _rgb(style.FREE)
        if held is not None:
            rgb[np.asarray(held, bool)] = _rgb(style.HELD)
        rgb[pins.any(axis=1)] = _rgb(style.AXIS_PINNED)
        rgb[pins.all(axis=1)] = _rgb(style.PINNED)
        rgb[moved] = _rgb(style.MOVED)
        self._nodes_poly.point_data["rgb"][:] = rgb
        self._nodes_poly.point_data["shape"][:] = role_shapes(pins, moved)
        self._nodes_poly.Modified()

    def node_colours(self) -> np.ndarray:
        """(n, 3) uint8: each node's colour as drawn."""
        return np.array(self._nodes_poly.point_data["rgb"])

    def set_folds(self, vertices: np.ndarray | None) -> None:
        """Mark the folded vertices of the model (a (m,) bool mask over the full mesh's
        vertices), or clear the marks (None)."""
        self.model.set_folds(vertices)

    def model_colours(self) -> np.ndarray:
        """(m, 3) uint8: each full-mesh vertex's colour as drawn."""
        return self.model.colours()

    def set_selection(self, rows) -> None:
        self.selection = np.asarray(rows, dtype=int)
        self._update_selection()

    def selected_rows(self) -> np.ndarray:
        """The selected rows among the nodes drawn."""
        return self.selection[self.selection < len(self.nodes)]

    def set_ghost(self, on: bool) -> None:
        self.actors["ghost"].SetVisibility(bool(on))

    def set_smooth(self, on: bool) -> None:
        self.model.set_smooth(on)

    def set_caps(self, on: bool) -> None:
        """Show the caps over an open model's holes (the volume kept is inside them)."""
        self.model.show_caps(on)

    def set_lattice_visible(self, on: bool, diagonals: bool | None = None) -> None:
        self.show_lattice = bool(on)
        if diagonals is not None:
            self.show_diagonals = bool(diagonals)
        self._apply_visibility()

    def set_guide(self, ends: np.ndarray | None, color: str = style.GUIDE) -> None:
        """Show the lock's guide: the line between ``ends`` (2, 3) (an axis lock, in its
        colour) or the two lines of ``ends`` (4, 3) (a plane lock's two axes); None hides
        it."""
        actor = self.actors.get("guide")
        if actor is None:
            return
        if ends is not None:
            ends = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
            self._guide.points[:] = ends if len(ends) == 4 else np.vstack([ends, ends])
            self._guide.Modified()
            actor.GetProperty().SetColor(*(c / 255 for c in style.hex_to_rgb(color)))
        actor.SetVisibility(ends is not None)

    def set_mirror(self, mirror) -> None:
        """Draw the symmetry's mirror plane (a :class:`isochor.core.goal.symmetry.Mirror`)
        across the lattice box, faintly in its axis's colour; None hides it."""
        actor = self.actors.get("mirror")
        if actor is None:
            return
        actor.SetVisibility(mirror is not None)
        if mirror is None:
            return
        lat = mirror.lattice
        lo, hi = lat.origin, lat.origin + np.diag(lat.axes)
        a, (b, c) = mirror.axis, [k for k in range(3) if k != mirror.axis]
        corners = np.zeros((4, 3))
        corners[:, a] = mirror.plane
        corners[:, b] = [lo[b], hi[b], hi[b], lo[b]]
        corners[:, c] = [lo[c], lo[c], hi[c], hi[c]]
        self._mirror.copy_from(pv.PolyData(corners, faces=[4, 0, 1, 2, 3]))
        rgb = style.hex_to_rgb(style.AXIS_COLOURS[mirror.name])
        actor.GetProperty().SetColor(*(v / 255 for v in rgb))

    def node_shapes(self) -> np.ndarray:
        """(n,) uint8: each node's glyph as drawn (:mod:`isochor.app.view.glyphs`)."""
        return np.array(self._nodes_poly.point_data["shape"])

    def _apply_visibility(self) -> None:
        self.actors["nodes"].SetVisibility(self.show_lattice)
        self.actors["axis"].SetVisibility(self.show_lattice)
        self.actors["diag"].SetVisibility(self.show_lattice and self.show_diagonals)
        self._update_selection()

    def _update_selection(self) -> None:
        actor, gap = self.actors.get("selected"), self.actors.get("selected_gap")
        if actor is None:
            return
        rows = self.selection[self.selection < len(self.nodes)]
        on = len(rows) > 0 and self.show_lattice
        actor.SetVisibility(on)
        gap.SetVisibility(on)
        if not on:
            return
        pts = self.nodes[rows]
        if self._sel_poly.n_points == len(pts):
            self._sel_poly.points[:] = pts
        else:
            self._sel_poly.copy_from(pv.PolyData(pts))
        self._sel_poly.Modified()
