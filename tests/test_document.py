"""The editor model (isochor.app.editor.document): its edit rules, selection, drag session, results,
status words and files. Qt-free, so everything here runs headless."""

from __future__ import annotations

import json
import os
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

from isochor.app.editor import goalrules, latticerules, noderules
from isochor.app.editor.document import (
    DocState,
    Document,
    Edit,
    SolveSummary,
    StateCell,
    default_lattice_shape,
    describe_status,
    initial_state,
    plural,
)
from isochor.core.errors import IsochorError
from isochor.core.io.meshio import load_mesh, save_mesh
from isochor.core.mesh import TriMesh
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.examples import example_scenario
from isochor.core.scenario.problem import build
from isochor.core.scenario.shapes import sphere_levels
from isochor.core.solve.generators import run_to_end
from isochor.core.solve.multilevel import solve
from tests.fresh import run_fresh

ROOT = Path(__file__).resolve().parents[1]

SPHERE = {"model": {"builtin": "sphere", "n_levels": 3}, "lattice": {"nodes": [3, 3, 3]}}


# -- fixtures and helpers ------------------------------------------------------------------
@pytest.fixture(scope="module")
def torus_problem():
    """The torus-compression example: 3x3x3, top and bottom layers moved, middle free."""
    return build(example_scenario("torus-compression"))


@pytest.fixture(scope="module")
def sphere_problem():
    """A built-in sphere in a 3x3x3 lattice, nothing moved: at rest."""
    return build(Scenario.from_dict(SPHERE))


@pytest.fixture(scope="module")
def torus_result(torus_problem):
    prob = torus_problem
    return run_to_end(solve(prob.surface, prob.nodes, prob.fixed, options=prob.options))


@pytest.fixture
def doc(torus_problem) -> Document:
    return Document(torus_problem, title="example: torus-compression")


@pytest.fixture
def rest(sphere_problem) -> Document:
    return Document(sphere_problem)


def events_of(document: Document) -> list[str]:
    events: list[str] = []
    document.subscribe(events.append)
    return events


def commit(document: Document, edit: Edit) -> StateCell:
    """What the undo stack does with an edit: a new current cell."""
    assert edit is not None
    cell = StateCell(edit.state)
    document.set_cell(cell)
    return cell


def free_rows(document: Document) -> np.ndarray:
    return np.flatnonzero(~document.state.fixed)


def assert_fresh(edit: Edit) -> None:
    """An edit's state is a new, unsolved state without a result."""
    assert isinstance(edit, Edit)
    assert edit.state.solved is False
    assert edit.state.result is None


def summary(**kw) -> SolveSummary:
    base = {
        "converged": True,
        "levels": (3, 4),
        "n_levels": 7,
        "rel_volume_error": -1.234e-5,
        "free_nodes": 9,
    }
    base.update(kw)
    return SolveSummary(**base)


def settings(goal) -> dict:
    """The goal's fields besides the target, by name."""
    return {k: v for k, v in asdict(goal).items() if k != "target_ratio"}


# -- DocState and the initial state ----------------------------------------------------------
def test_example_document_starts_with_its_moves(torus_problem):
    d = Document.example()
    assert d.title == "example: torus-compression"
    assert d.path is None and d.preserve is True and d.drag is None and d.live_nodes is None
    st = d.state
    assert st.lattice.shape == (3, 3, 3)
    # The top and bottom layers (k = 0, 2) are moved, the middle layer is free.
    expect = np.array([st.lattice.ijk(r)[2] != 1 for r in range(27)])
    np.testing.assert_array_equal(st.moved, expect)
    assert not st.pinned.any()
    np.testing.assert_array_equal(st.fixed, expect)
    np.testing.assert_allclose(st.nodes, torus_problem.nodes)
    assert st.goal.target_ratio == 1.0
    assert st.solved is False and st.result is None and not st.converged
    assert d.needs_solve()
    assert d.selection.rows.tolist() == []
    assert repr(d.cell) == "StateCell(solved=False)"


def test_initial_state_maps_moves_and_pins_to_flags():
    sc = Scenario.from_dict(
        {
            **SPHERE,
            "moves": [
                {"node": [0, 0, 0], "by": [0.1, 0.0, 0.0]},
                {"node": [2, 1, 0], "to": [2.0, 0.0, -1.0]},
            ],
            "pins": [[1, 1, 1], [2, 2, 2]],
            "target_volume_ratio": 1.0,
        }
    )
    prob = build(sc)
    st = initial_state(prob)
    lat = st.lattice
    assert np.flatnonzero(st.moved).tolist() == [lat.index(0, 0, 0), lat.index(2, 1, 0)]
    assert np.flatnonzero(st.pinned).tolist() == [lat.index(1, 1, 1), lat.index(2, 2, 2)]
    np.testing.assert_allclose(
        st.nodes[lat.index(0, 0, 0)], lat.rest_nodes[lat.index(0, 0, 0)] + [0.1, 0, 0]
    )
    np.testing.assert_allclose(st.nodes[lat.index(2, 1, 0)], [2.0, 0.0, -1.0])
    assert st.solved is False and st.result is None


def test_initial_state_at_rest_is_solved_without_result(rest):
    st = rest.state
    assert rest.title == "built-in sphere"
    assert not st.moved.any() and not st.pinned.any()
    np.testing.assert_allclose(st.nodes, st.lattice.rest_nodes)
    assert st.solved is True and st.result is None and st.converged
    assert not rest.needs_solve()
    # Pins alone keep it at rest; a target other than 1 needs a solve.
    pinned = initial_state(build(Scenario.from_dict({**SPHERE, "pins": [[0, 0, 0]]})))
    assert pinned.solved is True and pinned.pinned.sum() == 1
    deflate = initial_state(build(Scenario.from_dict({**SPHERE, "target_volume_ratio": 0.9})))
    assert deflate.solved is False and deflate.goal.target_ratio == 0.9


def test_docstate_arrays_are_read_only_copies(sphere_problem):
    nodes = sphere_problem.surface.lattice.rest_nodes.copy()
    pinned = np.zeros(27, bool)
    st = DocState(sphere_problem, nodes.ravel(), pinned, np.zeros(27, bool))
    assert st.nodes.shape == (27, 3)
    nodes[0] = 99.0
    pinned[0] = True
    assert st.nodes[0, 0] != 99.0 and not st.pinned[0]
    for a in (st.nodes, st.pinned, st.moved):
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[0] = a[1]
    assert st.surface is sphere_problem.surface and st.lattice is sphere_problem.surface.lattice


def test_docstate_edits_and_same_edit(sphere_problem):
    st = initial_state(sphere_problem)
    assert st.solved
    a = st.moved_to(st.nodes + 0.0, [1, 2])
    assert a.solved is False and a.result is None
    assert np.flatnonzero(a.moved).tolist() == [1, 2]
    b = a.pinned_as([2, 5], True)
    assert np.flatnonzero(b.pinned).tolist() == [2, 5]
    np.testing.assert_array_equal(np.flatnonzero(b.fixed), [1, 2, 5])
    c = b.pinned_as([2], False)  # unpinning also clears the moved flag
    assert np.flatnonzero(c.moved).tolist() == [1]
    assert np.flatnonzero(c.pinned).tolist() == [5]
    assert a.same_edit(st.moved_to(st.nodes + 0.0, [2, 1]))
    assert not a.same_edit(b)
    assert not a.same_edit(a.edited(goal=replace(a.goal, target_ratio=0.5)))
    assert not a.same_edit(a.edited(nodes=a.nodes + 1e-9))
    assert st.solved and not st.moved.any()  # the original is untouched
    assert plural(1) == "1 node" and plural(3) == "3 nodes" and plural(0, "pin") == "0 pins"


