"""The rules behind the window's tools (issue 12), headless: the grab, rotate and scale
gesture (typed values, locks, the affine map), the drag session of a transform, the
selection helpers, and the picking maths of surface points and hidden nodes."""

from __future__ import annotations

import numpy as np
import pytest

from isochor.app.editor import goalrules, handlerules, noderules
from isochor.app.editor.document import Document
from isochor.app.editor.selection import face, faces_containing, layer, line
from isochor.app.editor.transform import Transform, apply, rotation
from isochor.app.view import picking
from isochor.core.lattice import Lattice
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.problem import build
from tests.models import icosphere

SPHERE = {"model": {"builtin": "sphere", "n_levels": 3}, "lattice": {"nodes": [3, 4, 5]}}


@pytest.fixture(scope="module")
def problem():
    return build(Scenario.from_dict(SPHERE))


@pytest.fixture
def doc(problem) -> Document:
    return Document(problem)


def typed(t: Transform, text: str) -> Transform:
    for ch in text:
        assert t.type_key(ch)
    return t


# -- the gesture ------------------------------------------------------------------------------
def test_typed_scale_along_z_about_the_centre():
    centre = np.array([1.0, 2.0, 3.0])
    t = Transform("scale", centre)
    t.lock("z")
    typed(t, "0.5")
    assert t.typing and t.typed_value() == 0.5
    pts = np.array([[1.0, 2.0, 5.0], [3.0, 0.0, 1.0]])
    out = apply(t.matrix(), pts)
    assert np.allclose(out, [[1.0, 2.0, 4.0], [3.0, 0.0, 2.0]])
    assert t.text() == "Scale 0.5 along z — type a value, X/Y/Z lock, Enter confirms, Esc cancels"
    # Shift+Z: the plane across z (x and y scale, z stays)
    t.lock("z", plane=True)
    assert np.allclose(apply(t.matrix(), pts), [[1.0, 2.0, 5.0], [2.0, 1.0, 1.0]])
    assert t.text().startswith("Scale 0.5 across z —")
    # unlocked: uniform
    t.lock("z", plane=True)  # the same lock again unlocks
    assert t.axis is None
    assert np.allclose(apply(t.matrix(), pts), centre + 0.5 * (pts - centre))


def test_typed_rotation_about_an_axis_through_the_centre():
    centre = np.array([0.0, 1.0, 1.0])
    t = typed(Transform("rotate", centre), "90")
    t.lock("x")
    p = centre + [0.3, 1.0, 0.0]  # one unit along +y from the centre
    assert np.allclose(apply(t.matrix(), p), centre + [0.3, 0.0, 1.0]), "right-handed about +x"
    assert t.text().startswith("Rotate 90° about x —")
    t.lock("x", plane=True)  # Shift+X while turning about x: the same lock, so it unlocks
    assert t.axis is None
    t.lock("x", plane=True)
    assert (t.axis, t.plane) == ("x", False) and "about x" in t.text()
    typed(t, "-")
    assert np.allclose(apply(t.matrix(), p), centre + [0.3, 0.0, -1.0])
    # unlocked: about the line of sight
    v = Transform("rotate", centre, view=(0, 0, 2))
    typed(v, "90")
    assert np.allclose(apply(v.matrix(), centre + [1.0, 0, 0]), centre + [0, 1.0, 0])
    assert "about the line of sight" in v.text()
    assert np.allclose(rotation([0, 0, 1], np.pi / 2) @ [1, 0, 0], [0, 1, 0])


def test_grab_typed_and_mouse_values():
    t = Transform("grab", np.zeros(3))
    t.follow(np.array([0.1, 0.2, 0.3]))
    assert np.allclose(t.matrix()[:3, 3], [0.1, 0.2, 0.3])
    assert t.text().startswith("Move by (0.1, 0.2, 0.3) —")
    t.lock("y")
    assert np.allclose(t.matrix()[:3, 3], [0, 0.2, 0]), "the mouse's move, along y only"
    t.lock("y", plane=True)
    assert np.allclose(t.matrix()[:3, 3], [0.1, 0, 0.3])
    t.lock("y")
    typed(t, "0.2")
    assert np.allclose(t.matrix()[:3, 3], [0, 0.2, 0])
    assert t.text().startswith("Move 0.2 along y —")
    u = typed(Transform("grab", np.zeros(3)), "2")
    assert np.allclose(u.matrix()[:3, 3], [2, 0, 0]), "unlocked: along x, as in Blender"
    assert u.text().startswith("Move 2 along x —")


