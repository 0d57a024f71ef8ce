"""The scenario document (isochor.core.scenario.document): validation, files, solves."""

from __future__ import annotations

import copy
import json
import os
import re
import stat

import numpy as np
import pytest

from isochor.core.errors import IsochorError
from isochor.core.io.meshio import save_mesh
from isochor.core.mesh import TriMesh
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.examples import EXAMPLES, example_scenario
from isochor.core.scenario.paper_models import bend_scenario, cow_bend_scenario, squash_scenario
from isochor.core.scenario.problem import build
from isochor.core.solve.multilevel import solve
from tests.models import MODELS, club, model

GOOD = {
    "format": "isochor-scenario",
    "version": 1,
    "model": {"path": "club.ply"},
    "lattice": {"nodes": [5, 2, 2], "padding": 0.05},
    "moves": [
        {"node": [0, 0, 0], "by": [0.0, 0.3, 0.0]},
        {"node": [4, 1, 1], "to": [3.2, 0.9, 0.8]},
    ],
    "pins": [[2, 0, 0]],
    "target_volume_ratio": 1.0,
    "tolerance": {"volume": 0.0005, "nodes": 0.001},
}


def changed(path: str, value, doc=GOOD):
    """A copy of ``doc`` with the dotted ``path`` set to ``value`` (or removed for ...)."""
    out = copy.deepcopy(doc)
    *parents, last = path.split(".")
    obj = out
    for key in parents:
        obj = obj[int(key)] if isinstance(obj, list) else obj[key]
    if isinstance(obj, list):
        obj[int(last)] = value
    elif value is ...:
        del obj[last]
    else:
        obj[last] = value
    return out


def same_document(a: Scenario, b: Scenario) -> bool:
    """Equal scenarios, model paths compared where they lead (a written path is relative to
    its file)."""
    if "path" in a.model:
        return a.model_path() == b.model_path() and a.with_(model={}) == b.with_(model={})
    return a == b


def drive(gen):
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            return stop.value


def solve_scenario(scenario: Scenario):
    problem = build(scenario)
    return drive(
        solve(
            problem.surface,
            problem.nodes,
            problem.fixed,
            target_ratio=scenario.goal.target_ratio,
            options=problem.options,
        )
    )


@pytest.fixture(scope="module")
def club_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("models") / "club.ply"
    save_mesh(path, club(5))
    return path


# -- validation ---------------------------------------------------------------------------
def test_the_issue_example_parses():
    sc = Scenario.from_dict(GOOD)
    assert sc.lattice_nodes == (5, 2, 2)
    assert sc.moves[0].by == (0.0, 0.3, 0.0) and sc.moves[1].to == (3.2, 0.9, 0.8)
    assert sc.pins == ((2, 0, 0),)
    assert (sc.tol_volume, sc.tol_nodes) == (0.0005, 0.001)


@pytest.mark.parametrize(
    "path, value, field",
    [
        ("colour", "red", "'colour'"),
        ("lattice.size", 3, "lattice: unknown key 'size'"),
        ("moves.0.speed", 1, "moves[0]: unknown key 'speed'"),
        ("tolerance.energy", 1, "tolerance: unknown key 'energy'"),
        ("model.scale", 2, "model: unknown key 'scale'"),
        ("version", 4, "version"),
        ("version", "1", "version"),
        ("format", "something-else", "format"),
        ("model", ..., "missing key 'model'"),
        ("model", {"path": "a.obj", "builtin": "torus"}, "model"),
        ("model", {"path": 3}, "model.path"),
        ("model", {"builtin": 3}, "model.builtin"),
        ("lattice.nodes", [5, 2], "lattice.nodes"),
        ("lattice.nodes", [5, 2, "2"], "lattice.nodes"),
        ("lattice.nodes", [5, 2, 2.0], "lattice.nodes"),
        ("lattice.nodes", [11, 2, 2], "lattice.nodes"),
        ("lattice.nodes", [1, 2, 2], "lattice.nodes"),
        ("lattice.padding", "wide", "lattice.padding"),
        ("lattice.padding", -1, "lattice.padding"),
        ("lattice.frame", {"origin": [0, 0, 0]}, "lattice.frame"),
        ("moves", {"node": [0, 0, 0]}, "moves"),
        ("moves.0.node", [5, 0, 0], "moves[0].node"),
        ("moves.0.node", [0, 0, -1], "moves[0].node"),
        ("moves.1.node", [0, 0, 0], "moves[1].node"),  # the same node moved twice
        ("moves.0.by", [0, 1], "moves[0].by"),
        ("moves.0.by", [0, float("nan"), 0], "moves[0].by"),
        ("moves.0.by", [0, True, 0], "moves[0].by"),
        ("moves.0", {"node": [0, 0, 0]}, "moves[0]"),
        ("moves.0", {"node": [0, 0, 0], "by": [0, 0, 0], "to": [0, 0, 0]}, "moves[0]"),
        ("pins.0", [2, 2, 0], "pins[0]"),
        ("pins.0", [2, 0], "pins[0]"),
        ("pins", [[0, 0, 0], "x"], "pins[1]"),
        ("target_volume_ratio", 0, "target_volume_ratio"),
        ("target_volume_ratio", "1", "target_volume_ratio"),
        ("tolerance.volume", 2, "tolerance"),
        ("tolerance.nodes", None, "tolerance.nodes"),
        ("tolerance.volume", 1e-300, "tolerance.volume: must be from 1e-12 to 0.5"),
        (
            "target_volume_ratio",
            2**64,
            "target_volume_ratio 1.8446744073709552e+19 is outside 0.05..20",
        ),
        ("target_volume_ratio", 10**400, "target_volume_ratio: must be a finite number"),
        ("moves.0.by", [1e300, 0, 0], "moves[0].by: must be from -1e+15 to 1e+15"),
        ("lattice.padding", 2**70, "lattice.padding"),
        ("model.path", "a\0b.obj", "model.path: not a valid file name"),
    ],
)
def test_bad_documents_name_the_field(path, value, field):
    with pytest.raises(IsochorError) as err:
        Scenario.from_dict(changed(path, value))
    assert field in str(err.value)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('"target_volume_ratio": ' + "9" * 5000, "a number has 5000 digits"),
        ('"target_volume_ratio": NaN', "NaN is not a JSON number"),
        ('"target_volume_ratio": Infinity', "Infinity is not a JSON number"),
        ('"target_volume_ratio": 1e999', "target_volume_ratio: must be a finite number"),
    ],
)
def test_numbers_json_does_not_allow_are_one_line(tmp_path, text, words):
    path = tmp_path / "s.json"
    path.write_text('{"model": {"builtin": "sphere"}, ' + text + "}")
    with pytest.raises(IsochorError, match=words) as err:
        Scenario.read(path)
    assert "\n" not in str(err.value) and len(str(err.value)) < 300