# -- selection -------------------------------------------------------------------------------
def test_select_replace_add_toggle_and_events(doc):
    events = events_of(doc)
    assert doc.selection.select([5, 3, 3]) is True
    assert doc.selection.rows.tolist() == [3, 5]
    assert doc.selection.select([3, 5]) is False  # no change, no event
    assert doc.selection.select([7, 1], "add") is True
    assert doc.selection.rows.tolist() == [1, 3, 5, 7]
    assert doc.selection.select([3], "add") is False
    assert doc.selection.select([3, 4], "toggle") is True
    assert doc.selection.rows.tolist() == [1, 4, 5, 7]
    assert doc.selection.select(np.array([2]), "replace") is True
    assert doc.selection.rows.tolist() == [2]
    assert doc.selection.select([], "toggle") is False
    assert doc.selection.select(range(0)) is True
    assert doc.selection.rows.tolist() == []
    assert events == ["selection"] * 5
    assert doc.selection.rows.dtype.kind == "i"


def test_select_rejects_rows_outside_the_lattice_and_unknown_modes(doc):
    doc.selection.select([1])
    events = events_of(doc)
    for bad in ([27], [-1], [0, 30]):
        with pytest.raises(IndexError):
            doc.selection.select(bad)
    with pytest.raises(ValueError, match="unknown selection mode"):
        doc.selection.select([2], "intersect")
    assert doc.selection.rows.tolist() == [1]
    assert events == []


def test_select_all(doc):
    events = events_of(doc)
    assert doc.selection.all() is True
    assert doc.selection.rows.tolist() == list(range(27))
    assert doc.selection.all() is False
    assert events == ["selection"]


def test_the_selection_part_adds_toggles_and_follows_the_state(doc, sphere_problem):
    events = events_of(doc)
    sel = doc.selection
    assert sel.add([4, 2]) is True and sel.rows.tolist() == [2, 4]
    assert sel.toggle([2, 6]) is True and sel.rows.tolist() == [4, 6]
    assert sel.none() is True and sel.rows.tolist() == []
    assert sel.none() is False
    assert events == ["selection"] * 3
    # a new current state: the rows stay (silently) on the same lattice, go with a new one
    sel.select([3, 26])
    events.clear()
    commit(doc, noderules.edit_pins(doc.base(), [3], True))
    assert sel.rows.tolist() == [3, 26] and events == ["state"]
    commit(doc, latticerules.edit_lattice(doc.base(), (2, 2, 2)))
    assert sel.rows.tolist() == [] and events == ["state", "scene", "state"]


