"""Isochor inside Blender (issue 26 items 3, 4), headless with the ``bpy`` package:
Blender's own Lattice modifier against Isochor's FFD, the add-on (registers, solves, live,
bakes, undoes, refuses bad input in one line), the extension package, and Blender
importing the sequence GLB. ``make venv`` installs bpy in ``.venv-blender`` (bpy needs
numpy < 2, as Blender ships) and ``make test`` runs this file there; elsewhere it skips."""

from __future__ import annotations

import os
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip(
    "bpy",
    reason="bpy is not installed here: make venv puts it in .venv-blender (make test-blender)",
)
import bmesh  # noqa: E402  (Blender's, after bpy)

from isochor.core.defaults import TOL_VOLUME  # noqa: E402
from isochor.core.lattice import Lattice  # noqa: E402
from tests.blender_scenes import empty_scene, lattice, pin_and_drag, sphere  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: Blender evaluates the modifier in float32: a volume measured from its output is this close
F32_VOLUME = 1e-5
HAS_BASES = "basis" in getattr(Lattice, "__dataclass_fields__", {})
needs_bases = pytest.mark.skipif(
    not HAS_BASES, reason="needs Isochor's local lattice bases (helper 'bases', not merged yet)"
)
KINDS = ["KEY_BSPLINE", "KEY_CATMULL_ROM", "KEY_CARDINAL", "KEY_LINEAR"]


@pytest.fixture(scope="module")
def addon():
    """The add-on registered (the ``blender`` folder imported as Blender does)."""
    import blender

    bpy.ops.wm.read_factory_settings(use_empty=True)
    blender.register()
    yield blender
    blender.unregister()


def rigged(shape, kind, **mesh):
    empty_scene()
    ob = sphere(**mesh)
    lat = lattice(shape, kind)
    mod = ob.modifiers.new("Lattice", "LATTICE")
    mod.object = lat
    bpy.context.view_layer.objects.active = ob
    ob.select_set(True)
    bpy.context.view_layer.update()
    return ob, lat


def evaluated(ob) -> np.ndarray:
    depsgraph = bpy.context.evaluated_depsgraph_get()
    depsgraph.update()
    ev = ob.evaluated_get(depsgraph)
    out = np.empty(len(ev.data.vertices) * 3)
    ev.data.vertices.foreach_get("co", out)
    return out.reshape(-1, 3)


def points(lat) -> np.ndarray:
    out = np.empty(len(lat.data.points) * 3)
    lat.data.points.foreach_get("co_deform", out)
    return out.reshape(-1, 3)


def volume_ratio(addon, ob) -> float:
    from blender.scene import Target

    return Target.of(ob).volumes().ratio


# --- Blender's modifier = Isochor's FFD ---------------------------------------------------


def ffd_case(kind: str, shape, outside: bool = False):
    """Random points inside and outside the box (it spans -1..1), random point moves, a
    rotated, moved lattice object: (Blender's evaluated modifier output, Isochor's FFD of
    the same points, the points' size)."""
    from blender.rig import BASES, isochor_order
    from blender.scene import Target, User

    empty_scene()
    rng = np.random.default_rng(abs(hash((kind, shape, outside))) % 2**32)
    cloud = rng.uniform(-1.4, 1.4, (400, 3))
    mesh = bpy.data.meshes.new("cloud")
    mesh.from_pydata(cloud.tolist(), [], [])
    ob = bpy.data.objects.new("cloud", mesh)
    bpy.context.scene.collection.objects.link(ob)
    lat = lattice(shape, kind)
    lat.rotation_euler = (0.3, -0.2, 0.5)
    lat.location = (0.1, 0.2, -0.1)
    mod = ob.modifiers.new("Lattice", "LATTICE")
    mod.object = lat
    moved = points(lat) + rng.normal(0, 0.15, (len(lat.data.points), 3))
    lat.data.points.foreach_set("co_deform", moved.ravel())
    if outside:  # Blender puts the inner points on the faces' interpolation when set
        lat.data.use_outside = True
        moved = points(lat)
    bpy.context.view_layer.update()
    target = Target(lat, (User(ob, mod),))
    to_lat, rest = target.to_lattice(), target.rest()
    options = {"outside": True} if outside else {}
    ffd = Lattice(shape, rest[0], np.diag(rest[-1] - rest[0]), basis=BASES[kind], **options)
    local = cloud @ to_lat[:3, :3].T + to_lat[:3, 3]
    out = ffd.deform(local, isochor_order(moved, shape))
    back = np.linalg.inv(to_lat)
    return evaluated(ob), out @ back[:3, :3].T + back[:3, 3], np.ptp(cloud, axis=0).max()


@needs_bases
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 4, 2), (5, 3, 6), (8, 2, 4)])
def test_blenders_modifier_is_isochors_ffd(addon, kind, shape):
    """The evaluated modifier output equals Isochor's deformation within 1e-6 of the
    model's size (Blender evaluates in float32)."""
    blender, isochor_says, size = ffd_case(kind, shape)
    assert np.abs(blender - isochor_says).max() <= 1e-6 * size


@needs_bases
@pytest.mark.parametrize(("kind", "shape"), [("KEY_BSPLINE", (4, 3, 5)), ("KEY_LINEAR", (3, 3, 3))])
def test_blenders_outside_option_is_isochors(addon, kind, shape):
    blender, isochor_says, size = ffd_case(kind, shape, outside=True)
    assert np.abs(blender - isochor_says).max() <= 1e-6 * size


def test_point_orders_are_inverse():
    from blender.rig import blender_order, isochor_order

    shape = (4, 3, 2)
    u, v, w = np.meshgrid(range(4), range(3), range(2), indexing="ij")
    isochor_ijk = np.stack([u, v, w], -1).reshape(-1, 3)  # i slowest
    blender_uvw = blender_order(isochor_ijk, shape)
    index = (blender_uvw[:, 2] * 3 + blender_uvw[:, 1]) * 4 + blender_uvw[:, 0]
    np.testing.assert_array_equal(index, np.arange(24))  # Blender's u fastest
    np.testing.assert_array_equal(isochor_order(blender_uvw, shape), isochor_ijk)