def test_typing_rules():
    t = Transform("scale", np.zeros(3))
    assert not t.typing and t.typed_value() is None and t.value() == 1.0
    typed(t, "-")
    assert not t.typing, "a lone minus is no number yet"
    typed(t, "1.5.")
    assert t.typed == "-1.5", "one decimal point"
    assert t.typed_value() == -1.5
    typed(t, "\b\b\b")
    assert t.typed == "-" and not t.typing
    typed(t, "-.")
    assert t.typed == "." and t.typed_value() == 0.0
    assert not t.type_key("a")
    t.set_mode("rotate")
    assert t.typed == "" and t.axis is None and t.value() == 0.0
    with pytest.raises(ValueError):
        Transform("shear", np.zeros(3))
    with pytest.raises(ValueError):
        t.lock("w")


# -- the drag session of a transform ---------------------------------------------------------
def test_a_transform_drag_is_one_edit_with_its_verb(doc):
    lat = doc.state.lattice
    rows = layer(lat, [lat.index(2, 0, 0)], 0)
    doc.selection.select(rows)
    drag = doc.begin_drag("Scale")
    assert drag.text == f"Scale {len(rows)} nodes"
    base = np.array(doc.state.nodes)
    t = typed(Transform("scale", base[rows].mean(axis=0)), "0.5")
    t.lock("z")
    nodes = drag.transform(t.matrix())
    centre = base[rows].mean(axis=0)
    assert np.allclose(nodes[rows, 2], centre[2] + 0.5 * (base[rows, 2] - centre[2]))
    assert np.array_equal(nodes[rows, :2], base[rows, :2])
    others = np.setdiff1d(np.arange(lat.n_nodes), rows)
    assert np.array_equal(nodes[others], base[others])
    # a live preview's free nodes are kept, the dragged ones are where the gesture put them
    free = base + 0.01
    nodes = drag.transform(t.matrix(), free)
    assert np.array_equal(nodes[others], free[others])
    edit = doc.end_drag()
    assert edit.text == f"Scale {len(rows)} nodes"
    assert edit.state.moved[rows].all() and not edit.state.moved[others].any()


# -- selection helpers ------------------------------------------------------------------------
def test_layer_row_face_and_inverse(doc):
    lat = doc.state.lattice  # 3 x 4 x 5
    r = lat.index(1, 2, 3)
    assert len(layer(lat, [r], 0)) == 20 and len(layer(lat, [r], 2)) == 12
    assert all(lat.ijk(x)[1] == 2 for x in layer(lat, [r], 1))
    assert [lat.ijk(x) for x in line(lat, [r], 2)] == [(1, 2, k) for k in range(5)]
    two = line(lat, [r, lat.index(0, 0, 0)], 0)
    assert len(two) == 6
    assert faces_containing(lat, [r]) == []
    corner = lat.index(2, 3, 0)
    assert faces_containing(lat, [corner]) == [(0, True), (1, True), (2, False)]
    rows, name = face(lat, [corner], toward=(0, 0, -1))
    assert name == "z min" and len(rows) == 12
    rows, name = face(lat, [corner], toward=(1, 0.1, 0))
    assert name == "x max" and len(rows) == 20
    assert face(lat, [r])[1] == ""

    doc.selection.select([r])
    assert doc.selection.layer(0) and len(doc.selection.rows) == 20
    doc.selection.select([r])
    assert doc.selection.row(1) and len(doc.selection.rows) == 4
    assert doc.selection.face() == ""  # an inner row is on no face
    doc.selection.select([corner, lat.index(2, 0, 0)])
    assert doc.selection.face(toward=(0, 0, -1)) == "z min"
    assert doc.selection.inverse() and len(doc.selection.rows) == lat.n_nodes - 12
    doc.selection.select([])
    assert not doc.selection.layer(0) and not doc.selection.row(0)
    assert doc.selection.inverse() and len(doc.selection.rows) == lat.n_nodes