def test_the_edit_base_is_a_snapshot(doc):
    """A rule reads the base it is given: what changes in the document after the base was
    taken does not reach it, and nothing a rule does changes the document."""
    doc.selection.select([13])
    doc.show_live(doc.state.nodes + 0.01)
    base = doc.base()
    assert base.state is doc.state and base.rows.tolist() == [13] and base.handle is None
    np.testing.assert_array_equal(base.nodes, doc.base_nodes())
    assert base.problems is doc.problems
    with pytest.raises(ValueError, match="read-only"):
        base.nodes[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        base.rows[0] = 1
    doc.selection.select([0])
    doc.show_live(None)
    edit = noderules.edit_toggle_pin(base)
    assert np.flatnonzero(edit.state.pin_axes.any(axis=1)).tolist() == [13], "the old rows"
    free = np.flatnonzero(~edit.state.fixed)
    np.testing.assert_array_equal(edit.state.nodes[free], base.nodes[free])
    assert doc.state is base.state and doc.selection.rows.tolist() == [0]
    assert not doc.state.pinned.any()


# -- edit_position ---------------------------------------------------------------------------
def test_edit_position_moves_one_node_to_the_typed_value(doc):
    r = int(free_rows(doc)[0])
    doc.selection.select([r])
    before = doc.cell
    edit = noderules.edit_position(doc.base(), 1, 0.75)
    assert_fresh(edit)
    assert edit.text == "Move 1 node"
    assert edit.state.nodes[r, 1] == pytest.approx(0.75)
    expect = np.array(doc.state.nodes)
    expect[r, 1] = 0.75
    np.testing.assert_allclose(edit.state.nodes, expect)
    assert edit.state.moved[r] and edit.state.fixed[r]
    np.testing.assert_array_equal(
        np.flatnonzero(edit.state.moved), np.union1d(np.flatnonzero(doc.state.moved), [r])
    )
    assert doc.cell is before and not doc.state.moved[r]  # an edit commits nothing itself


def test_edit_position_moves_the_centre_of_several_nodes(doc):
    rows = free_rows(doc)[:3]
    doc.selection.select(rows)
    nodes = doc.state.nodes
    centre = nodes[rows, 0].mean()
    edit = noderules.edit_position(doc.base(), 0, centre + 0.4)
    assert_fresh(edit)
    assert edit.text == "Move 3 nodes"
    assert edit.state.nodes[rows, 0].mean() == pytest.approx(centre + 0.4)
    np.testing.assert_allclose(edit.state.nodes[rows, 0], nodes[rows, 0] + 0.4)
    np.testing.assert_array_equal(edit.state.nodes[rows, 1:], nodes[rows, 1:])
    assert edit.state.moved[rows].all()
    others = np.setdiff1d(np.arange(27), rows)
    np.testing.assert_array_equal(edit.state.nodes[others], nodes[others])


def test_edit_position_without_a_change_is_none(doc):
    assert noderules.edit_position(doc.base(), 0, 1.0) is None  # nothing selected
    r = int(free_rows(doc)[0])
    doc.selection.select([r])
    assert noderules.edit_position(doc.base(), 0, float("nan")) is None
    assert noderules.edit_position(doc.base(), 0, float("inf")) is None
    assert (
        noderules.edit_position(doc.base(), 2, float(doc.state.nodes[r, 2])) is None
    )  # where it is


def test_edit_position_starts_from_the_base_nodes(doc):
    r = int(free_rows(doc)[0])
    doc.selection.select([r])
    live = doc.state.nodes + 0.01
    doc.show_live(live)
    edit = noderules.edit_position(doc.base(), 0, 2.0)
    others = np.setdiff1d(np.arange(27), [r])
    np.testing.assert_allclose(edit.state.nodes[others], live[others])
    assert edit.state.nodes[r, 0] == pytest.approx(2.0)
    np.testing.assert_allclose(edit.state.nodes[r, 1:], live[r, 1:])
    # Preserve off: plain FFD, the free nodes at rest and the live nodes ignored.
    doc.set_preserve(False)
    edit = noderules.edit_position(doc.base(), 0, 2.0)
    st = doc.state
    rest = st.lattice.rest_nodes
    free = np.setdiff1d(free_rows(doc), [r])
    np.testing.assert_allclose(edit.state.nodes[free], rest[free])
    np.testing.assert_allclose(edit.state.nodes[st.fixed], st.nodes[st.fixed])
    np.testing.assert_allclose(edit.state.nodes[r], [2.0, *rest[r, 1:]])


# -- edit_pins and edit_toggle_pin -------------------------------------------------------------
def test_edit_pins_pins_and_unpins(doc):
    free = free_rows(doc)[:2]
    edit = noderules.edit_pins(doc.base(), free, True)
    assert_fresh(edit)
    assert edit.text == "Pin 2 nodes"
    assert np.flatnonzero(edit.state.pinned).tolist() == free.tolist()
    np.testing.assert_array_equal(edit.state.moved, doc.state.moved)
    commit(doc, edit)
    assert noderules.edit_pins(doc.base(), free, True) is None  # pinned already
    assert noderules.edit_pins(doc.base(), free[:1], True) is None

    unpin = noderules.edit_pins(doc.base(), free[:1], False)
    assert_fresh(unpin)
    assert unpin.text == "Unpin 1 node"
    assert np.flatnonzero(unpin.state.pinned).tolist() == free[1:].tolist()

    moved = int(np.flatnonzero(doc.state.moved)[0])
    unpin_moved = noderules.edit_pins(doc.base(), [moved], False)
    assert unpin_moved.text == "Unpin 1 node"
    assert not unpin_moved.state.moved[moved] and not unpin_moved.state.fixed[moved]
    # The node stays where it was (the solver moves it later).
    np.testing.assert_allclose(unpin_moved.state.nodes[moved], doc.state.nodes[moved])

    still_free = free_rows(doc)[:1]
    assert noderules.edit_pins(doc.base(), still_free, False) is None  # not fixed: nothing to unpin
    assert noderules.edit_pins(doc.base(), [], True) is None
    assert noderules.edit_pins(doc.base(), np.zeros(0, int), False) is None


def test_edit_pins_all_nodes(doc):
    pin_all = noderules.edit_pins(doc.base(), None, True)
    assert pin_all.text == "Pin all nodes"
    assert pin_all.state.pinned.all()
    unpin_all = noderules.edit_pins(doc.base(), None, False)
    assert unpin_all.text == "Unpin all nodes"
    assert not unpin_all.state.fixed.any()
    commit(doc, pin_all)
    assert noderules.edit_pins(doc.base(), None, True) is None
    assert noderules.edit_pins(doc.base(), range(27), True) is None


def test_edit_pins_start_from_the_base_nodes(doc):
    live = doc.state.nodes + np.linspace(0, 0.02, 81).reshape(27, 3)
    doc.show_live(live)
    edit = noderules.edit_pins(doc.base(), free_rows(doc)[:1], True)
    np.testing.assert_allclose(edit.state.nodes, live)
    # Preserve off: the plain FFD, free nodes at rest and fixed ones where the user put them.
    doc.set_preserve(False)
    st = doc.state
    edit = noderules.edit_pins(doc.base(), free_rows(doc)[:1], True)
    expect = np.where(st.fixed[:, None], st.nodes, st.lattice.rest_nodes)
    np.testing.assert_allclose(edit.state.nodes, expect)
    assert not np.allclose(edit.state.nodes, live)


def test_edit_toggle_pin(doc):
    assert noderules.edit_toggle_pin(doc.base()) is None  # nothing selected
    free = free_rows(doc)[:2]
    doc.selection.select(free)
    edit = noderules.edit_toggle_pin(doc.base())
    assert edit.text == "Pin 2 nodes" and edit.state.pinned[free].all()
    commit(doc, edit)
    assert doc.selection.rows.tolist() == free.tolist()
    edit = noderules.edit_toggle_pin(doc.base())  # all fixed: unpin
    assert edit.text == "Unpin 2 nodes" and not edit.state.fixed[free].any()
    # Moved nodes count as fixed: toggling unpins them and clears their moved flag.
    moved = np.flatnonzero(doc.state.moved)[:3]
    doc.selection.select(moved)
    edit = noderules.edit_toggle_pin(doc.base())
    assert edit.text == "Unpin 3 nodes"
    assert not edit.state.moved[moved].any() and not edit.state.pinned[moved].any()
    # A mixed selection (some free) is pinned; the moved flags stay.
    mixed = np.array([moved[0], free_rows(doc)[-1]])
    doc.selection.select(mixed)
    edit = noderules.edit_toggle_pin(doc.base())
    assert edit.text == "Pin 2 nodes"
    assert edit.state.pinned[mixed].all() and edit.state.moved[moved[0]]


# -- edit_target -----------------------------------------------------------------------------
def test_edit_target(rest):
    edit = goalrules.edit_target(rest.base(), 90)
    assert_fresh(edit)
    assert edit.text == "Target volume 90 %"
    assert edit.state.goal.target_ratio == pytest.approx(0.9)
    np.testing.assert_array_equal(edit.state.moved, rest.state.moved)
    assert goalrules.edit_target(rest.base(), 100) is None  # the same ratio
    assert goalrules.edit_target(rest.base(), 100.0) is None
    for bad in (0, -5, float("nan")):
        assert goalrules.edit_target(rest.base(), bad) is None
    commit(rest, edit)
    assert rest.needs_solve()
    assert goalrules.edit_target(rest.base(), 90.0) is None
    back = goalrules.edit_target(rest.base(), 112.5)
    assert back.text == "Target volume 112.5 %"
    assert back.state.goal.target_ratio == pytest.approx(1.125)


def test_edit_target_rejects_an_infinite_target(rest):
    assert goalrules.edit_target(rest.base(), float("inf")) is None


def test_edit_target_starts_from_the_base_nodes(doc):
    live = doc.state.nodes * 1.01
    doc.show_live(live)
    np.testing.assert_allclose(goalrules.edit_target(doc.base(), 95).state.nodes, live)


# -- edit_reset ------------------------------------------------------------------------------
def test_edit_reset(doc):
    st = doc.state
    commit(doc, noderules.edit_pins(doc.base(), free_rows(doc)[:1], True))
    edit = noderules.edit_reset(doc.base())
    assert edit.text == "Reset nodes"
    new = edit.state
    np.testing.assert_allclose(new.nodes, st.lattice.rest_nodes)
    assert not new.pinned.any() and not new.moved.any()
    assert new.solved is True and new.result is None  # at rest with ratio 1: solved
    assert new.problem is st.problem
    commit(doc, edit)
    assert noderules.edit_reset(doc.base()) is None  # at rest already
    assert describe_status(doc.state, preserve=True, activity="idle")[0] == "At rest"


def test_edit_reset_with_another_target_needs_a_solve(doc):
    commit(doc, goalrules.edit_target(doc.base(), 80))
    edit = noderules.edit_reset(doc.base())
    assert edit.state.solved is False and edit.state.goal.target_ratio == pytest.approx(0.8)
    assert not edit.state.fixed.any()


def test_edit_reset_of_pins_alone(rest):
    assert noderules.edit_reset(rest.base()) is None
    commit(rest, noderules.edit_pins(rest.base(), [4], True))
    edit = noderules.edit_reset(rest.base())
    assert edit is not None and not edit.state.pinned.any() and edit.state.solved


# -- edit_lattice ----------------------------------------------------------------------------
def test_edit_lattice_builds_a_new_lattice_at_rest(doc):
    commit(doc, noderules.edit_pins(doc.base(), free_rows(doc)[:1], True))
    commit(doc, goalrules.edit_target(doc.base(), 90))
    old = doc.problem
    edit = latticerules.edit_lattice(doc.base(), (4, 3, 2))
    assert edit.text == "Rebuild lattice 4x3x2"
    st = edit.state
    assert st.lattice.shape == (4, 3, 2) and st.problem is not old
    np.testing.assert_allclose(st.nodes, st.lattice.rest_nodes)
    assert not st.moved.any() and not st.pinned.any()
    assert st.problem.scenario.moves == () and st.problem.scenario.pins == ()
    assert st.goal.target_ratio == pytest.approx(0.9)
    assert st.solved is False and st.result is None  # ratio 0.9: to be solved
    # The model pyramid is reused, not loaded again.
    assert all(a is b for a, b in zip(st.surface.levels, old.surface.levels))
    assert doc.problem is old  # nothing committed


def test_edit_lattice_at_ratio_one_is_solved_at_rest(doc):
    edit = latticerules.edit_lattice(doc.base(), [2, 2, 2])
    assert edit.state.solved is True and edit.state.result is None
    assert edit.state.lattice.shape == (2, 2, 2)


def test_edit_lattice_checks_the_shape(doc):
    assert latticerules.edit_lattice(doc.base(), (3, 3, 3)) is None  # the same shape
    for bad in ((1, 3, 3), (3, 11, 3), (3, 3, 0), (3, 3), (3, 3, 3, 3)):
        with pytest.raises(IsochorError, match="2 to 10"):
            latticerules.edit_lattice(doc.base(), bad)
    edit = latticerules.edit_lattice(doc.base(), (10, 2, 10))
    assert edit.state.lattice.shape == (10, 2, 10)


def test_edit_lattice_keeps_the_outside_option_where_the_basis_has_it(doc):
    commit(doc, latticerules.edit_lattice(doc.base(), (4, 4, 4), "bspline", True))
    assert doc.state.lattice.outside
    kept = latticerules.edit_lattice(doc.base(), (5, 4, 4))  # None keeps it
    assert kept.state.lattice.outside and "outside" in kept.text
    with pytest.raises(IsochorError, match="Outside option needs a local basis"):
        latticerules.edit_lattice(doc.base(), (4, 4, 4), "bernstein", True)
    dropped = latticerules.edit_lattice(doc.base(), (4, 4, 4), "bernstein")  # Bernstein has none
    assert not dropped.state.lattice.outside
    assert dropped.state.lattice.basis == ("bernstein",) * 3


def test_edit_lattice_reuses_a_problem_built_before(doc):
    first = latticerules.edit_lattice(doc.base(), (4, 3, 3))
    commit(doc, first)
    second = latticerules.edit_lattice(doc.base(), (3, 4, 3))
    commit(doc, second)
    again = latticerules.edit_lattice(doc.base(), (4, 3, 3))
    assert again.state.problem is first.state.problem
    assert again.state is not first.state
    assert not again.state.moved.any()
    np.testing.assert_allclose(again.state.nodes, again.state.lattice.rest_nodes)


def test_edit_lattice_back_to_the_original_shape_is_at_rest(doc):
    commit(doc, latticerules.edit_lattice(doc.base(), (4, 3, 3)))
    back = latticerules.edit_lattice(doc.base(), (3, 3, 3))
    st = back.state
    assert st.lattice.shape == (3, 3, 3)
    assert not st.moved.any() and not st.pinned.any()
    np.testing.assert_allclose(st.nodes, st.lattice.rest_nodes)


# -- results belong to the state they solved ---------------------------------------------------
def test_every_edit_is_unsolved_without_a_result(doc):
    doc.record_result(doc.cell, None, summary())
    assert doc.state.solved and doc.state.result is not None
    doc.selection.select(free_rows(doc)[:2])
    edits = [
        noderules.edit_position(doc.base(), 0, 0.3),
        noderules.edit_pins(doc.base(), None, True),
        noderules.edit_toggle_pin(doc.base()),
        goalrules.edit_target(doc.base(), 95),
    ]
    doc.begin_drag().move([0.1, 0.0, 0.0])
    edits.append(doc.end_drag())
    for edit in edits:
        assert_fresh(edit)
        assert edit.state.problem is doc.problem


def test_record_result_on_the_current_cell(doc):
    events = events_of(doc)
    doc.show_live(doc.state.nodes + 0.1)
    solved = doc.state.nodes + 0.05
    s = summary()
    doc.record_result(doc.cell, solved, s)
    assert events == ["state"]
    assert doc.state.solved and doc.state.result is s
    np.testing.assert_allclose(doc.state.nodes, solved)
    assert not doc.state.nodes.flags.writeable
    assert doc.live_nodes is None
    assert not doc.needs_solve()


def test_record_result_on_a_cell_that_is_not_current(doc):
    old = doc.cell
    old_nodes = old.state.nodes
    commit(doc, goalrules.edit_target(doc.base(), 90))
    current = doc.state
    events = events_of(doc)
    doc.show_live(current.nodes)
    doc.record_result(old, None, summary(levels=(6,)))
    assert events == []
    assert doc.state is current and doc.live_nodes is not None
    assert old.state.solved and old.state.result.levels == (6,)
    np.testing.assert_array_equal(old.state.nodes, old_nodes)  # None keeps the nodes
    # Undo lands on the solved state.
    doc.set_cell(old)
    assert doc.state.solved and not doc.needs_solve()


def test_solve_summary_span_words():
    assert summary(levels=(4,), n_levels=7).span() == "Solved level 5 of 7"
    assert summary(levels=(3, 4), n_levels=7).span() == "Solved levels 4–5 of 7"
    assert summary(levels=(0, 1, 2), n_levels=3).span() == "Solved levels 1–3 of 3"
    failed = SolveSummary.failed("boom")
    assert failed.converged is False and failed.message == "boom" and failed.levels == ()
    assert failed.span() == "Solved no level"


def test_solve_summary_of_a_real_solve(doc, torus_result):
    r = torus_result
    n = len(doc.surface.levels)
    s = SolveSummary.of(r, n)
    assert s.converged is True and r.converged
    assert s.levels == tuple(st.level for st in r.levels) and len(s.levels) >= 1
    assert s.n_levels == n == 7
    assert s.free_nodes == 9
    assert s.rel_volume_error == pytest.approx(r.rel_volume_error)
    assert abs(s.rel_volume_error) <= doc.problem.options.tol_volume
    assert s.sigma == pytest.approx(r.sigma) and s.lam == pytest.approx(r.lam)
    assert s.elapsed == pytest.approx(r.elapsed)
    first, last = s.levels[0] + 1, s.levels[-1] + 1
    words = f"level {first}" if first == last else f"levels {first}–{last}"
    assert s.span() == f"Solved {words} of 7"
    doc.record_result(doc.cell, r.nodes, s)
    assert doc.state.converged
    np.testing.assert_allclose(doc.state.nodes, r.nodes)
    chip, tone, text = describe_status(doc.state, preserve=True, activity="idle")
    assert (chip, tone) == ("Converged", "good")
    assert text == (
        f"Converged: |dV|/V0 = {abs(r.rel_volume_error):.1e} on the full mesh, 9 free nodes."
    )


def test_an_edit_after_a_converged_solve_shows_no_old_result(doc, torus_result):
    doc.record_result(doc.cell, torus_result.nodes, SolveSummary.of(torus_result, 7))
    assert describe_status(doc.state, preserve=True, activity="idle")[0] == "Converged"
    row = free_rows(doc)[:1]
    doc.selection.select(row)
    commit(doc, noderules.edit_position(doc.base(), 2, 0.2))
    assert doc.state.result is None
    assert describe_status(doc.state, preserve=True, activity="idle") == (
        "Edited",
        "neutral",
        "Not solved yet.",
    )
    # The edit starts from the solved nodes.
    others = np.setdiff1d(np.arange(27), row)
    np.testing.assert_allclose(doc.state.nodes[others], np.asarray(torus_result.nodes)[others])
    assert doc.state.nodes[row[0], 2] == pytest.approx(0.2)


# -- set_cell --------------------------------------------------------------------------------
def test_set_cell_with_a_new_lattice_clears_the_selection(doc):
    doc.selection.select([1, 2, 26])
    events = events_of(doc)
    doc.show_live(doc.state.nodes)
    doc.begin_drag()
    commit(doc, latticerules.edit_lattice(doc.base(), (2, 2, 2)))
    assert events == ["scene", "state"]
    assert doc.selection.rows.tolist() == []
    assert doc.drag is None and doc.live_nodes is None


def test_set_cell_with_the_same_lattice_keeps_the_selection(doc):
    doc.selection.select([1, 2, 26])
    events = events_of(doc)
    doc.show_live(doc.state.nodes)
    doc.begin_drag()
    cell = commit(doc, goalrules.edit_target(doc.base(), 90))
    assert events == ["state"]
    assert doc.cell is cell
    assert doc.selection.rows.tolist() == [1, 2, 26]
    assert doc.drag is None and doc.live_nodes is None


# -- the drag session ------------------------------------------------------------------------
def test_begin_drag_needs_a_selection(doc):
    assert doc.begin_drag() is None
    assert doc.drag is None
    assert doc.end_drag() is None


def test_drag_moves_only_the_dragged_nodes(doc):
    rows = free_rows(doc)[:2]
    doc.selection.select(rows)
    base = doc.base_nodes()
    drag = doc.begin_drag()
    assert doc.drag is drag and drag.before is doc.cell
    assert drag.rows.tolist() == rows.tolist()
    assert drag.text == "Move 2 nodes"
    np.testing.assert_allclose(drag.base, base)
    delta = np.array([0.1, -0.2, 0.05])
    nodes = drag.move(delta)
    np.testing.assert_allclose(nodes[rows], base[rows] + delta)
    others = np.setdiff1d(np.arange(27), rows)
    np.testing.assert_array_equal(nodes[others], base[others])
    np.testing.assert_array_equal(drag.nodes, nodes)
    # Deltas are from the start, not cumulative.
    nodes = drag.move(2 * delta)
    np.testing.assert_allclose(nodes[rows], base[rows] + 2 * delta)
    # With ``free``: the other nodes from the live preview.
    free = base + 0.3
    nodes = drag.move(delta, free)
    np.testing.assert_allclose(nodes[rows], base[rows] + delta)
    np.testing.assert_allclose(nodes[others], free[others])
    out = drag.with_dragged(base - 1.0)
    np.testing.assert_allclose(out[rows], base[rows] + delta)
    np.testing.assert_allclose(out[others], base[others] - 1.0)


def test_drag_fixed_includes_the_dragged_rows(doc):
    rows = free_rows(doc)[:2]
    doc.selection.select(rows)
    drag = doc.begin_drag()
    fixed = drag.fixed()
    assert fixed.shape == (27, 3), "per coordinate"
    expect = doc.state.fixed_axes.copy()
    expect[rows] = True
    np.testing.assert_array_equal(fixed, expect)
    assert not doc.state.fixed[rows].any()  # the state is untouched


def test_end_drag_returns_the_move(doc):
    rows = free_rows(doc)[:2]
    doc.selection.select(rows)
    before = doc.cell
    drag = doc.begin_drag()
    drag.move([0.0, 0.0, 0.25])
    edit = doc.end_drag()
    assert doc.drag is None and doc.cell is before
    assert_fresh(edit)
    assert edit.text == "Move 2 nodes"
    np.testing.assert_allclose(edit.state.nodes, drag.nodes)
    assert edit.state.moved[rows].all()
    np.testing.assert_array_equal(edit.state.pinned, before.state.pinned)
    assert doc.end_drag() is None


def test_end_drag_takes_the_free_nodes_from_the_live_solve(doc):
    rows = free_rows(doc)[:1]
    doc.selection.select(rows)
    start_live = doc.state.nodes + 0.01
    doc.show_live(start_live)
    drag = doc.begin_drag()
    np.testing.assert_allclose(drag.base, start_live)  # starts from what is on screen
    delta = np.array([0.2, 0.0, 0.0])
    drag.move(delta, doc.live_nodes)
    newer = doc.state.nodes + 0.02  # the preview solve went on
    doc.show_live(newer)
    edit = doc.end_drag()
    others = np.setdiff1d(np.arange(27), rows)
    np.testing.assert_allclose(edit.state.nodes[others], newer[others])
    np.testing.assert_allclose(edit.state.nodes[rows], start_live[rows] + delta)
    assert edit.state.moved[rows].all()


def test_drag_with_preserve_off_is_plain_ffd(doc):
    doc.set_preserve(False)
    rows = free_rows(doc)[:1]
    doc.selection.select(rows)
    doc.show_live(doc.state.nodes + 0.5)  # ignored without the volume constraint
    st = doc.state
    plain = np.where(st.fixed[:, None], st.nodes, st.lattice.rest_nodes)
    drag = doc.begin_drag()
    np.testing.assert_allclose(drag.base, plain)
    drag.move([0.0, 0.1, 0.0])
    edit = doc.end_drag()
    others = np.setdiff1d(np.arange(27), rows)
    np.testing.assert_allclose(edit.state.nodes[others], plain[others])
    np.testing.assert_allclose(edit.state.nodes[rows], plain[rows] + [0.0, 0.1, 0.0])


def test_cancel_drag(doc):
    doc.selection.select([4])
    before = doc.cell
    doc.begin_drag().move([1.0, 1.0, 1.0])
    doc.cancel_drag()
    assert doc.drag is None and doc.cell is before
    assert doc.end_drag() is None
    assert not doc.state.moved[4]


# -- views of the state ----------------------------------------------------------------------
def test_view_and_base_nodes(doc):
    st = doc.state
    solved = st.nodes + 0.1
    doc.record_result(doc.cell, solved, summary())
    np.testing.assert_allclose(doc.view_nodes(), solved)
    np.testing.assert_allclose(doc.base_nodes(), solved)
    live = solved + 0.1
    doc.show_live(live)
    np.testing.assert_allclose(doc.base_nodes(), live)
    base = doc.base_nodes()
    base[:] = 0  # a copy
    np.testing.assert_allclose(doc.live_nodes, live)
    doc.set_preserve(False)
    plain = np.where(st.fixed[:, None], solved, st.lattice.rest_nodes)
    np.testing.assert_allclose(doc.view_nodes(), plain)
    np.testing.assert_allclose(doc.base_nodes(), plain)
    assert not doc.needs_solve()
    # view_nodes of another state
    np.testing.assert_allclose(
        doc.view_nodes(st), np.where(st.fixed[:, None], st.nodes, st.lattice.rest_nodes)
    )


# -- describe_status -------------------------------------------------------------------------
def test_describe_status_for_each_activity(doc, rest):
    edited = doc.state
    at_rest = rest.state
    conv = replace(edited, solved=True, result=summary(free_nodes=1))
    bad = replace(edited, solved=True, result=summary(converged=False, message="no"))
    bad_silent = replace(edited, solved=True, result=summary(converged=False))
    failed = replace(edited, solved=True, result=SolveSummary.failed("Lattice folded."))

    for st in (edited, at_rest, conv, bad):
        assert describe_status(st, preserve=False, activity="solving") == (
            "Plain FFD",
            "neutral",
            "Volume constraint off: plain free-form deformation.",
        )
        assert describe_status(st, preserve=True, activity="dragging") == (
            "Dragging",
            "busy",
            "Release to solve.",
        )
        assert describe_status(st, preserve=True, activity="solving") == (
            "Solving…",
            "busy",
            "Solving…",
        )

    assert describe_status(edited, preserve=True, activity="idle") == (
        "Edited",
        "neutral",
        "Not solved yet.",
    )
    assert describe_status(at_rest, preserve=True, activity="idle") == (
        "At rest",
        "good",
        "At rest: nothing to solve.",
    )
    assert describe_status(conv, preserve=True, activity="idle") == (
        "Converged",
        "good",
        "Converged: |dV|/V0 = 1.2e-05 on the full mesh, 1 free node.",
    )
    assert describe_status(bad, preserve=True, activity="idle") == ("Not converged", "bad", "no")
    assert describe_status(bad_silent, preserve=True, activity="idle") == (
        "Not converged",
        "bad",
        "The solve did not converge.",
    )
    assert describe_status(edited, preserve=True, activity="stopped") == (
        "Stopped",
        "neutral",
        "Stopped before converging: Solve again to finish.",
    )
    # Stopped after the state was solved: the solved state speaks.
    assert describe_status(conv, preserve=True, activity="stopped")[0] == "Converged"
    assert describe_status(failed, preserve=True, activity="failed") == (
        "Solver failed",
        "bad",
        "Lattice folded.",
    )
    assert describe_status(failed, preserve=True, activity="idle") == (
        "Not converged",
        "bad",
        "Lattice folded.",
    )
    assert describe_status(edited, preserve=True, activity="failed") == (
        "Solver failed",
        "bad",
        "The solve did not converge.",
    )


# -- files -----------------------------------------------------------------------------------
def edited_torus(doc: Document) -> Document:
    """The torus with a typed move, a pin on a free node, a pin on a moved node, target 95 %."""
    free = free_rows(doc)
    doc.selection.select(free[:1])
    commit(doc, noderules.edit_position(doc.base(), 0, 0.5))
    commit(
        doc, noderules.edit_pins(doc.base(), [free[1], 0], True)
    )  # node 0 is moved (and now pinned too)
    commit(doc, goalrules.edit_target(doc.base(), 95))
    return doc


def test_scenario_of_the_current_state(doc):
    edited_torus(doc)
    st = doc.state
    lat = st.lattice
    sc = doc.scenario()
    moved = np.flatnonzero(st.moved)
    assert [m.node for m in sc.moves] == [lat.ijk(r) for r in moved]
    for mv, r in zip(sc.moves, moved):
        assert mv.by is None and mv.to == tuple(float(x) for x in st.nodes[r])
        assert all(type(x) is float for x in mv.to)
    free = np.flatnonzero(~doc.problem.fixed.any(axis=1))  # the example's free nodes
    assert sc.pins == (lat.ijk(int(free[1])),)  # not node 0: it is moved
    assert st.pinned[0]
    assert sc.goal.target_ratio == pytest.approx(0.95)
    assert sc.model == {"builtin": "torus"}
    assert sc.lattice_nodes == (3, 3, 3)
    assert sc.tol_volume == doc.problem.scenario.tol_volume


def test_save_and_read_round_trip(doc, tmp_path):
    edited_torus(doc)
    path = tmp_path / "squash.json"
    doc.save(path)
    assert doc.path == Path(os.path.abspath(path)) and doc.title == "squash.json"
    sc = Scenario.read(path)
    mine = doc.scenario()
    assert sc.moves == mine.moves and sc.pins == mine.pins
    assert sc.goal.target_ratio == mine.goal.target_ratio
    assert sc.lattice_nodes == mine.lattice_nodes and sc.padding == mine.padding
    # Opened again, it is the same edit.
    again = Document.open(path)
    assert again.path == Path(os.path.abspath(path)) and again.title == "squash.json"
    st, new = doc.state, again.state
    np.testing.assert_allclose(new.nodes, st.nodes, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(new.moved, st.moved)
    np.testing.assert_array_equal(new.pinned & ~new.moved, st.pinned & ~st.moved)
    assert new.goal.target_ratio == st.goal.target_ratio
    assert new.solved is False


def test_open_a_scenario_as_a_template(tmp_path):
    path = tmp_path / "t.json"
    example_scenario("torus-compression").write(path)
    d = Document.open(path, template=True)
    assert d.path is None and d.title == "t.json"
    assert d.state.moved.sum() == 18
    d2 = Document.open(str(path))
    assert d2.path == Path(os.path.abspath(path))


def test_open_rejects_unknown_files(tmp_path):
    with pytest.raises(IsochorError) as exc:
        Document.open(tmp_path / "notes.txt")
    msg = str(exc.value)
    assert "notes.txt" in msg and ".txt" in msg
    assert "OBJ, PLY, STL, OFF" in msg and "JSON" in msg
    with pytest.raises(IsochorError, match=r"\(none\)"):
        Document.open(tmp_path / "README")
    with pytest.raises(IsochorError, match="no such file"):
        Document.open(tmp_path / "missing.obj")
    with pytest.raises(IsochorError, match="no such scenario file"):
        Document.open(tmp_path / "missing.json")


def test_open_a_scenario_whose_model_is_missing(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"model": {"path": "gone.obj"}}), encoding="utf-8")
    with pytest.raises(IsochorError, match="gone.obj"):
        Document.open(path)