@pytest.mark.parametrize(
    ("model", "words"),
    [
        ({"builtin": "torus", "n_levels": float("inf")}, "model.n_levels: must be a finite"),
        ({"builtin": "torus", "n_levels": 2.5}, "model.n_levels: must be a whole number"),
        ({"builtin": "sphere", "radius": 1e300}, "model.radius: must be from 1e-06 to 1e+06"),
        ({"builtin": "torus", "minor": 2.0}, "model.minor: must be smaller than model.major"),
    ],
)
def test_builtin_shape_parameters_are_bounded(model, words):
    with pytest.raises(IsochorError, match=re.escape(words)):
        build(Scenario.from_dict({"model": model}))


def test_a_move_far_beyond_the_lattice_is_refused():
    doc = {"model": {"builtin": "sphere", "n_levels": 2}}
    doc["moves"] = [{"node": [0, 0, 0], "by": [1e6, 0, 0]}]
    with pytest.raises(IsochorError, match=r"moves\[0\]: moves node \[0, 0, 0\] by 1e\+06"):
        build(Scenario.from_dict(doc))


def test_not_an_object():
    with pytest.raises(IsochorError, match="scenario: must be a JSON object"):
        Scenario.from_dict([1, 2, 3])


# -- files --------------------------------------------------------------------------------
def test_read_errors_name_the_file(tmp_path):
    with pytest.raises(IsochorError, match="no such scenario file"):
        Scenario.read(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"model": {"path": "a.obj"},\n "pins": [}\n')
    with pytest.raises(IsochorError, match=r"bad\.json: not valid JSON \(line 2"):
        Scenario.read(bad)
    bad.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(IsochorError, match="bad.json"):
        Scenario.read(bad)
    bad.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(IsochorError, match="bad.json"):
        Scenario.read(bad)
    bad.write_text(json.dumps(changed("pins.0", [9, 9, 9])))
    with pytest.raises(IsochorError, match=r"bad\.json: pins\[0\]"):
        Scenario.read(bad)


def test_relative_model_paths_are_relative_to_the_scenario_file(tmp_path, club_file, monkeypatch):
    (tmp_path / "scenes" / "deep").mkdir(parents=True)
    (tmp_path / "assets").mkdir()
    target = tmp_path / "assets" / "club.ply"
    target.write_bytes(club_file.read_bytes())
    scene = tmp_path / "scenes" / "deep" / "bend.json"
    scene.write_text(json.dumps(changed("model.path", "../../assets/club.ply")))
    monkeypatch.chdir(tmp_path / "scenes")  # somewhere else entirely
    sc = Scenario.read(scene)
    assert sc.model_path() == target.resolve()
    problem = build(sc)
    assert problem.surface.full.n_faces == 20480
    # written elsewhere, the path is rewritten relative to the new place
    sc.write(tmp_path / "copy.json")
    doc = json.loads((tmp_path / "copy.json").read_text())
    assert doc["model"]["path"] == os.path.join("assets", "club.ply")
    assert Scenario.read(tmp_path / "copy.json").model_path() == target.resolve()


def test_missing_model_file_names_it(tmp_path):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(changed("model.path", "nowhere.obj")))
    with pytest.raises(IsochorError, match="model.path 'nowhere.obj': no such file"):
        build(Scenario.read(scene))


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_write_read_round_trip(tmp_path, name):
    sc = example_scenario(name)
    sc.write(tmp_path / "s.json")
    back = Scenario.read(tmp_path / "s.json")
    assert back == sc
    assert back.to_dict() == sc.to_dict()
    assert [p.name for p in tmp_path.iterdir()] == ["s.json"]
    mode = stat.S_IMODE(os.stat(tmp_path / "s.json").st_mode)
    assert mode & stat.S_IRGRP or os.name == "nt"