# --- the add-on ---------------------------------------------------------------------------


def test_the_addon_registers(addon):
    assert hasattr(bpy.types.Scene, "isochor")
    for op in ("preserve_volume", "live", "bake", "measure"):
        assert hasattr(bpy.ops.isochor, op), op
    assert bpy.types.VIEW3D_PT_isochor.bl_category == "Isochor"
    assert bpy.context.scene.isochor.ratio == 1.0


class Layout:
    """A stand-in for Blender's UI layout (none headless) that checks what a panel asks
    for: properties that exist, operators that are registered."""

    def __init__(self, seen: list):
        self.seen = seen

    def prop(self, data, name, **_):
        assert hasattr(data, name), name
        self.seen.append(name)

    def prop_search(self, data, name, search, collection, **_):
        assert hasattr(data, name) and hasattr(search, collection), (name, collection)
        self.seen.append(name)

    def operator(self, idname, **_):
        group, op = idname.split(".")
        assert hasattr(getattr(bpy.ops, group), op), idname
        self.seen.append(idname)

    def label(self, text="", **_):
        self.seen.append(text)

    def row(self, **_):
        return self

    box = row


def test_the_panel_draws(addon):
    from types import SimpleNamespace

    ob, lat = rigged((3, 3, 3), "KEY_BSPLINE", subdivisions=1)
    props = bpy.context.scene.isochor
    for pins in ("SELECTED", "GROUP"):
        props.pins = pins
        seen: list = []
        bpy.types.VIEW3D_PT_isochor.draw(SimpleNamespace(layout=Layout(seen)), bpy.context)
        assert {"isochor.preserve_volume", "isochor.live", "isochor.bake"} <= set(seen)
        assert ("group" in seen) == (pins == "GROUP")
    props.pins = "SELECTED"


def test_bad_input_is_one_line_and_changes_nothing(addon):
    empty_scene()
    ob = sphere()
    bpy.context.view_layer.objects.active = ob
    with pytest.raises(RuntimeError, match=r"Isochor: 'ball' has no Lattice modifier$") as err:
        bpy.ops.isochor.preserve_volume()
    assert len(str(err.value).strip().splitlines()) == 1
    lat = lattice((3, 3, 3), "KEY_BSPLINE")
    mod = ob.modifiers.new("Lattice", "LATTICE")
    mod.object = lat
    mod.strength = 0.5
    before = points(lat)
    with pytest.raises(RuntimeError, match=r"has strength 0.5; set it to 1$"):
        bpy.ops.isochor.preserve_volume()
    mod.strength = 1.0
    with pytest.raises(RuntimeError, match=r"pin some lattice points first"):
        bpy.ops.isochor.preserve_volume()
    np.testing.assert_array_equal(points(lat), before)


@needs_bases
def test_a_mesh_that_cannot_be_closed_is_one_line(addon):
    """A flat open sheet (a square's fan) cannot be closed into a solid (an open mesh with
    a volume is capped and solved): one line saying why, nothing changed."""
    empty_scene()
    mesh = bpy.data.meshes.new("sheet")
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 0)]
    mesh.from_pydata(corners, [], [(0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)])
    ob = bpy.data.objects.new("sheet", mesh)
    bpy.context.scene.collection.objects.link(ob)
    lat = lattice((3, 3, 3), "KEY_BSPLINE")
    ob.modifiers.new("Lattice", "LATTICE").object = lat
    bpy.context.view_layer.objects.active = ob
    lat.data.points.foreach_set("select", np.arange(27) < 9)
    before = points(lat)
    why = r"^Error: Isochor: the surface is a single flat open sheet.*no solid to keep$"
    with pytest.raises(RuntimeError, match=why) as err:
        bpy.ops.isochor.preserve_volume()
    assert len(str(err.value).strip().splitlines()) == 1
    np.testing.assert_array_equal(points(lat), before)


@needs_bases
@pytest.mark.parametrize(
    ("shape", "kind"), [((4, 4, 4), "KEY_BSPLINE"), ((10, 6, 6), "KEY_CATMULL_ROM")]
)
def test_preserve_volume_keeps_the_evaluated_volume_and_the_far_side(addon, shape, kind):
    ob, lat = rigged(shape, kind)
    rest_bottom = evaluated(ob)
    pinned = pin_and_drag(lat, 0.3)
    bpy.context.view_layer.update()
    dragged = volume_ratio(addon, ob)
    assert abs(dragged - 1) > 10 * TOL_VOLUME  # the drag alone changes the volume
    before = points(lat)
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    after = points(lat)
    np.testing.assert_array_equal(after[pinned], before[pinned])  # the pins held, exactly
    assert np.abs(after[~pinned] - before[~pinned]).max() > 0  # the free points moved
    assert abs(volume_ratio(addon, ob) - 1) <= TOL_VOLUME + F32_VOLUME
    # the far side (the lowest tenth of the mesh, below the pinned layer) stays in place
    low = rest_bottom[:, 2] < np.quantile(rest_bottom[:, 2], 0.1)
    moved = np.linalg.norm(evaluated(ob)[low] - rest_bottom[low], axis=1).max()
    assert moved <= 0.05 * np.ptp(rest_bottom[:, 2]), moved
    assert bpy.context.scene.isochor.volume_ratio == pytest.approx(1, abs=TOL_VOLUME + F32_VOLUME)


@needs_bases
def test_blenders_outside_option_solves(addon):
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=2)
    lat.data.use_outside = True
    pin_and_drag(lat, 0.3)
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    assert abs(volume_ratio(addon, ob) - 1) <= TOL_VOLUME + F32_VOLUME


@needs_bases
def test_a_target_ratio(addon):
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=2)
    pin_and_drag(lat, 0.1)
    bpy.context.scene.isochor.ratio = 1.2
    try:
        assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    finally:
        bpy.context.scene.isochor.ratio = 1.0
    assert volume_ratio(addon, ob) == pytest.approx(1.2, rel=TOL_VOLUME + F32_VOLUME)