# -- picking maths ------------------------------------------------------------------------------
def ortho(scale: float = 100.0, height: float = 400.0) -> picking.Projection:
    """Looking down -z: world (x, y) -> pixels (200 + scale x, 200 - scale y); near z in
    front (depth = -z / 10)."""
    m = np.array(
        [
            [scale / 200, 0, 0, 0],
            [0, scale / 200, 0, 0],
            [0, 0, -0.1, 0],
            [0, 0, 0, 1],
        ]
    )
    return picking.Projection(m, (0.0, 0.0, 400.0, 400.0), height)


def test_surface_hit_gives_the_front_triangle_and_its_weights():
    proj = ortho()
    mesh = icosphere(2)
    x, y = proj.project([0.3, -0.2, 0.0])[0][0]
    face_row, w, p = picking.surface_hit(proj, mesh.vertices, mesh.faces, x, y)
    corners = mesh.vertices[mesh.faces[face_row]]
    assert np.allclose(w @ corners, p) and w.min() >= -1e-9 and w.sum() == pytest.approx(1)
    assert p[2] > 0.8, "the front of the sphere (towards +z, the camera)"
    assert np.allclose(p[:2], [0.3, -0.2], atol=1e-2)
    assert picking.surface_hit(proj, mesh.vertices, mesh.faces, 5.0, 5.0) is None
    # the same weights on another embedding of the mesh: the same surface point there
    moved = mesh.vertices * 2.0
    assert np.allclose(w @ moved[mesh.faces[face_row]], 2 * p)


def test_occluded_points_are_behind_the_mesh():
    proj = ortho()
    mesh = icosphere(2)
    pts = np.array(
        [
            [0.0, 0.0, 2.0],  # in front
            [0.0, 0.0, -2.0],  # behind
            [0.0, 0.0, 0.0],  # inside
            [1.5, 0.0, -2.0],  # behind, beside it: seen
        ]
    )
    assert picking.occluded(proj, pts, mesh.vertices, mesh.faces).tolist() == [
        False,
        True,
        True,
        False,
    ]
    a, b = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]
    (x0, y0), (x1, _) = proj.project([a, b])[0]
    assert x1 - x0 == pytest.approx(100.0)
    assert picking.segment_distance(proj, a, b, x0 + 50, y0 + 10) == pytest.approx(10.0)
    assert picking.segment_distance(proj, a, b, x1 + 20, y0) == pytest.approx(20.0)


def test_a_lattice_made_elsewhere_works_with_the_rules():
    lat = Lattice((2, 2, 2), np.zeros(3), np.eye(3))
    rows, name = face(lat, [0, 1], toward=(-1, 0, 0))
    assert name == "x min" and sorted(rows) == [0, 1, 2, 3]


# -- handles ---------------------------------------------------------------------------------
def commit(document: Document, edit):
    from isochor.app.editor.state import StateCell

    assert edit is not None
    cell = StateCell(edit.state)
    document.set_cell(cell)
    return cell


def test_handle_edits_selection_and_rest_points(doc):
    st = doc.state
    full = st.surface.full
    face = 7
    w = np.array([0.2, 0.3, 0.5])
    at = doc.rest_point(face, w)
    assert np.allclose(at, w @ full.vertices[full.faces[face]])
    edit = handlerules.edit_add_handle(doc.base(), at)
    assert edit.text == "Add handle" and not edit.state.solved
    assert np.allclose(edit.state.handles[0].to, at), "at rest, placed where it is"
    commit(doc, edit)
    assert doc.handle_points().shape == (1, 3)
    doc.selection.select([3])
    assert (
        doc.selection.select_handle(0)
        and doc.selection.handle == 0
        and len(doc.selection.rows) == 0
    )
    doc.selection.select([4])
    assert doc.selection.handle is None, "a node selection replaces the handle's"
    doc.selection.select_handle(0)
    with pytest.raises(IndexError):
        doc.selection.select_handle(5)
    move = handlerules.edit_move_handle(doc.base(), 0, at + [0.0, 0.0, 0.2])
    assert move.text == "Move handle" and np.allclose(move.state.handles[0].to[2], at[2] + 0.2)
    assert handlerules.edit_move_handle(doc.base(), 0, doc.state.handles[0].to) is None
    commit(doc, move)
    assert doc.selection.handle == 0, "a handle stays selected across its own edit"
    remove = handlerules.edit_remove_handle(doc.base())
    assert remove.text == "Remove handle" and remove.state.handles == ()
    commit(doc, remove)
    assert doc.selection.handle is None and handlerules.edit_remove_handle(doc.base()) is None