def sphere_mesh(scale=(1.0, 1.0, 1.0)) -> TriMesh:
    m = sphere_levels(3)[-1]
    return TriMesh(m.vertices * np.asarray(scale), m.faces)


@pytest.mark.parametrize(
    ("scale", "shape"),
    [((2.0, 1.0, 1.0), (4, 3, 3)), ((1.0, 1.0, 2.0), (3, 3, 4)), ((1.0, 1.6, 1.0), (3, 4, 3))],
)
def test_open_a_model_in_a_default_lattice(tmp_path, scale, shape):
    mesh = sphere_mesh(scale)
    assert default_lattice_shape(mesh) == shape
    path = tmp_path / "model.obj"
    save_mesh(path, mesh)
    d = Document.open(path)
    assert d.state.lattice.shape == shape
    assert d.title == "model.obj" and d.path is None
    assert d.state.solved and not d.state.fixed.any()
    sc = d.scenario()
    assert Path(sc.model["path"]).is_absolute()
    assert sc.model["path"] == os.path.abspath(path)
    np.testing.assert_allclose(d.deformed_mesh().vertices, d.surface.full.vertices, atol=1e-9)


def test_export_never_replaces_the_model_it_was_made_from(tmp_path):
    path = tmp_path / "model.obj"
    save_mesh(path, sphere_mesh((2.0, 1.0, 1.0)))
    before = path.read_bytes()
    os.symlink(path, tmp_path / "link.obj")
    d = Document.open(path)
    d.selection.select([0])
    commit(d, noderules.edit_position(d.base(), 0, -3.0))
    for target in (path, tmp_path / "link.obj", tmp_path / "." / "model.obj"):
        with pytest.raises(IsochorError, match="would overwrite the model"):
            d.export(target)
    assert path.read_bytes() == before
    d.export(tmp_path / "deformed.obj")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["deformed.obj", "link.obj", "model.obj"]