@needs_bases
def test_undo_restores_the_points(addon):
    """The solve is one undo step: Blender pushes it after an operator with "UNDO" (in the
    UI; a background session does not, so the test pushes it as the UI would)."""
    for op in ("preserve_volume", "bake", "live"):
        assert "UNDO" in getattr(bpy.types, f"ISOCHOR_OT_{op}").bl_options
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=2)
    pin_and_drag(lat, 0.3)
    bpy.ops.ed.undo_push(message="drag")
    before = points(lat)
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    bpy.ops.ed.undo_push(message=bpy.types.ISOCHOR_OT_preserve_volume.bl_label)
    assert not np.array_equal(points(bpy.data.objects["cage"]), before)
    bpy.ops.ed.undo()
    np.testing.assert_array_equal(points(bpy.data.objects["cage"]), before)


@needs_bases
def test_live_solves_coarse_levels_first_and_follows_a_moved_pin(addon):
    from blender.scene import Target
    from blender.solving import LiveSolver, Settings

    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE")
    pinned = pin_and_drag(lat, 0.2)
    live = LiveSolver(Target.of(ob), Settings())
    writes = []
    while live.tick(budget=0.0):  # one step a tick: every level's nodes written
        writes.append(points(lat).copy())
    assert live.solves == 1 and live.last.converged and len(writes) > 1
    assert abs(volume_ratio(addon, ob) - 1) <= TOL_VOLUME + F32_VOLUME
    lat.data.points[int(np.flatnonzero(pinned)[-1])].co_deform.z += 0.1  # drags a pin on
    assert live.tick(budget=10.0) is False and live.solves == 2
    assert abs(volume_ratio(addon, ob) - 1) <= TOL_VOLUME + F32_VOLUME
    assert live.tick() is False and live.solves == 2  # nothing moved: no solve


@needs_bases
def test_a_24_frame_bake_keeps_each_frames_volume(addon):
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=2)
    data = lat.data
    pu, pv = data.points_u, data.points_v
    height = data.points[-1].co[2] - data.points[0].co[2]
    top = data.points[-1]
    for i in range(pu * pv):
        data.points[i].keyframe_insert("co_deform", frame=1)
    for frame, lift in ((1, 0.0), (12, 0.35), (24, -0.25)):
        top.co_deform.z = data.points[-1].co.z + lift * height
        top.keyframe_insert("co_deform", frame=frame)
    data.points.foreach_set("select", np.zeros(len(data.points), bool))
    props = bpy.context.scene.isochor
    props.frame_start, props.frame_end = 1, 24
    assert bpy.ops.isochor.bake() == {"FINISHED"}
    ratios = []
    for frame in range(1, 25):
        bpy.context.scene.frame_set(frame)
        ratios.append(volume_ratio(addon, ob))
    assert np.abs(np.array(ratios) - 1).max() <= TOL_VOLUME + F32_VOLUME, ratios
    bpy.context.scene.frame_set(12)
    assert abs(points(lat)[-1, 2] - (data.points[-1].co.z + 0.35 * height)) < 1e-5  # the key
    assert lat["isochor_baked"]  # a re-bake does not take these for pins


# --- what the modifier deforms: shape keys, rigs, several meshes; Edit Mode ---------------


def blender_volume(ob, lattice_on: bool = True) -> float:
    """The volume of ``ob`` as Blender evaluates it, in world units, by Blender's own
    ``bmesh.calc_volume`` (the Lattice modifier on, or switched off: the modifier's input)."""
    mod = next(m for m in ob.modifiers if m.type == "LATTICE")
    mod.show_viewport = lattice_on
    try:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        ev = ob.evaluated_get(depsgraph)
        bm = bmesh.new()
        bm.from_mesh(ev.to_mesh())
        ev.to_mesh_clear()
        bm.transform(ob.matrix_world)
        try:
            return bm.calc_volume(signed=True)
        finally:
            bm.free()
    finally:
        mod.show_viewport = True


def kept(ob) -> float:
    """Blender's volume of the lattice's output over that of its input."""
    return blender_volume(ob) / blender_volume(ob, lattice_on=False)


def swell_top(ob) -> None:
    """Key the ball's top half swollen (x and y by 1.3, z by 1.2), at value 1."""
    ob.shape_key_add(name="Basis")
    key = ob.shape_key_add(name="swell")
    for point in key.data:
        if point.co.z > 0:
            point.co = (point.co.x * 1.3, point.co.y * 1.3, point.co.z * 1.2)
    key.value = 1.0


@needs_bases
def test_a_shape_key_at_value_1_is_what_is_solved(addon):
    """A shape key that swells the top of the ball, at value 1: the modifier deforms the
    keyed shape, so that is the volume kept (Blender's, not the Basis shape's)."""
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=3)
    swell_top(ob)
    bpy.context.view_layer.update()
    keyed = blender_volume(ob, lattice_on=False)
    ob.data.shape_keys.key_blocks["swell"].mute = True
    basis = blender_volume(ob, lattice_on=False)
    ob.data.shape_keys.key_blocks["swell"].mute = False
    assert keyed / basis - 1 > 0.2  # the key changes the solid a lot
    pin_and_drag(lat, 0.3)
    assert abs(kept(ob) - 1) > 10 * TOL_VOLUME
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME
    assert bpy.context.scene.isochor.volume == pytest.approx(blender_volume(ob), rel=F32_VOLUME)


@needs_bases
def test_the_session_is_kept_for_the_same_mesh_and_built_again_when_it_changes(addon):
    """A second solve of the same mesh and lattice takes the session the first built; a
    mesh that changed under the modifier (a shape key) or a lattice of another resolution
    builds a new one, and each solve keeps Blender's volume of what the modifier deforms
    then (a stale session would keep the old solid's)."""
    from blender.sessions import SESSIONS

    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=3)
    SESSIONS.clear()
    built = SESSIONS.built

    def solved(lift: float) -> None:
        pin_and_drag(lat, lift)
        bpy.context.view_layer.update()
        assert abs(kept(ob) - 1) > 10 * TOL_VOLUME  # the drag alone changes the volume
        assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
        assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME

    solved(0.3)
    assert SESSIONS.built == built + 1
    solved(0.2)  # the dragged points lifted further: the same problem
    assert SESSIONS.built == built + 1
    swell_top(ob)
    solved(0.1)
    assert SESSIONS.built == built + 2
    lat.data.points_w = 5  # another resolution (Blender puts the points back on the grid)
    solved(0.3)
    assert SESSIONS.built == built + 3