def test_a_handle_drag_moves_the_target_only(doc):
    at = doc.rest_point(0, [1.0, 0.0, 0.0])
    drag = doc.begin_handle_drag(None, at=at)
    assert drag.text == "Add handle" and drag.index == 0 and len(drag.rows) == 0
    base = np.array(doc.state.nodes)
    nodes = drag.move([0.1, 0.0, 0.0])
    assert np.array_equal(nodes, base), "no node is under the cursor"
    assert np.allclose(drag.target, at + [0.1, 0.0, 0.0])
    assert np.array_equal(drag.fixed(), doc.state.fixed_axes)
    edit = doc.end_drag()
    assert edit.text == "Add handle" and np.allclose(edit.state.handles[0].to, at + [0.1, 0, 0])
    commit(doc, edit)
    drag = doc.begin_handle_drag(0)
    drag.move([0.0, -0.1, 0.0], free=base + 0.01)
    edit = drag.finish(base + 0.02)
    assert edit.text == "Move handle"
    assert np.allclose(edit.state.handles[0].to, at + [0.1, -0.1, 0.0]), "from where it was"
    assert np.allclose(edit.state.nodes, base + 0.02), "the solve starts from the live nodes"


def test_handles_and_symmetry_are_saved_and_read_back(doc, tmp_path):
    from isochor.core.scenario.document import Scenario

    at = doc.rest_point(3, [0.5, 0.25, 0.25])
    commit(doc, handlerules.edit_add_handle(doc.base(), at, to=at + 0.1))
    commit(doc, goalrules.edit_symmetry(doc.base(), "z"))
    assert doc.state.goal.symmetry == "z"
    path = tmp_path / "handles.json"
    doc.save(path)
    sc = Scenario.read(path)
    assert sc.goal.symmetry == "z" and len(sc.handles) == 1
    assert np.allclose(sc.handles[0].at, at) and np.allclose(sc.handles[0].to, at + 0.1)
    again = Document.open(path).state
    assert again.goal.symmetry == "z" and again.handles == doc.state.handles
    assert again.goal == doc.state.goal and not again.solved
    # reset takes the handles away with the moves and pins
    reset = noderules.edit_reset(doc.base())
    assert reset.state.handles == () and reset.state.goal.symmetry == "z"


def test_the_status_says_what_became_of_the_handles():
    from isochor.app.editor.state import SolveSummary, handles_note
    from isochor.core.goal.handles import HandleResult

    met = HandleResult((0, 0, 0), (1, 0, 0), (1, 0, 0), 0.0)
    miss = HandleResult((0, 0, 0), (1, 0, 0), (0.9, 0, 0), 0.031)
    assert handles_note(SolveSummary(True)) == ""
    assert handles_note(SolveSummary(True, handles=(met,))) == " The handle is met."
    assert handles_note(SolveSummary(True, handles=(met, met))) == " All 2 handles met."
    note = handles_note(SolveSummary(True, handles=(met, miss)))
    assert note == (
        " 2 handles cannot all be met: fitted by least squares, largest miss 3.1% of the size."
    )