def test_model_paths_keep_symbolic_links(tmp_path):
    real = tmp_path / "real_folder"
    real.mkdir()
    link = tmp_path / "linked"
    os.symlink(real, link, target_is_directory=True)
    save_mesh(real / "model.obj", sphere_mesh((2.0, 1.0, 1.0)))

    d = Document.open(link / "model.obj")
    model = d.scenario().model["path"]
    assert Path(model).is_absolute()
    assert model == os.path.abspath(link / "model.obj")
    assert "real_folder" not in model

    d.selection.select([0])
    commit(d, noderules.edit_position(d.base(), 0, -3.0))
    d.save(link / "scene.json")
    assert d.path == Path(os.path.abspath(link / "scene.json"))
    saved = json.loads((real / "scene.json").read_text(encoding="utf-8"))
    assert saved["model"]["path"] == "model.obj"
    assert "real_folder" not in (link / "scene.json").read_text(encoding="utf-8")

    # Saved elsewhere: relative to the folder as the user sees it, through the link.
    other = tmp_path / "other"
    other.mkdir()
    d.save(other / "scene.json")
    saved = json.loads((other / "scene.json").read_text(encoding="utf-8"))
    assert saved["model"]["path"] == os.path.join("..", "linked", "model.obj")

    # The real folder is renamed and the link follows it: the scenario still opens.
    moved = tmp_path / "renamed_folder"
    real.rename(moved)
    link.unlink()
    os.symlink(moved, link, target_is_directory=True)
    again = Document.open(link / "scene.json")
    assert again.scenario().model_path() == Path(os.path.abspath(link / "model.obj"))
    assert again.state.moved[0]
    np.testing.assert_allclose(again.state.nodes[0], d.state.nodes[0])
    assert Document.open(other / "scene.json").state.moved[0]