@needs_bases
def test_an_armature_then_the_lattice(addon):
    """The usual character stack: an Armature modifier (a posed bone that moves and
    grows the upper half) before the Lattice modifier; the posed shape's volume is kept."""
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=3)
    arm_data = bpy.data.armatures.new("rig")
    arm = bpy.data.objects.new("rig", arm_data)
    bpy.context.scene.collection.objects.link(arm)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    bone = arm_data.edit_bones.new("top")
    bone.head, bone.tail = (0, 0, 0), (0, 0, 0.5)
    bpy.ops.object.mode_set(mode="OBJECT")
    group = ob.vertex_groups.new(name="top")
    z = np.array([v.co.z for v in ob.data.vertices])
    for i in np.flatnonzero(z > 0):
        group.add([int(i)], float(min(1.0, 3 * z[i])), "REPLACE")
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = arm
    ob.modifiers.move(len(ob.modifiers) - 1, 0)  # before the Lattice modifier
    assert [m.type for m in ob.modifiers] == ["ARMATURE", "LATTICE"]
    pose = arm.pose.bones["top"]
    pose.scale = (1.25, 1.25, 1.25)
    pose.location = (0.05, 0.1, 0.0)
    bpy.context.view_layer.objects.active = ob
    bpy.context.view_layer.update()
    ob.modifiers["Armature"].show_viewport = False
    unposed = blender_volume(ob, lattice_on=False)
    ob.modifiers["Armature"].show_viewport = True
    assert blender_volume(ob, lattice_on=False) / unposed - 1 > 0.1  # the pose grew it
    pin_and_drag(lat, 0.3)
    assert abs(kept(ob) - 1) > 10 * TOL_VOLUME
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME


def two_balls():
    """Two balls of different sizes side by side under one lattice; the big one active."""
    ob, lat = rigged((5, 4, 4), "KEY_BSPLINE", subdivisions=3, radius=0.45)
    ob.location = (-0.45, 0, 0)
    small = sphere("small", subdivisions=3, radius=0.3)
    small.location = (0.5, 0, 0)
    small.modifiers.new("Lattice", "LATTICE").object = lat
    bpy.context.view_layer.update()
    return ob, small, lat


@needs_bases
@pytest.mark.parametrize("preserve", ["TOTAL", "BODIES"])
def test_two_meshes_under_one_lattice(addon, preserve):
    """Both meshes count: their volumes summed, or each its own, as the panel says."""
    ob, small, lat = two_balls()
    props = bpy.context.scene.isochor
    props.preserve = preserve
    data = lat.data
    u = np.arange(len(data.points)) % data.points_u
    data.points.foreach_set("select", u <= 1)  # the left two layers pinned
    for i in np.flatnonzero(u == 0):  # ... and squashed towards the middle
        data.points[int(i)].co_deform.x += 0.12
    bpy.context.view_layer.update()
    try:
        rest = [blender_volume(o, lattice_on=False) for o in (ob, small)]
        assert abs(blender_volume(ob) / rest[0] - 1) > 10 * TOL_VOLUME
        assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
        now = [blender_volume(o) for o in (ob, small)]
    finally:
        props.preserve = "TOTAL"
    assert abs(sum(now) / sum(rest) - 1) <= TOL_VOLUME + F32_VOLUME
    each = [n / r - 1 for n, r in zip(now, rest, strict=True)]
    if preserve == "BODIES":
        assert max(map(abs, each)) <= TOL_VOLUME + F32_VOLUME, each
    else:  # summed: the free right side grows the small ball to make up the big one's loss
        assert max(map(abs, each)) > 10 * TOL_VOLUME, each
    # the lattice active: the same rig, both meshes
    bpy.context.view_layer.objects.active = lat
    assert bpy.ops.isochor.measure() == {"FINISHED"}
    assert props.volume == pytest.approx(sum(now), rel=F32_VOLUME)


def edit_drag(lat, lift: float) -> np.ndarray:
    """In the lattice's Edit Mode: select the pins and lift the top middle, as
    :func:`pin_and_drag` does, through the edit lattice (whose points' ``co`` Blender
    does not read as the rest grid: the height is taken before)."""
    height = lat.data.points[-1].co[2] - lat.data.points[0].co[2]
    bpy.context.view_layer.objects.active = lat
    assert bpy.ops.object.mode_set(mode="EDIT") == {"FINISHED"}
    assert lat.data.is_editmode
    return pin_and_drag(lat, lift, height)


@needs_bases
@pytest.mark.parametrize("active", ["lattice", "mesh"])
def test_edit_mode(addon, active):
    """Pins selected and points moved in the lattice's Edit Mode, with the lattice or the
    mesh active: the solve reads them as the artist sees them, the result shows in Edit
    Mode (Blender's evaluated mesh keeps its volume) and stays after leaving it."""
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=3)
    pinned = edit_drag(lat, 0.3)
    if active == "mesh":
        bpy.context.view_layer.objects.active = ob
    assert lat.mode == "EDIT"
    before = points(lat)
    assert abs(kept(ob) - 1) > 10 * TOL_VOLUME  # the edit shows: the drag changed it
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    assert lat.mode == "EDIT"
    in_edit = points(lat)
    np.testing.assert_array_equal(in_edit[pinned], before[pinned])
    assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME  # seen in Edit Mode
    bpy.context.view_layer.objects.active = lat
    assert bpy.ops.object.mode_set(mode="OBJECT") == {"FINISHED"}
    np.testing.assert_array_equal(points(lat), in_edit)  # kept after leaving
    assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME


@needs_bases
def test_the_solve_runs_beside_blender_and_esc_cancels(addon):
    """What the modal operator's timer drives (Blender without a window runs no modal
    operator): the solve's thread runs while Blender's main thread goes on evaluating the
    scene, nothing is written until it ends, its result is Blender's kept volume; a
    cancel (Esc) ends the thread and leaves the points as they were."""
    from blender.scene import RigError, Target
    from blender.solving import Settings, Solve

    ob, lat = rigged((8, 8, 8), "KEY_BSPLINE", subdivisions=5)
    pin_and_drag(lat, 0.3)
    bpy.context.view_layer.update()
    before, dragged = points(lat), blender_volume(ob)
    job = Solve(Target.of(ob), Settings())
    turns, stages = 0, []
    while job.running:  # the timer's turns: Blender's own work between them
        assert blender_volume(ob) == dragged  # the scene is untouched while it solves
        stages.append((job.stage, job.fraction))
        turns += 1
        job.wait(0.02)
    assert turns >= 1 and stages[0][0] == "load"
    np.testing.assert_array_equal(points(lat), before)
    job.finish()
    assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME
    solved = points(lat)
    job = Solve(Target.of(ob), Settings(ratio=1.3))
    job.cancel()
    assert job.wait(60)
    with pytest.raises(RigError, match="^Isochor: cancelled; nothing was changed$"):
        job.finish()
    np.testing.assert_array_equal(points(lat), solved)


