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


@dataclass(frozen=True)
class User:
    """A mesh object the lattice deforms, and its Lattice modifier."""

    mesh: bpy.types.Object
    modifier: bpy.types.Modifier

    def after(self) -> list:
        """The modifiers after the Lattice modifier."""
        mods = list(self.mesh.modifiers)
        return mods[mods.index(self.modifier) + 1 :]


@dataclass
class Target:
    """The lattice object and the meshes its Lattice modifiers deform (``users``, each
    counted: summed, or each body its own, as the panel says)."""

    lattice: bpy.types.Object
    users: tuple[User, ...]

    @property
    def mesh(self) -> bpy.types.Object:
        """The first mesh (the one a single-mesh rig has)."""
        return self.users[0].mesh

    @classmethod
    def of(cls, obj) -> Target:
        """The rig of the active object (a mesh with a Lattice modifier, or a lattice that
        a mesh's Lattice modifier uses), with every mesh the same lattice deforms;
        :class:`RigError` when not supported."""
        if obj is None:
            raise RigError("Isochor: select a mesh with a Lattice modifier, or its lattice")
        if obj.type == "LATTICE":
            lattice = obj
        elif obj.type == "MESH":
            mods = [m for m in obj.modifiers if m.type == "LATTICE"]
            if not mods:
                raise RigError(f"Isochor: {obj.name!r} has no Lattice modifier")
            if mods[0].object is None:
                raise RigError(
                    f"Isochor: the Lattice modifier of {obj.name!r} has no lattice object"
                )
            lattice = mods[0].object
        else:
            raise RigError(
                f"Isochor: {obj.name!r} is not a mesh; select a mesh with a Lattice modifier"
            )
        users = []
        for ob in bpy.context.view_layer.objects:
            if ob.type != "MESH":
                continue
            mods = [m for m in ob.modifiers if m.type == "LATTICE"]
            on = [m for m in mods if m.object is lattice and m.show_viewport]
            if not on:
                continue
            if len(mods) > 1:
                raise RigError(f"Isochor: {ob.name!r} has {len(mods)} Lattice modifiers; keep one")
            users.append(User(ob, on[0]))
        if not users:
            raise RigError(
                f"Isochor: no mesh's Lattice modifier (shown in the viewport) uses lattice "
                f"{lattice.name!r}"
            )
        users.sort(key=lambda u: u.mesh != obj)  # the active mesh first
        target = cls(lattice, tuple(users))
        target.check()
        return target

    def check(self) -> None:
        lat, data = self.lattice, self.lattice.data
        for user in self.users:
            mod = user.modifier
            if abs(mod.strength - 1.0) > 0:
                raise RigError(
                    f"Isochor: the Lattice modifier of {user.mesh.name!r} has strength "
                    f"{mod.strength:g}; set it to 1"
                )
            if mod.vertex_group:
                raise RigError(
                    f"Isochor: the Lattice modifier of {user.mesh.name!r} uses a vertex "
                    "group; clear it"
                )
            _invertible(user.mesh, "mesh")
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
        _invertible(lat, "lattice")

    @property
    def shape(self) -> tuple[int, int, int]:
        data = self.lattice.data
        return (data.points_u, data.points_v, data.points_w)

    def to_lattice(self, mesh=None) -> np.ndarray:
        """4x4: the mesh's object space (the first mesh's by default) -> the lattice's."""
        mesh = self.mesh if mesh is None else mesh
        return np.linalg.inv(np.array(self.lattice.matrix_world)) @ np.array(mesh.matrix_world)

    def points(self) -> np.ndarray:
        """(n, 3) the lattice points' co_deform, Blender's order (in the lattice's Edit
        Mode the edited ones: Blender's points are then the edit lattice's)."""
        pts = self.lattice.data.points
        out = np.empty(len(pts) * 3)
        pts.foreach_get("co_deform", out)
        return out.reshape(-1, 3)

    def rest(self) -> np.ndarray:
        """(n, 3) the rest grid (the points' ``co``), Blender's order. In the lattice's
        Edit Mode Blender reads a point's ``co`` against the object's lattice, not the
        edit lattice its points then come from (values that are no grid), so there it is
        read from a copy of the lattice data, which holds no edit lattice."""
        data = self.lattice.data
        copy = data.copy() if data.is_editmode else None
        try:
            pts = (copy or data).points
            out = np.empty(len(pts) * 3)
            pts.foreach_get("co", out)
        finally:
            if copy is not None:
                bpy.data.lattices.remove(copy)
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

    def inputs(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each mesh as it enters its Lattice modifier, as Blender evaluates it (shape
        keys, the modifiers before it: an Armature, ...): (vertices in the lattice's
        space, triangles). Blender evaluates each with the Lattice modifier and those
        after it switched off for the moment."""
        out = []
        for user, (vertices, faces) in zip(self.users, self._evaluate(upto=True), strict=True):
            if not len(faces):
                raise RigError(f"Isochor: mesh {user.mesh.name!r} has no faces")
            out.append((_moved(vertices, self.to_lattice(user.mesh)), faces))
        return out

    def outputs(self) -> list[np.ndarray]:
        """Each mesh's vertices as its Lattice modifier leaves them (Blender's evaluated
        mesh with the modifiers after it switched off), in the lattice's space."""
        return [
            _moved(vertices, self.to_lattice(user.mesh))
            for user, (vertices, _) in zip(self.users, self._evaluate(upto=False), strict=True)
        ]

    def _evaluate(self, upto: bool) -> list[tuple[np.ndarray, np.ndarray]]:
        """Blender's evaluated mesh of each user, the modifiers after the Lattice modifier
        (and, ``upto``, the Lattice modifier too) off while it is read."""
        switched = [
            m
            for user in self.users
            for m in ([user.modifier] if upto else []) + user.after()
            if m.show_viewport
        ]
        for m in switched:
            m.show_viewport = False
        try:
            depsgraph = bpy.context.evaluated_depsgraph_get()
            depsgraph.update()
            return [_mesh_arrays(user.mesh.evaluated_get(depsgraph)) for user in self.users]
        finally:
            for m in switched:
                m.show_viewport = True
            if switched:
                bpy.context.evaluated_depsgraph_get().update()

    def rig(self, source: str = "SELECTED", group: str = "", extra_pins=None) -> Rig:
        """The :class:`Rig` of the meshes as they enter the modifier and the lattice now."""
        data = self.lattice.data
        basis = tuple(_basis(getattr(data, f"interpolation_type_{a}"), a) for a in "uvw")
        meshes = self.inputs()
        offsets = np.cumsum([0] + [len(v) for v, _ in meshes])
        rest = self.rest()
        if np.ptp(rest, axis=0).min() <= 0:
            raise RigError(f"Isochor: lattice {self.lattice.name!r} has no rest grid to solve")
        pins = self.pinned(source, group)
        if extra_pins is not None:
            pins = pins | extra_pins
        shape = self.shape
        return Rig(
            vertices=np.concatenate([v for v, _ in meshes]),
            faces=np.concatenate([f + o for (_, f), o in zip(meshes, offsets, strict=False)]),
            shape=shape,
            basis=basis,
            origin=rest[0].copy(),
            axes=np.diag(rest[-1] - rest[0]),
            nodes=isochor_order(self.points(), shape),
            pinned=isochor_order(pins, shape),
            outside=bool(data.use_outside),
            counts=tuple(int(len(v)) for v, _ in meshes),
        )

    def write(self, nodes: np.ndarray, free: np.ndarray | None = None) -> None:
        """Isochor-ordered ``nodes`` into the points' co_deform (only the ``free`` ones, a
        Blender-ordered mask, when given). In the lattice's Edit Mode they go to the edit
        lattice: shown at once, kept when Edit Mode ends."""
        shape = self.shape
        new = blender_order(np.asarray(nodes, float), shape)
        if free is not None:
            new = np.where(np.asarray(free)[:, None], new, self.points())
        self.lattice.data.points.foreach_set("co_deform", new.ravel())
        self.lattice.data.update_tag()
        for user in self.users:
            user.mesh.update_tag()

    def volumes(self, rig: Rig | None = None) -> Volumes:
        """The volume a solve keeps, at rest (as the meshes enter the modifier) and now
        (as it leaves them), in world units: the closed solid of the meshes (an open one
        capped as Isochor caps it, :meth:`.rig.Rig.solid`). The meshes' vertices are
        Blender's evaluated ones; the cap points are moved by Isochor's FFD (Blender's
        map within 1e-6 of the size)."""
        rig = self.rig() if rig is None else rig
        solid = rig.solid()
        caps_now = rig.lattice().deform(solid.caps, rig.nodes)
        now = self.outputs()
        if [len(v) for v in now] != list(rig.counts):
            raise RigError(
                "Isochor: the Lattice modifier's output has other vertices than its input"
            )
        scale = abs(float(np.linalg.det(np.array(self.lattice.matrix_world)[:3, :3])))
        return Volumes(
            rest=scale * solid.volume(rig.vertices, solid.caps),
            now=scale * solid.volume(np.concatenate(now), caps_now),
            holes=solid.holes,
        )


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


def _mesh_arrays(ob) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (v, 3) in object space, triangles (f, 3)) of an evaluated object."""
    mesh = ob.to_mesh()
    try:
        mesh.calc_loop_triangles()
        faces = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", faces)
        return _coordinates(mesh.vertices), faces.reshape(-1, 3).astype(np.int64)
    finally:
        ob.to_mesh_clear()


def _invertible(obj, what: str) -> None:
    """A :class:`RigError` for an object whose transform is flat (a scale of zero along
    an axis): it maps the space onto a plane, so no volume can be kept in it."""
    m = np.array(obj.matrix_world)[:3, :3]
    size = np.linalg.norm(m, axis=0).max()
    if not size or abs(np.linalg.det(m)) <= 1e-12 * size**3:
        raise RigError(
            f"Isochor: {what} {obj.name!r} is flat (its scale or transform has no thickness "
            "along an axis); give it depth"
        )


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