def test_export_writes_the_deformed_mesh(rest, tmp_path):
    path = tmp_path / "out.obj"
    rest.export(path)
    loaded = load_mesh(path).mesh
    assert loaded.n_faces == rest.surface.full.n_faces
    np.testing.assert_allclose(
        np.sort(loaded.vertices, axis=0), np.sort(rest.surface.full.vertices, axis=0), atol=1e-9
    )
    nodes = rest.state.nodes * 2.0 - rest.surface.center  # scaled about the centre
    mesh = rest.deformed_mesh(nodes)
    np.testing.assert_allclose(
        mesh.vertices, rest.surface.full.vertices * 2.0 - rest.surface.center, atol=1e-9
    )


# -- no Qt -----------------------------------------------------------------------------------
def test_the_document_runs_without_qt():
    """A whole edit session in a fresh interpreter imports neither Qt nor VTK."""
    code = (
        "from isochor.app.editor import goalrules, handlerules, latticerules, noderules\n"
        "from isochor.app.editor import selection, timelinerules\n"
        "from isochor.app.editor.document import Document, StateCell, describe_status\n"
        "from isochor.core.scenario.document import Scenario\n"
        "from isochor.core.scenario.problem import build\n"
        f"d = Document(build(Scenario.from_dict({SPHERE!r})))\n"
        "d.selection.select([0, 1])\n"
        "d.set_cell(StateCell(noderules.edit_position(d.base(), 0, -2.0).state))\n"
        "d.begin_drag().move([0.1, 0, 0])\n"
        "d.set_cell(StateCell(d.end_drag().state))\n"
        "print(describe_status(d.state, preserve=True, activity='idle')[0])\n"
    )
    out, gui = run_fresh(code, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[0] == "Edited"
    assert gui == [], f"imported: {gui}"


# -- the goal's settings, pins on some axes, what is held (issue 11) --------------------------
GOAL_SPHERE = {
    **SPHERE,
    "version": 2,
    "pins": [[0, 0, 0], {"node": [1, 1, 2], "axes": "z"}, {"node": [2, 0, 1], "axes": "xy"}],
    "preserve": "per-body",
    "keep_centroid": True,
    "anchor": "none",
    "fold_guard": False,
}


def test_initial_state_reads_axis_pins_and_the_goal():
    prob = build(Scenario.from_dict(GOAL_SPHERE))
    st = initial_state(prob)
    lat = st.lattice
    z_only, xy, full = lat.index(1, 1, 2), lat.index(2, 0, 1), lat.index(0, 0, 0)
    assert st.pin_axes.shape == (27, 3)
    assert st.pin_axes[z_only].tolist() == [False, False, True]
    assert st.pin_axes[xy].tolist() == [True, True, False]
    assert st.pin_axes[full].all()
    assert np.flatnonzero(st.pinned).tolist() == sorted([full, z_only, xy])
    assert np.flatnonzero(st.axis_pinned).tolist() == sorted([z_only, xy])
    np.testing.assert_array_equal(st.fixed_axes, prob.fixed)  # what the core would hold
    assert settings(st.goal) == {
        "preserve": "per-body",
        "keep_centroid": True,
        "anchor": "none",
        "fold_guard": False,
        "symmetry": "none",
    }
    assert st.goal == prob.scenario.goal
    for a in (st.pin_axes, st.pinned, st.axis_pinned, st.fixed, st.fixed_axes):
        assert not a.flags.writeable


def test_a_plain_state_has_the_default_goal(doc):
    st = doc.state
    assert st.goal.anchor == "far-side" and st.goal.fold_guard and not st.goal.keep_centroid
    assert st.goal.preserve == "total" and st.goal.target_ratio == 1.0
    assert st.pin_axes.shape == (27, 3) and not st.pin_axes.any()
    np.testing.assert_array_equal(st.fixed_axes, np.repeat(st.moved[:, None], 3, axis=1))


@pytest.mark.parametrize(
    ("rule", "value", "setting", "new", "words"),
    [
        ("edit_anchor", False, "anchor", "none", "Hold far side off"),
        ("edit_keep_centroid", True, "keep_centroid", True, "Keep centre of mass"),
        ("edit_preserve", "per-body", "preserve", "per-body", "Preserve each body"),
        ("edit_fold_guard", False, "fold_guard", False, "Fold guard off"),
    ],
)
def test_each_goal_setting_is_an_undoable_edit_with_words(doc, rule, value, setting, new, words):
    before = doc.cell
    old = getattr(doc.state.goal, setting)
    edit = getattr(goalrules, rule)(doc.base(), value)
    assert_fresh(edit)
    assert edit.text == words
    assert getattr(edit.state.goal, setting) == new
    np.testing.assert_array_equal(edit.state.nodes, doc.base_nodes())
    assert not edit.state.same_edit(doc.state), "a setting makes another edit"
    after = commit(doc, edit)
    assert doc.needs_solve()
    assert getattr(goalrules, rule)(doc.base(), value) is None, (
        "the same value again: nothing to do"
    )
    doc.set_cell(before)  # undo
    assert getattr(doc.state.goal, setting) == old
    doc.set_cell(after)  # redo
    assert getattr(doc.state.goal, setting) == new
    back = {"edit_anchor": True, "edit_preserve": "total"}.get(rule, not value)
    assert getattr(goalrules, rule)(doc.base(), back).text != words  # the words of the way back


def test_goal_settings_refuse_unknown_values(doc):
    with pytest.raises(IsochorError, match="preserve"):
        goalrules.edit_preserve(doc.base(), "each")
    with pytest.raises(IsochorError, match="anchor"):
        goalrules.edit_setting(doc.base(), "anchor", "middle")
    with pytest.raises(ValueError, match="unknown goal setting"):
        goalrules.edit_setting(doc.base(), "target_ratio", 0.5)


def test_edit_target_beyond_the_reachable_range_says_so(rest):
    with pytest.raises(IsochorError, match=r"0\.05\.\.20"):
        goalrules.edit_target(rest.base(), 2)
    with pytest.raises(IsochorError, match=r"0\.05\.\.20"):
        goalrules.edit_target(rest.base(), 2500)
    assert goalrules.edit_target(rest.base(), 5).state.goal.target_ratio == pytest.approx(0.05)


def test_edit_pin_axes_pins_some_axes_only(doc):
    r = int(free_rows(doc)[0])
    edit = goalrules.edit_pin_axes(doc.base(), [r], "z")
    assert_fresh(edit)
    assert edit.text == "Pin 1 node on z"
    st = edit.state
    assert st.pin_axes[r].tolist() == [False, False, True]
    assert st.pinned[r] and st.axis_pinned[r] and st.fixed[r] and not st.moved[r]
    assert st.fixed_axes[r].tolist() == [False, False, True]
    commit(doc, edit)
    assert goalrules.edit_pin_axes(doc.base(), [r], "z") is None
    assert goalrules.edit_pin_axes(doc.base(), [r], "yx").text == "Pin 1 node on x and y"
    assert goalrules.edit_pin_axes(doc.base(), [r], "xyz").text == "Pin 1 node"
    unpin = goalrules.edit_pin_axes(doc.base(), [r], "")
    assert unpin.text == "Unpin 1 node" and not unpin.state.fixed[r]
    assert goalrules.edit_pin_axes(doc.base(), [], "z") is None
    with pytest.raises(ValueError, match="xyz"):
        goalrules.edit_pin_axes(doc.base(), [r], "w")
    # P pins every axis of a node pinned on some, and unpins it when all are fixed
    doc.selection.select([r])
    assert noderules.edit_pins(doc.base(), [r], True).state.pin_axes[r].all()
    assert noderules.edit_toggle_pin(doc.base()).text == "Unpin 1 node"


def test_pinning_a_moved_node_on_some_axes_frees_the_others(doc):
    moved = int(np.flatnonzero(doc.state.moved)[0])
    edit = goalrules.edit_pin_axes(doc.base(), [moved], "z")
    assert edit.text == "Pin 1 node on z"
    assert not edit.state.moved[moved] and edit.state.axis_pinned[moved]
    np.testing.assert_array_equal(edit.state.nodes[moved], doc.state.nodes[moved])
    assert goalrules.edit_pin_axes(doc.base(), [moved], "xyz") is None, (
        "a moved node is fixed on every axis"
    )


def test_edit_pin_axis_turns_one_axis_of_the_selection(doc):
    a, b = (int(r) for r in free_rows(doc)[:2])
    commit(doc, goalrules.edit_pin_axes(doc.base(), [a], "x"))
    edit = goalrules.edit_pin_axis(doc.base(), [a, b], 2, True)
    assert edit.text == "Pin 2 nodes on z"
    assert edit.state.pin_axes[a].tolist() == [True, False, True]
    assert edit.state.pin_axes[b].tolist() == [False, False, True]
    commit(doc, edit)
    assert goalrules.edit_pin_axis(doc.base(), [a, b], 2, True) is None
    free = goalrules.edit_pin_axis(doc.base(), [a], 0, False)
    assert free.text == "Free 1 node on x" and free.state.pin_axes[a].tolist() == [0, 0, 1]
    assert goalrules.edit_pin_axis(doc.base(), [b], 1, False) is None, (
        "not pinned on y: nothing to free"
    )
    moved = int(np.flatnonzero(doc.state.moved)[0])
    edit = goalrules.edit_pin_axis(doc.base(), [moved], 1, False)
    assert edit.text == "Free 1 node on y" and not edit.state.moved[moved]
    assert edit.state.pin_axes[moved].tolist() == [True, False, True]


def test_drag_and_plain_ffd_hold_pinned_coordinates_only(doc):
    r = int(free_rows(doc)[0])
    commit(doc, goalrules.edit_pin_axes(doc.base(), [r], "z"))
    other = int(free_rows(doc)[0])
    doc.selection.select([other])
    fixed = doc.begin_drag().fixed()
    assert fixed[r].tolist() == [False, False, True] and fixed[other].all()
    doc.cancel_drag()
    solved = doc.state.nodes + 0.1
    doc.record_result(doc.cell, solved, summary())
    doc.set_preserve(False)
    rest = doc.state.lattice.rest_nodes
    view = doc.view_nodes()
    np.testing.assert_allclose(view[r], [rest[r, 0], rest[r, 1], solved[r, 2]])


def test_held_is_the_far_face_of_a_move_on_a_fresh_lattice(rest):
    lat = rest.state.lattice
    assert rest.held()[1] == "", "nothing moved: nothing held"
    corner = lat.index(2, 2, 2)
    rest.selection.select([corner])
    commit(rest, noderules.edit_position(rest.base(), 0, float(rest.state.nodes[corner, 0]) + 0.3))
    mask, face = rest.held()
    assert face == "x min" and mask.sum() == 9
    assert all(lat.ijk(r)[0] == 0 for r in np.flatnonzero(mask))
    # what a drag would hold, before it is solved
    rest.selection.select([lat.index(0, 0, 0)])
    drag = rest.begin_drag()
    drag.move([0.0, 0.0, -0.2])
    assert rest.held()[1] == "", "two moved corners: no face is free of them"
    rest.cancel_drag()
    # no anchor, or no volume constraint: nothing held
    commit(rest, goalrules.edit_anchor(rest.base(), False))
    assert rest.held()[1] == "" and not rest.held()[0].any()
    rest.set_cell(StateCell(goalrules.edit_anchor(rest.base(), True).state))
    rest.set_preserve(False)
    assert rest.held()[1] == ""


def test_a_solve_summary_keeps_what_the_window_shows(rest):
    """Held rows and face, folds, bodies and the centroid of a real solve; held() of a
    solved state is what its solve held."""
    lat = rest.state.lattice
    corner = lat.index(2, 2, 2)
    rest.selection.select([corner])
    commit(rest, goalrules.edit_keep_centroid(rest.base(), True))
    commit(rest, noderules.edit_position(rest.base(), 0, float(rest.state.nodes[corner, 0]) + 0.3))
    st = rest.state
    result = run_to_end(
        solve(st.surface, st.nodes, st.fixed_axes, goal=st.goal, options=st.problem.options)
    )
    s = SolveSummary.of(result, len(st.surface.levels))
    assert s.held == tuple(result.held) and len(s.held) == 9 and s.held_face == "x min"
    assert s.folds is result.folds and not s.folded and s.folded_vertices is None
    assert s.centroid_shift == result.centroid_shift and s.centroid_shift is not None
    assert s.bodies == ()  # one body
    rest.record_result(rest.cell, result.nodes, s)
    mask, face = rest.held()
    assert face == "x min" and np.flatnonzero(mask).tolist() == list(s.held)
    assert s == replace(s, folds=None), "summaries compare without their folds"


def test_a_folded_result_says_so(doc):
    from isochor.core.goal.folds import Folds

    mask = np.zeros(10, bool)
    mask[:3] = True
    folds = Folds(0.032, 0.3, 0.01, -0.5, mask)
    r = summary(converged=False, message="the result is folded", folds=folds)
    st = replace(doc.state, solved=True, result=r)
    assert r.folded and r.folded_vertices.tolist() == mask.tolist()
    assert describe_status(st, preserve=True, activity="idle") == (
        "Folded",
        "bad",
        "Folded: 3.2% of the model is inside out — undo, pin fewer nodes or move less.",
    )
    assert describe_status(st, preserve=True, activity="dragging")[0] == "Dragging"
    assert describe_status(st, preserve=False, activity="idle")[0] == "Plain FFD"
    flat = Folds(0.0, 0.0, 0.0, 0.5, np.zeros(10, bool))
    ok = replace(st, result=summary(folds=flat))
    assert not ok.result.folded and describe_status(ok, preserve=True, activity="idle")[0] == (
        "Converged"
    )


def test_the_sentences_of_the_goal():
    from isochor.app.editor.state import (
        bodies_sentence,
        centroid_sentence,
        fold_sentence,
        held_sentence,
        percent,
    )
    from isochor.core.solve.records import BodyVolume

    assert held_sentence(9, "x max") == (
        "Holding the x max face (9 nodes) so the model does not drift — untick Hold far "
        "side to let it move."
    )
    assert held_sentence(0, "") == "" and held_sentence(9, "") == ""
    assert [percent(f) for f in (0.032, 0.511, 1.0, 0.00181)] == ["3.2%", "51%", "100%", "0.18%"]
    assert fold_sentence(0.511).startswith("Folded: 51% of the model is inside out")
    two = (BodyVolume(2.0, 2.0, 2.0), BodyVolume(1.0, 1.0, 0.97))
    assert bodies_sentence(two) == "Volume of each body: body 1 100.00 % · body 2 97.00 %"
    assert bodies_sentence(two[:1]) == ""
    assert centroid_sentence(None) == ""
    assert centroid_sentence(0.0123) == "Centre of mass moved 1.230 % of the model's size."
    assert centroid_sentence(1e-9) == (
        "Centre of mass moved less than 0.001 % of the model's size."
    )


def test_reset_and_rebuild_keep_the_goal_and_drop_axis_pins(doc):
    commit(doc, goalrules.edit_anchor(doc.base(), False))
    commit(doc, goalrules.edit_pin_axes(doc.base(), free_rows(doc)[:1], "z"))
    reset = noderules.edit_reset(doc.base()).state
    assert not reset.pin_axes.any() and reset.goal.anchor == "none"
    rebuilt = latticerules.edit_lattice(doc.base(), (4, 3, 3)).state
    assert not rebuilt.pin_axes.any() and rebuilt.goal.anchor == "none"
    assert rebuilt.problem.scenario.axis_pins == ()


def test_save_writes_version_2_with_axis_pins_and_the_goal(doc, tmp_path):
    z_only, xy = (int(r) for r in free_rows(doc)[:2])
    commit(doc, goalrules.edit_pin_axes(doc.base(), [z_only], "z"))
    commit(doc, goalrules.edit_pin_axes(doc.base(), [xy], "xy"))
    commit(doc, noderules.edit_pins(doc.base(), free_rows(doc)[:1], True))
    commit(doc, goalrules.edit_anchor(doc.base(), False))
    commit(doc, goalrules.edit_keep_centroid(doc.base(), True))
    commit(doc, goalrules.edit_fold_guard(doc.base(), False))
    commit(doc, goalrules.edit_preserve(doc.base(), "per-body"))
    lat = doc.state.lattice
    sc = doc.scenario()
    assert sc.version == 2
    assert sc.axis_pins == ((lat.ijk(z_only), "z"), (lat.ijk(xy), "xy"))
    assert len(sc.pins) == 1
    path = tmp_path / "goal.json"
    doc.save(path)
    raw = json.loads(path.read_text())
    assert raw["version"] == 2
    assert {"node": list(lat.ijk(z_only)), "axes": "z"} in raw["pins"]
    assert (raw["preserve"], raw["keep_centroid"], raw["anchor"], raw["fold_guard"]) == (
        "per-body",
        True,
        "none",
        False,
    )
    again = Document.open(path).state
    st = doc.state
    np.testing.assert_array_equal(
        again.pin_axes & ~again.moved[:, None], st.pin_axes & ~st.moved[:, None]
    )
    np.testing.assert_array_equal(again.moved, st.moved)
    assert again.goal == st.goal


def test_save_without_the_new_settings_writes_version_1_and_version_1_opens(doc, tmp_path):
    path = tmp_path / "plain.json"
    commit(doc, noderules.edit_pins(doc.base(), free_rows(doc)[:1], True))
    doc.save(path)
    raw = json.loads(path.read_text())
    assert raw["version"] == 1 and "anchor" not in raw and "preserve" not in raw
    assert all(isinstance(p, list) for p in raw["pins"])
    opened = Document.open(path).state
    assert settings(opened.goal) == {
        "preserve": "total",
        "keep_centroid": False,
        "anchor": "far-side",
        "fold_guard": True,
        "symmetry": "none",
    }
    assert not opened.axis_pinned.any() and opened.pinned.sum() == 1
