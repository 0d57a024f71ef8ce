"""Reading and writing Blender's data for the add-on: the active mesh, its Lattice modifier
and lattice checked (one clear line when something is not supported), the
:class:`~.rig.Rig` read from them, solved points written back, volumes measured (an open
mesh capped as Isochor caps it)."""

from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from .rig import BASES, Rig, blender_order, isochor_order

#: the custom property listing the lattice points a bake keyed (not pins on a re-bake)
BAKED = "isochor_baked"


class RigError(Exception):
    """Bad input for the add-on: one line for Blender's report area; nothing was changed."""


@dataclass
class Target:
    """The mesh object, its Lattice modifier and the lattice object."""

    mesh: bpy.types.Object
    modifier: bpy.types.Modifier
    lattice: bpy.types.Object

    @classmethod
    def of(cls, obj) -> Target:
        """The rig of the active object (a mesh with a Lattice modifier, or a lattice used
        by the modifier of a selected mesh); :class:`RigError` when not supported."""
        if obj is None:
            raise RigError("Isochor: select a mesh with a Lattice modifier")
        if obj.type == "LATTICE":
            users = [
                o
                for o in bpy.context.selected_objects
                if o.type == "MESH" and any(_lattice_of(m) is obj for m in o.modifiers)
            ]
            if len(users) != 1:
                raise RigError(
                    f"Isochor: select the one mesh deformed by lattice {obj.name!r} with it"
                )
            obj = users[0]
        if obj.type != "MESH":
            raise RigError(
                f"Isochor: {obj.name!r} is not a mesh; select a mesh with a Lattice modifier"
            )
        mods = [m for m in obj.modifiers if m.type == "LATTICE"]
        if not mods:
            raise RigError(f"Isochor: {obj.name!r} has no Lattice modifier")
        if len(mods) > 1:
            raise RigError(f"Isochor: {obj.name!r} has {len(mods)} Lattice modifiers; keep one")
        mod = mods[0]
        if mod.object is None:
            raise RigError(f"Isochor: the Lattice modifier of {obj.name!r} has no lattice object")
        target = cls(obj, mod, mod.object)
        target.check()
        return target

    def check(self) -> None:
        mod, lat, data = self.modifier, self.lattice, self.lattice.data
        before = list(self.mesh.modifiers).index(mod)
        if any(m.show_viewport for m in list(self.mesh.modifiers)[:before]):
            raise RigError(
                "Isochor: the Lattice modifier must come first (it solves the mesh as it "
                "enters the modifier)"
            )
        if abs(mod.strength - 1.0) > 0:
            raise RigError(
                f"Isochor: the Lattice modifier's strength is {mod.strength:g}; set it to 1"
            )
        if mod.vertex_group:
            raise RigError("Isochor: the Lattice modifier uses a vertex group; clear it")
        if data.shape_keys is not None or any(m.show_viewport for m in lat.modifiers):
            raise RigError(
                f"Isochor: lattice {lat.name!r} has shape keys or modifiers; apply or remove them"
            )
        shape = (data.points_u, data.points_v, data.points_w)
        if min(shape) < 2:
            raise RigError(
                f"Isochor: lattice {lat.name!r} has {'x'.join(map(str, shape))} points; "
                "it needs at least 2 along each axis"
            )

    @property
    def shape(self) -> tuple[int, int, int]:
        data = self.lattice.data
        return (data.points_u, data.points_v, data.points_w)

    def to_lattice(self) -> np.ndarray:
        """4x4: the mesh's object space -> the lattice's."""
        return np.array(self.lattice.matrix_world.inverted() @ self.mesh.matrix_world)

    def points(self) -> np.ndarray:
        """(n, 3) the lattice points' co_deform, Blender's order."""
        pts = self.lattice.data.points
        out = np.empty(len(pts) * 3)
        pts.foreach_get("co_deform", out)
        return out.reshape(-1, 3)

    def rest(self) -> np.ndarray:
        pts = self.lattice.data.points
        out = np.empty(len(pts) * 3)
        pts.foreach_get("co", out)
        return out.reshape(-1, 3)

    def pinned(self, source: str, group: str) -> np.ndarray:
        """(n,) Blender's order: the points selected, or in vertex group ``group``."""
        data = self.lattice.data
        if source == "GROUP":
            vg = self.lattice.vertex_groups.get(group)
            if vg is None:
                raise RigError(
                    f"Isochor: lattice {self.lattice.name!r} has no vertex group {group!r}"
                )
            out = np.zeros(len(data.points), bool)
            for i, point in enumerate(data.points):
                out[i] = any(g.group == vg.index and g.weight > 0 for g in point.groups)
            return out
        out = np.zeros(len(data.points), bool)
        data.points.foreach_get("select", out)
        return out

    def keyed(self) -> np.ndarray:
        """(n,) the points whose co_deform has keyframes (not those a bake keyed)."""
        out = np.zeros(len(self.lattice.data.points), bool)
        for path in _animated_paths(self.lattice.data):
            if path.startswith("points[") and path.endswith("].co_deform"):
                out[int(path[7 : path.index("]")])] = True
        out[list(self.lattice.get(BAKED, []))] = False
        return out

    def rig(self, source: str = "SELECTED", group: str = "", extra_pins=None) -> Rig:
        """The :class:`Rig` of the mesh as it enters the modifier and the lattice now."""
        data, mesh = self.lattice.data, self.mesh.data
        basis = tuple(_basis(getattr(data, f"interpolation_type_{a}"), a) for a in "uvw")
        mesh.calc_loop_triangles()
        if not len(mesh.loop_triangles):
            raise RigError(f"Isochor: mesh {self.mesh.name!r} has no faces")
        faces = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", faces)
        to_lat = self.to_lattice()
        local = _moved(_coordinates(mesh.vertices), to_lat)
        rest = self.rest()
        pins = self.pinned(source, group)
        if extra_pins is not None:
            pins = pins | extra_pins
        shape = self.shape
        return Rig(
            vertices=local,
            faces=faces.reshape(-1, 3).astype(np.int64),
            shape=shape,
            basis=basis,
            origin=rest[0].copy(),
            axes=np.diag(rest[-1] - rest[0]),
            nodes=isochor_order(self.points(), shape),
            pinned=isochor_order(pins, shape),
            outside=bool(data.use_outside),
        )

    def write(self, nodes: np.ndarray, free: np.ndarray | None = None) -> None:
        """Isochor-ordered ``nodes`` into the points' co_deform (only the ``free`` ones, a
        Blender-ordered mask, when given)."""
        shape = self.shape
        new = blender_order(np.asarray(nodes, float), shape)
        if free is not None:
            new = np.where(np.asarray(free)[:, None], new, self.points())
        self.lattice.data.points.foreach_set("co_deform", new.ravel())
        self.lattice.data.update_tag()
        self.mesh.update_tag()

    def volumes(self, depsgraph=None) -> Volumes:
        """The volume a solve keeps, at rest and now, in world units: the closed solid of
        the mesh as the Lattice modifier leaves it, an open mesh capped as Isochor caps it
        (:meth:`.rig.Rig.solid`). The cap points are moved by Isochor's FFD (Blender's map
        within 1e-6 of the size); the mesh's vertices are Blender's evaluated ones (also
        the FFD's when a later modifier is on: its output is not the lattice's)."""
        rig = self.rig()
        solid = rig.solid()
        lattice_world = np.array(self.lattice.matrix_world)
        mesh_world = np.array(self.mesh.matrix_world)
        ffd = rig.lattice()
        caps_now = _moved(ffd.deform(solid.caps, rig.nodes), lattice_world)
        now = self._evaluated(depsgraph)
        if now is None:  # another modifier after the lattice: the lattice's output by the FFD
            now = _moved(ffd.deform(rig.vertices, rig.nodes), lattice_world)
        else:
            now = _moved(now, mesh_world)
        rest = _moved(_coordinates(self.mesh.data.vertices), mesh_world)
        return Volumes(
            rest=solid.volume(rest, _moved(solid.caps, lattice_world)),
            now=solid.volume(now, caps_now),
            holes=solid.holes,
        )

    def _evaluated(self, depsgraph) -> np.ndarray | None:
        """(v, 3) the mesh's vertices as Blender evaluates them, object space; None when a
        modifier after the lattice is on (the output is not the lattice's)."""
        mods = list(self.mesh.modifiers)
        if any(m.show_viewport for m in mods[mods.index(self.modifier) + 1 :]):
            return None
        depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        ob = self.mesh.evaluated_get(depsgraph)
        mesh = ob.to_mesh()
        try:
            out = _coordinates(mesh.vertices)
        finally:
            ob.to_mesh_clear()
        return out if len(out) == len(self.mesh.data.vertices) else None