@needs_bases
def test_the_exported_scenario_solves_the_same_in_isochor_solve(addon, tmp_path):
    """Export Scenario, then ``isochor solve`` on it (out of process): both converge and
    the command's mesh is the one Blender's modifier shows after the add-on's solve,
    within the solver's node tolerance of the lattice's size."""
    import json
    import subprocess
    import sys

    from isochor.core.defaults import TOL_NODES
    from tests.test_caps import read_back

    ob, lat = rigged((5, 5, 5), "KEY_BSPLINE", subdivisions=4)
    pin_and_drag(lat, 0.3)
    path = tmp_path / "ball.json"
    assert bpy.ops.isochor.export_scenario(filepath=str(path)) == {"FINISHED"}
    assert json.loads(path.read_text())["model"]["path"] == "ball.obj"
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    run = subprocess.run(
        [sys.executable, "-m", "isochor.app.cli.main", "solve", str(path), "--out",
         str(tmp_path / "out.obj"), "--report", str(tmp_path / "r.json")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert json.loads((tmp_path / "r.json").read_text())["converged"]
    cli, _ = read_back(tmp_path / "out.obj")
    from blender.scene import Target

    target = Target.of(ob)
    (shown,) = target.outputs()  # Blender's evaluated mesh, in the lattice's space
    size = np.ptp(target.rest(), axis=0).max()
    assert np.abs(cli - shown).max() <= TOL_NODES * size


# --- open meshes: the capped volume, Blender's Suzanne -----------------------------------


def arrays(ob) -> tuple[np.ndarray, np.ndarray]:
    """The mesh's vertices (object space) and its triangles, as Blender triangulates it."""
    mesh = ob.data
    mesh.calc_loop_triangles()
    tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
    mesh.loop_triangles.foreach_get("vertices", tris)
    return np.array([v.co for v in mesh.vertices]), tris.reshape(-1, 3)


def pieces(edges: np.ndarray, n: int) -> int:
    """How many connected pieces ``edges`` (k, 2) of ``n`` vertices make."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    graph = sp.coo_matrix((np.ones(len(edges)), tuple(np.asarray(edges).T)), shape=(n, n))
    label = connected_components(graph, directed=False)[1]
    return len(np.unique(label[np.asarray(edges).ravel()]))


def parts_and_holes(vertices, faces) -> tuple[int, int]:
    """Loose parts (joined by edges, as Blender's Separate by Loose Parts) and boundary
    loops (edges on one triangle), counted by this test."""
    sides = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    edges, count = np.unique(sides, axis=0, return_counts=True)
    return pieces(edges, len(vertices)), pieces(edges[count == 1], len(vertices))


def capped_now(ob, rest: np.ndarray, faces: np.ndarray) -> float:
    """The volume of ``ob`` as Blender evaluates it, its holes capped by this test: a fan
    over each loop from the loop's mean point at rest, moved by Blender's own modifier (a
    point cloud under the same lattice): a cap that deforms with the space over its hole."""
    from tests.test_caps import capped_volume

    def apex(loop: np.ndarray) -> np.ndarray:
        mesh = bpy.data.meshes.new("apex")
        mesh.from_pydata([rest[loop].mean(axis=0).tolist()], [], [])
        probe = bpy.data.objects.new("apex", mesh)
        bpy.context.scene.collection.objects.link(probe)
        probe.matrix_world = ob.matrix_world
        probe.modifiers.new("Lattice", "LATTICE").object = ob.modifiers[0].object
        try:
            return evaluated(probe)[0]
        finally:
            bpy.data.objects.remove(probe)
            bpy.data.meshes.remove(mesh)

    return capped_volume(evaluated(ob), faces, apex=apex)


def suzanne():
    """Blender's own Suzanne in an empty scene: open eye sockets, two eyes (open at the
    back) sunk into them, as separate parts."""
    empty_scene()
    assert bpy.ops.mesh.primitive_monkey_add() == {"FINISHED"}
    return bpy.context.active_object


def holed_ball(subdivisions: int):
    """A ball under a 4^3 B-spline lattice with the faces beyond x = 0.6 deleted: one hole."""
    ob, lat = rigged((4, 4, 4), "KEY_BSPLINE", subdivisions=subdivisions)
    bm = bmesh.new()
    bm.from_mesh(ob.data)
    bmesh.ops.delete(bm, geom=[f for f in bm.faces if f.calc_center_median().x > 0.6],
                     context="FACES")  # fmt: skip
    bm.to_mesh(ob.data)
    bm.free()
    return ob, lat


@needs_bases
def test_an_open_mesh_reads_and_keeps_its_capped_volume(addon, capfd):
    """A ball with a hole: the solve keeps the capped volume, the read-out measures it (not
    the open surface's sum, which moves with the origin) and the report line says so."""
    from tests.test_caps import CAP_SLACK, capped_volume

    ob, lat = holed_ball(subdivisions=2)
    rest, faces = arrays(ob)
    at_rest = capped_volume(rest, faces)
    pin_and_drag(lat, 0.3)
    bpy.context.view_layer.update()
    assert abs(capped_now(ob, rest, faces) / at_rest - 1) > 0.01  # the drag alone changes it
    capfd.readouterr()
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    assert "(1 hole capped)" in capfd.readouterr().out
    kept = capped_now(ob, rest, faces) / at_rest
    assert abs(kept - 1) <= TOL_VOLUME + F32_VOLUME + CAP_SLACK, kept
    props = bpy.context.scene.isochor
    assert props.holes == 1 and abs(props.volume_ratio - 1) <= TOL_VOLUME + F32_VOLUME
    read = props.volume
    assert read == pytest.approx(capped_now(ob, rest, faces), rel=F32_VOLUME + CAP_SLACK)

    # the mesh and its lattice far from the origin: the same read-out; the open surface's
    # own sum (what a closed mesh's volume is) changes
    def surface_sum() -> float:
        p = evaluated(ob) @ np.array(ob.matrix_world)[:3, :3].T + np.array(ob.location)
        return float(np.einsum("ij,ij->i", p[faces[:, 0]],
                               np.cross(p[faces[:, 1]], p[faces[:, 2]])).sum() / 6)  # fmt: skip

    before = surface_sum()
    for o in (ob, lat):
        o.location = (40.0, -30.0, 20.0)
    bpy.context.view_layer.update()
    assert abs(surface_sum() - before) > abs(before)
    assert bpy.ops.isochor.measure() == {"FINISHED"}
    assert props.volume == pytest.approx(read, rel=F32_VOLUME)
    # a modifier after the lattice (here one that adds vertices): still the lattice's solid
    ob.modifiers.new("Subdivision", "SUBSURF")
    assert bpy.ops.isochor.measure() == {"FINISHED"}
    assert props.volume == pytest.approx(read, rel=F32_VOLUME) and props.holes == 1


@needs_bases
def test_caps_added_as_geometry_let_blender_check_the_volume_kept(addon):
    """Add Caps on a ball with a hole: Blender's own volume of the capped mesh is the
    capped volume Isochor reads (the same solid); after a solve Blender's volume of the
    capped mesh under the lattice is kept."""
    from blender.scene import Target

    ob, lat = holed_ball(subdivisions=3)
    bpy.context.view_layer.update()
    isochor_says = Target.of(ob).volumes()
    assert isochor_says.holes == 1
    vertices = len(ob.data.vertices)
    assert bpy.ops.isochor.add_caps() == {"FINISHED"}
    assert len(ob.data.vertices) == vertices + 1  # the cap point, a real vertex now
    _, holes = parts_and_holes(*arrays(ob))
    assert holes == 0
    blender_says = blender_volume(ob, lattice_on=False)
    assert blender_says == pytest.approx(isochor_says.rest, rel=F32_VOLUME)
    assert Target.of(ob).volumes().holes == 0
    pin_and_drag(lat, 0.3)
    assert abs(kept(ob) - 1) > 10 * TOL_VOLUME
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    assert abs(kept(ob) - 1) <= TOL_VOLUME + F32_VOLUME
    assert bpy.ops.isochor.add_caps() == {"FINISHED"}  # closed: nothing more to add
    assert len(ob.data.vertices) == vertices + 1


def flat_lattice(ob, lat):
    lat.scale = (1.0, 1.0, 0.0)


def flat_mesh(ob, lat):
    ob.scale = (1.0, 0.0, 1.0)


def one_layer(ob, lat):
    lat.data.points_w = 1


def no_lattice_object(ob, lat):
    ob.modifiers[0].object = None


def a_vertex_group(ob, lat):
    ob.vertex_groups.new(name="some")
    ob.modifiers[0].vertex_group = "some"


def no_faces(ob, lat):
    bm = bmesh.new()
    bm.from_mesh(ob.data)
    bmesh.ops.delete(bm, geom=list(bm.faces), context="FACES_ONLY")
    bm.to_mesh(ob.data)
    bm.free()


def two_lattice_modifiers(ob, lat):
    ob.modifiers.new("Lattice.001", "LATTICE").object = lat


def the_lattice_active_and_unused(ob, lat):
    ob.modifiers[0].show_viewport = False
    bpy.context.view_layer.objects.active = lat


@needs_bases
@pytest.mark.parametrize(
    ("spoil", "says"),
    [
        (flat_lattice, r"lattice 'cage' is flat .*give it depth"),
        (flat_mesh, r"mesh 'ball' is flat .*give it depth"),
        (one_layer, r"has 3x3x1 points; it needs at least 2 along each axis"),
        (no_lattice_object, r"the Lattice modifier of 'ball' has no lattice object"),
        (a_vertex_group, r"uses a vertex group; clear it"),
        (no_faces, r"mesh 'ball' has no faces"),
        (two_lattice_modifiers, r"'ball' has 2 Lattice modifiers; keep one"),
        (the_lattice_active_and_unused, r"no mesh's Lattice modifier .* uses lattice 'cage'"),
    ],
)
def test_every_bad_input_is_one_line(addon, spoil, says):
    """Each of these is one line in the report area (no traceback) for every operator
    that reads the rig, and changes nothing (Bake may first say that nothing is keyed)."""
    ob, lat = rigged((3, 3, 3), "KEY_BSPLINE", subdivisions=1)
    lat.data.points.foreach_set("select", np.arange(27) < 9)
    spoil(ob, lat)
    bpy.context.view_layer.update()
    before = points(lat)
    for op in ("preserve_volume", "measure", "bake", "export_scenario"):
        kwargs = {"filepath": "/nonexistent/never.json"} if op == "export_scenario" else {}
        line = f"(.*{says}|no lattice point has keyframes.*)" if op == "bake" else f".*{says}"
        with pytest.raises(RuntimeError, match=f"^Error: Isochor: {line}$") as err:
            getattr(bpy.ops.isochor, op)(**kwargs)
        assert len(str(err.value).strip().splitlines()) == 1, op
    np.testing.assert_array_equal(points(lat), before)


def test_suzanne_exported_by_blender_opens_and_squashes_with_its_parts(tmp_path):
    """Blender's Suzanne written by Blender's OBJ exporter, opened by the library and by the
    command line (this Python, out of process): its parts are its bodies, its holes are
    capped, and a squash keeps the capped volume, measured by this test's own caps."""
    import json
    import subprocess
    import sys

    import isochor
    from tests.test_caps import CAP_SLACK, TOL, capped_volume, read_back, squash_scenario

    suzanne()
    path = tmp_path / "suzanne.obj"
    assert bpy.ops.wm.obj_export(filepath=str(path), export_materials=False) == {"FINISHED"}
    v_in, f_in = read_back(path)
    parts, holes = parts_and_holes(*arrays(bpy.context.active_object))
    assert (parts, holes) == (3, 4)  # the head and two eyes; the sockets and the eyes' backs
    before = abs(capped_volume(v_in, f_in))
    height = float(np.ptp(v_in[:, 2]))
    # the library: each body (the head, each eye) keeps its own capped volume
    session = isochor.load(path, lattice=(3, 3, 3), preserve="per-body")
    print("the repair says:", *session.warnings, sep="\n  ")
    for i in range(3):
        for j in range(3):
            session.move((i, j, 2), by=(0, 0, -0.2 * height))
    assert session.solve().converged
    report = session.report
    assert report["bodies"] == parts and report["caps"]["holes"] == holes
    assert report["volume_original"] == pytest.approx(before, rel=CAP_SLACK)
    assert max(abs(b["final"] / b["original"] - 1) for b in report["body_volumes"]) <= TOL
    assert sorted(b["original"] for b in report["body_volumes"])[0] < 0.02 * before  # an eye
    out = tmp_path / "out.obj"
    session.export(out)
    v_out, f_out = read_back(out)
    assert v_out.shape == v_in.shape and np.array_equal(f_out, f_in)  # its own faces, no caps
    assert abs(capped_volume(v_out, f_out)) == pytest.approx(before, rel=TOL + CAP_SLACK)
    assert v_out[:, 2].max() < v_in[:, 2].max() - 0.1 * height  # squashed
    # the command line, out of process
    scene, cli_out, cli_report = squash_scenario(path, tmp_path, height), tmp_path / "cli.obj", \
        tmp_path / "r.json"  # fmt: skip
    run = subprocess.run(
        [sys.executable, "-m", "isochor.app.cli.main", "solve", str(scene), "--out",
         str(cli_out), "--report", str(cli_report)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    print("the command line says:", run.stdout, run.stderr, sep="\n")
    assert f"capped: {holes} hole(s)" in run.stdout
    doc = json.loads(cli_report.read_text())
    assert doc["converged"] and doc["bodies"] == parts and doc["caps"]["holes"] == holes
    v_cli, f_cli = read_back(cli_out)
    assert np.array_equal(f_cli, f_in)
    assert abs(capped_volume(v_cli, f_cli)) == pytest.approx(before, rel=TOL + CAP_SLACK)


@pytest.mark.parametrize("fmt", ["ply", "stl", "glb"])
def test_suzanne_in_blenders_other_formats_opens_the_same(tmp_path, fmt):
    """Blender's PLY (quads and triangles mixed), STL and glTF of Suzanne: her three parts
    are three bodies, her four holes capped."""
    from isochor.core.io.meshio import load_mesh

    suzanne()
    path = tmp_path / f"suzanne.{fmt}"
    export = {"ply": bpy.ops.wm.ply_export, "stl": bpy.ops.wm.stl_export}
    assert export.get(fmt, bpy.ops.export_scene.gltf)(filepath=str(path)) == {"FINISHED"}
    loaded = load_mesh(path)
    assert (loaded.bodies, loaded.mesh.cap_vertices) == (3, 4), loaded.warnings


@needs_bases
def test_the_addon_keeps_suzannes_capped_volume(addon, capfd):
    """Suzanne under a B-spline lattice: the bottom layer pinned, the top one lifted;
    Preserve Volume keeps the volume of her capped solid (measured by this test's caps on
    Blender's evaluated mesh) and says how many holes it capped."""
    from tests.test_caps import CAP_SLACK, capped_volume

    ob = suzanne()
    lat = lattice((4, 4, 4), "KEY_BSPLINE", size=(3.0, 2.0, 2.2))
    ob.modifiers.new("Lattice", "LATTICE").object = lat
    bpy.context.view_layer.objects.active = ob
    data = lat.data
    w = np.arange(len(data.points)) // (data.points_u * data.points_v)
    top = np.flatnonzero(w == data.points_w - 1)
    data.points.foreach_set("select", (w == 0) | (w == data.points_w - 1))
    for i in top:
        data.points[int(i)].co_deform.z += 0.5
    bpy.context.view_layer.update()
    rest, faces = arrays(ob)
    at_rest = capped_volume(rest, faces)
    assert capped_now(ob, rest, faces) / at_rest - 1 > 0.1  # the lift grew her
    capfd.readouterr()
    assert bpy.ops.isochor.preserve_volume() == {"FINISHED"}
    said = capfd.readouterr().out
    print(said)
    assert "(4 holes capped)" in said
    kept = capped_now(ob, rest, faces) / at_rest
    assert abs(kept - 1) <= TOL_VOLUME + F32_VOLUME + CAP_SLACK, kept
    props = bpy.context.scene.isochor
    assert props.holes == 4 and abs(props.volume_ratio - 1) <= TOL_VOLUME + F32_VOLUME
    assert np.ptp(evaluated(ob)[:, 2]) > np.ptp(rest[:, 2]) + 0.3  # she is taller, still


# --- the extension package and the pipeline -----------------------------------------------


INSTALL = """
import sys
import time
import bpy

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.extensions.package_install_files(
    filepath=sys.argv[1], repo="user_default", enable_on_install=True
)
import isochor
from isochor.core import kernels

print("ENABLED", "bl_ext.user_default.isochor" in bpy.context.preferences.addons.keys())
print("FROM", isochor.__file__)
sys.path.insert(0, sys.argv[2])
import tests.blender_scenes as t  # the scene helpers (no factory reset: it would disable)

ob, lat = t.sphere(subdivisions=5), t.lattice((6, 6, 6), "KEY_BSPLINE")
ob.modifiers.new("Lattice", "LATTICE").object = lat
bpy.context.view_layer.objects.active = ob
t.pin_and_drag(lat, 0.3)
print("SOLVE", bpy.ops.isochor.preserve_volume())
print("FIRST", kernels.status())  # the first solve: NumPy while the child compiles
print("RATIO", bpy.context.scene.isochor.volume_ratio)
print("READY", kernels.ready(900), kernels.status())
print("NUMBA", sys.modules["numba"].__file__)
t.pin_and_drag(lat, 0.1)
print("SOLVE2", bpy.ops.isochor.preserve_volume())
print("RATIO2", bpy.context.scene.isochor.volume_ratio)
"""

#: an interpreter holding only bpy and what bpy itself needs (make testdeps)
BPY_ONLY = ROOT / ".venv-bpy" / "bin" / "python"


def test_the_manifest_says_the_packages_version():
    from blender.build import manifest_version, version

    assert manifest_version() == version()


def test_the_manifest_says_the_projects_homepage():
    """The source manifest's website is pyproject.toml's Homepage (build.py writes it into
    the built manifest; the install test reads it there)."""
    from blender.build import homepage, manifest_website

    assert homepage().startswith("https://")
    assert manifest_website() == homepage()


def test_the_extension_package_builds_and_installs(tmp_path):
    """``make addon`` (here: this platform's zip only), validated by Blender's tool, then
    installed into a fresh Blender user folder of an interpreter that holds only bpy,
    enabled, and solving with its own wheels: the compiled kernels too, compiled in the
    background into a fresh cache while the first solve runs on NumPy."""
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, str(ROOT / "blender" / "build.py"), "--platform", "current",
         "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    (package,) = tmp_path.glob("isochor-*.zip")
    names = zipfile.ZipFile(package).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    wheels = {n.split("/")[1].split("-")[0] for n in names if n.startswith("wheels/")}
    assert wheels == {"isochor", "scipy", "trimesh", "fast_simplification", "threadpoolctl",
                      "numba", "llvmlite"}  # fmt: skip
    manifest = zipfile.ZipFile(package).read("blender_manifest.toml").decode()
    assert all(f'"./{n}"' in manifest for n in names if n.endswith(".whl"))
    assert "build.py" not in names
    platform = re.search(r"^platforms = \[(.*)\]$", manifest, re.M)
    assert platform and platform.group(1) == '"linux-x64"' and "linux_x64" in package.name
    assert re.search(r'^copyright = \[".+"\]$', manifest, re.M)
    from blender.build import homepage

    assert re.search(rf'^website = "{re.escape(homepage())}"$', manifest, re.M)
    licence = zipfile.ZipFile(package).read("LICENSE").decode()
    assert "GNU GENERAL PUBLIC LICENSE" in licence and "Version 3" in licence
    if (ROOT / "LICENSE").is_file():  # the library's own (MIT), beside the add-on's
        assert zipfile.ZipFile(package).read("LICENSE-isochor") == (ROOT / "LICENSE").read_bytes()
    if not HAS_BASES:
        return
    if not BPY_ONLY.exists():
        pytest.skip("no .venv-bpy (an interpreter with bpy only): make testdeps")
    user = tmp_path / "user"
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(user),
           "XDG_CACHE_HOME": str(tmp_path / "cache")}  # fmt: skip
    env.pop("PYTHONPATH", None)
    run = subprocess.run(
        [str(BPY_ONLY), "-c", INSTALL, str(package), str(ROOT)],
        capture_output=True, text=True, timeout=1200, env=env, cwd=tmp_path,
    )  # fmt: skip
    said = dict(line.split(" ", 1) for line in run.stdout.splitlines() if line[:1].isupper())
    assert run.returncode == 0 and said.get("ENABLED") == "True", run.stdout + run.stderr
    assert said["FROM"].startswith(str(user)), said  # isochor from the extension's wheel
    assert said["NUMBA"].startswith(str(user)), said  # and numba
    assert said["SOLVE"] == "{'FINISHED'}"
    assert abs(float(said["RATIO"]) - 1) <= TOL_VOLUME + F32_VOLUME
    assert said["READY"] == "True ready", said  # compiled by a child, loaded from the cache
    assert said["SOLVE2"] == "{'FINISHED'}"
    assert abs(float(said["RATIO2"]) - 1) <= TOL_VOLUME + F32_VOLUME


def test_blender_imports_the_sequence_glb_with_uvs_and_materials(tmp_path):
    from tests.test_cli_goals import solve
    from tests.test_gltf_pipeline import textured_sphere, three_keys

    textured_sphere().export(tmp_path / "ball.obj")
    run = solve(tmp_path, three_keys({"path": "ball.obj"}), "--sequence", "anim.glb")
    assert run.returncode == 0, run
    empty_scene()
    assert bpy.ops.import_scene.gltf(filepath=str(tmp_path / "anim.glb")) == {"FINISHED"}
    (ob,) = [o for o in bpy.data.objects if o.type == "MESH"]
    mesh = ob.data
    assert len(mesh.uv_layers) == 1 and len(mesh.materials) == 1
    images = [n for n in mesh.materials[0].node_tree.nodes if n.type == "TEX_IMAGE"]
    assert images and images[0].image is not None and images[0].image.size[0] == 4
    keys = mesh.shape_keys.key_blocks
    assert len(keys) == 11  # the basis and a key a frame
    action = mesh.shape_keys.animation_data.action
    assert action is not None and action.frame_range[1] > action.frame_range[0]