# -- symmetry --------------------------------------------------------------------------------
def test_symmetry_on_mirrors_the_selected_side_and_edits_follow(doc):
    from isochor.core.errors import IsochorError

    lat = doc.state.lattice  # 3 x 4 x 5
    a, b = lat.index(0, 1, 1), lat.index(2, 2, 3)
    doc.selection.select([a])
    commit(doc, noderules.edit_position(doc.base(), 2, float(doc.state.nodes[a, 2]) + 0.3))
    doc.selection.select([b])
    commit(doc, noderules.edit_pins(doc.base(), [b, lat.index(2, 0, 0)], True))
    # with b (high x side) selected, the high side is mirrored: a's move is lost
    edit = goalrules.edit_symmetry(doc.base(), "x")
    assert edit.text == "Symmetry across x, the x-max side mirrored"
    st = edit.state
    m = st.mirror
    assert st.goal.symmetry == "x" and m.asymmetry(st.nodes) < 1e-12
    assert st.pinned[b] and st.pinned[m.partner[b]] and not st.moved[a]
    # without a selection, the side with more fixed nodes (two pins against one move)
    doc.selection.select([])
    edit = goalrules.edit_symmetry(doc.base(), "x")
    assert edit.text == "Symmetry across x, the x-max side mirrored"
    doc.selection.select([a])
    assert (
        goalrules.edit_symmetry(doc.base(), "x").text
        == "Symmetry across x, the x-min side mirrored"
    )
    doc.selection.select([])
    commit(doc, edit)
    assert goalrules.edit_symmetry(doc.base(), "x") is None
    # edits mirror from now on: a move, a pin on one axis, an unpin
    doc.selection.select([a])
    move = noderules.edit_position(doc.base(), 1, float(doc.state.nodes[a, 1]) - 0.2)
    assert move.text == "Move 1 node, mirrored"
    assert move.state.moved[m.partner[a]] and m.asymmetry(move.state.nodes) < 1e-12
    commit(doc, move)
    axis = goalrules.edit_pin_axes(doc.base(), [lat.index(0, 0, 0)], "z")
    assert axis.state.pin_axes[m.partner[lat.index(0, 0, 0)]].tolist() == [False, False, True]
    unpin = noderules.edit_pins(doc.base(), [m.partner[b]], False)
    assert not unpin.state.fixed[b] and not unpin.state.fixed[m.partner[b]]
    assert goalrules.edit_symmetry(doc.base(), "none").text == "Symmetry off"
    with pytest.raises(IsochorError):
        goalrules.edit_symmetry(doc.base(), "w")


def test_a_mirrored_drag_keeps_the_plane_and_the_pairs(doc):
    lat = doc.state.lattice
    commit(doc, goalrules.edit_symmetry(doc.base(), "x"))
    m = doc.state.mirror
    side, plane = lat.index(0, 1, 2), lat.index(1, 1, 2)
    doc.selection.select([side, plane])
    drag = doc.begin_drag()
    assert sorted(drag.rows) == sorted([side, plane, int(m.partner[side])])
    nodes = drag.move([0.2, 0.1, 0.0])
    assert np.allclose(nodes[m.partner[side]], m.point(nodes[side]))
    assert nodes[plane, 0] == pytest.approx(m.plane), "a node on the plane stays on it"
    assert drag.text == "Move 2 nodes, mirrored"
    edit = doc.end_drag()
    assert edit.state.moved[m.partner[side]] and m.asymmetry(edit.state.nodes) < 1e-12
    # both partners selected: the first leads, the result is symmetric
    commit(doc, edit)
    doc.selection.select([side, int(m.partner[side])])
    drag = doc.begin_drag("Rotate")
    nodes = drag.move([0.0, 0.0, 0.3])
    assert m.asymmetry(nodes) < 1e-12 and drag.text == "Rotate 2 nodes"


def test_symmetry_needs_an_axis_aligned_lattice():
    from isochor.core.errors import IsochorError

    spec = dict(SPHERE, lattice={"nodes": [3, 3, 3]})
    frame = {"origin": [-2, -2, -2], "axes": [[4, 0.4, 0], [0, 4, 0], [0, 0, 4]]}
    spec["lattice"] = {"nodes": [3, 3, 3], "frame": frame}
    d = Document(build(Scenario.from_dict(spec)))
    with pytest.raises(IsochorError, match="not aligned"):
        goalrules.edit_symmetry(d.base(), "x")


def test_the_held_face_drawn_before_a_solve_is_the_one_it_holds(doc):
    from isochor.core.solve.generators import run_to_end
    from isochor.core.solve.multilevel import solve

    at = doc.rest_point(11, [0.4, 0.3, 0.3])
    commit(doc, handlerules.edit_add_handle(doc.base(), at, to=at + [0.0, 0.0, 0.3]))
    commit(doc, goalrules.edit_symmetry(doc.base(), "y"))
    st = doc.state
    mask, face = doc.held()
    assert face and mask.any()
    result = run_to_end(
        solve(
            st.surface,
            st.nodes,
            st.fixed_axes,
            goal=st.goal,
            handles=st.handles,
            options=st.problem.options,
        )
    )
    assert result.held_face == face and sorted(result.held) == np.flatnonzero(mask).tolist()
    assert st.mirror.asymmetry(result.nodes) < 1e-9