@dataclass(frozen=True)
class Volumes:
    """What the read-out shows: the volume at rest and now (world units) and how many
    holes were capped to measure them."""

    rest: float
    now: float
    holes: int

    @property
    def ratio(self) -> float:
        return self.now / self.rest if self.rest else 0.0

    def capped(self) -> str:
        """' (3 holes capped)' for the report line, '' for a closed mesh."""
        return f" ({holes_capped(self.holes)})" if self.holes else ""


def holes_capped(holes: int) -> str:
    """'3 holes capped', '1 hole capped'."""
    return f"{holes} hole{'' if holes == 1 else 's'} capped"


def _coordinates(vertices) -> np.ndarray:
    out = np.empty(len(vertices) * 3)
    vertices.foreach_get("co", out)
    return out.reshape(-1, 3)


def _moved(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def _basis(kind: str, axis: str) -> str:
    if kind not in BASES:
        raise RigError(f"Isochor: the lattice's {axis} interpolation {kind!r} is not supported")
    return BASES[kind]


def _lattice_of(modifier):
    return modifier.object if modifier.type == "LATTICE" else None


def _animated_paths(data) -> list[str]:
    """The data paths keyed on ``data``'s action (Blender 4.4+ layered actions too)."""
    anim = data.animation_data
    action = anim.action if anim is not None else None
    if action is None:
        return []
    curves = list(getattr(action, "fcurves", None) or [])
    if not curves and hasattr(action, "layers"):
        slot = getattr(anim, "action_slot", None)
        for layer in action.layers:
            for strip in layer.strips:
                bag = strip.channelbag(slot) if slot is not None else None
                curves += list(bag.fcurves) if bag is not None else []
    return [c.data_path for c in curves]