def test_frame_lattice_round_trip(tmp_path):
    doc = changed(
        "lattice",
        {
            "nodes": [3, 3, 3],
            "frame": {"origin": [-2, -1, -1], "axes": [[4, 0, 0], [0, 2, 0], [0, 0, 2]]},
        },
    )
    sc = Scenario.from_dict(changed("moves", [], doc) | {"pins": []})
    sc.write(tmp_path / "f.json")
    back = Scenario.read(tmp_path / "f.json")
    assert same_document(back, sc)
    assert back.frame == ((-2.0, -1.0, -1.0), ((4.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 2.0)))


# -- reproducible solves ------------------------------------------------------------------
def test_written_scenario_solves_twice_to_the_same_nodes(tmp_path, club_file):
    sc = bend_scenario(club_file, angle_deg=50)
    sc.write(tmp_path / "bend.json")
    back = Scenario.read(tmp_path / "bend.json")
    assert same_document(back, sc)
    assert back.model["path"] == os.path.relpath(club_file, tmp_path)
    first, second = solve_scenario(back), solve_scenario(Scenario.read(tmp_path / "bend.json"))
    direct = solve_scenario(sc)
    assert first.converged
    assert np.max(np.abs(first.nodes - second.nodes)) <= 1e-12
    assert np.max(np.abs(first.nodes - direct.nodes)) <= 1e-12


def _scaled_copy(sc: Scenario, path, factor: float) -> Scenario:
    doc = sc.to_dict()
    doc["model"]["path"] = str(path)
    for mv in doc["moves"]:
        key = "by" if "by" in mv else "to"
        mv[key] = [factor * x for x in mv[key]]
    return Scenario.from_dict(doc)


@pytest.mark.parametrize("source", ["club", "kitten.obj"])
def test_scaled_model_gives_the_scaled_result(tmp_path, club_file, source):
    path = club_file if source == "club" else model(source)
    from isochor.core.io.meshio import load_mesh

    mesh = load_mesh(path).mesh
    big = tmp_path / "big.ply"
    save_mesh(big, TriMesh(mesh.vertices * 1000.0, mesh.faces))
    sc = squash_scenario(path, squash=0.25)
    small_result = solve_scenario(sc)
    big_result = solve_scenario(_scaled_copy(sc, big, 1000.0))
    assert small_result.converged and big_result.converged
    size = 1000.0 * np.ptp(mesh.vertices, axis=0).max()
    assert np.max(np.abs(1000.0 * small_result.nodes - big_result.nodes)) <= 1e-6 * size
    assert big_result.volume_final == pytest.approx(1e9 * small_result.volume_final, rel=1e-6)


def test_cow_bend_scenario_is_the_papers_setup():
    sc = cow_bend_scenario(model("cow.obj").parent)
    assert sc.lattice_nodes == (5, 2, 2)
    assert sc.model_path() == (MODELS / "cow.obj").resolve()
    assert sorted(m.node for m in sc.moves) == [(4, j, k) for j in (0, 1) for k in (0, 1)]
    assert sorted(sc.pins) == [(0, j, k) for j in (0, 1) for k in (0, 1)]
    assert all(m.by[1] > 0 for m in sc.moves)  # the head end goes up


def test_a_model_given_as_a_scenario_says_what_to_do(tmp_path):
    from isochor.core.errors import IsochorError
    from isochor.core.scenario.document import Scenario

    model = tmp_path / "cube.obj"
    model.write_text("v 0 0 0\n")
    with pytest.raises(IsochorError, match="this is a model, not a scenario file"):
        Scenario.read(model)


def test_a_model_sticking_out_of_its_frame_is_said_with_how_much():
    doc = {"model": {"builtin": "sphere", "n_levels": 2}}  # the unit sphere
    inside = build(Scenario.from_dict(doc))
    assert inside.coverage is None and inside.warnings == []
    # a frame covering x from -1 to 0.6 only: the cap beyond x = 0.6 sticks out
    doc["lattice"] = {"nodes": [3, 3, 3], "frame": {"origin": [-1, -1.1, -1.1],
                      "axes": [[1.6, 0, 0], [0, 2.2, 0], [0, 0, 2.2]]}}  # fmt: skip
    problem = build(Scenario.from_dict(doc))
    points = problem.surface.full.vertices
    share = np.mean(points[:, 0] > 0.6)
    assert problem.coverage == problem.warnings[-1]
    assert problem.coverage.startswith(f"{100 * share:.3g}% of the model's vertices")
    assert f"up to {(points[:, 0].max() - 0.6) / 1.6:.3g} of its size" in problem.coverage
