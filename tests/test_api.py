"""The Python API (isochor.deform, isochor.Session, isochor.load): the types it takes and
gives back, the volume kept (measured by trimesh, not by core), the pyramid reused."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

import isochor
import isochor.core.lattice
from isochor.core.io.meshio import save_mesh
from tests.models import icosphere, model

ROOT = Path(__file__).resolve().parents[1]


def ball(subdivisions: int = 3) -> trimesh.Trimesh:
    """An icosphere with texture coordinates (a UV per vertex) that must survive."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    uv = mesh.vertices[:, :2] * 0.5 + 0.5
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv)
    return mesh


def volume(vertices, faces) -> float:
    return float(trimesh.Trimesh(vertices, faces, process=False).volume)


def test_deform_a_trimesh_gives_a_trimesh_with_its_vertices_and_uvs():
    mesh = ball()
    before = mesh.vertices.copy()
    out = isochor.deform(mesh, (3, 3, 3), moves={(2, 1, 1): (0.5, 0, 0)}, pins=[(0, 1, 1)])
    assert isinstance(out.mesh, trimesh.Trimesh) and out.converged
    assert np.array_equal(mesh.vertices, before)  # the input is left alone
    assert out.mesh.vertices.shape == mesh.vertices.shape
    assert np.array_equal(out.mesh.faces, mesh.faces)
    assert np.array_equal(out.mesh.visual.uv, mesh.visual.uv)
    assert out.mesh.vertices[:, 0].max() > mesh.vertices[:, 0].max() + 0.1  # stretched
    assert out.mesh.volume == pytest.approx(mesh.volume, rel=5e-4)
    assert out.report["converged"] is True and out.report["lattice"] == [3, 3, 3]


def test_deform_arrays_gives_arrays_and_a_target_volume():
    mesh = icosphere(3)
    vertices, faces = isochor.deform(
        (mesh.vertices, mesh.faces),
        (3, 3, 3),
        moves=[{"node": [1, 1, 2], "by": [0, 0, -0.4]}],
        target=0.8,
    ).mesh
    assert isinstance(vertices, np.ndarray) and vertices.shape == mesh.vertices.shape
    assert volume(vertices, faces) == pytest.approx(
        0.8 * volume(mesh.vertices, mesh.faces), rel=1e-3
    )


def test_deform_a_pyvista_mesh_gives_a_pyvista_mesh():
    pv = pytest.importorskip("pyvista", reason="pyvista is the viewport's library")
    sphere = pv.Sphere(theta_resolution=24, phi_resolution=24)
    out = isochor.deform(sphere, (3, 3, 3), moves={(0, 0, 0): (-0.2, -0.2, -0.2)})
    assert isinstance(out.mesh, pv.PolyData) and out.mesh.n_points == sphere.n_points
    faces = np.asarray(sphere.triangulate().faces).reshape(-1, 4)[:, 1:]
    assert volume(out.mesh.points, faces) == pytest.approx(volume(sphere.points, faces), rel=5e-4)


@pytest.mark.parametrize(
    ("mesh", "words"),
    [
        (42, r"\(vertices, faces\) arrays, a trimesh.Trimesh or a pyvista.PolyData; got int"),
        ("no-such-file.obj", "no-such-file.obj.*no such file"),  # a string is a path
        ((np.zeros((4, 2)), np.array([[0, 1, 2]])), r"vertices must be an \(n, 3\) array"),
        ((np.zeros((3, 3)), np.array([[0, 1, 5]])), "a vertex that does not exist"),
        ((np.eye(3), np.array([[0, 1, 2]])), "flat open sheet.*no solid to keep"),
    ],
)
def test_a_bad_mesh_is_one_sentence(mesh, words):
    with pytest.raises(isochor.IsochorError, match=words):
        isochor.deform(mesh, (3, 3, 3))


def test_bad_lattices_and_nodes_are_the_scenario_files_words():
    with pytest.raises(isochor.IsochorError, match="lattice.nodes: each axis needs 2 to 10"):
        isochor.Session(ball(), (11, 3, 3))
    with pytest.raises(
        isochor.IsochorError, match=r"target_volume_ratio -1.0 is outside 0\.05\.\.20"
    ):
        isochor.Session(ball(), target=-1)
    session = isochor.Session(ball(), (3, 3, 3))
    with pytest.raises(isochor.IsochorError, match="node .* is not a node of the 3x3x3"):
        session.pin((3, 0, 0))
    with pytest.raises(isochor.IsochorError, match="exactly one of by= or to="):
        session.move((0, 0, 0))


def test_a_session_solves_three_edits_reusing_its_pyramid(monkeypatch):
    session = isochor.Session(ball(4), (3, 3, 3))
    assert session.lattice.shape == (3, 3, 3)
    session.pin((0, 1, 1))
    session.move((2, 1, 1), by=(0.3, 0, 0))
    first = session.solve()
    assert first.converged

    bases = []
    real = isochor.core.lattice.Lattice.basis
    monkeypatch.setattr(
        isochor.core.lattice.Lattice, "basis", lambda self, p: bases.append(len(p)) or real(self, p)
    )
    monkeypatch.setattr(isochor.core.api, "pyramid_of", None)  # would fail if called
    session.move((2, 1, 1), by=(0.2, 0, 0))
    second = session.solve()
    corner = session.lattice.index(2, 2, 2)
    was = session.nodes[corner].copy()  # a free node: where the second solve put it
    records = list(_steps(session, lambda s: s.move((2, 2, 2), by=(0, 0.2, 0))))
    assert second.converged and records and records[-1].level_done
    assert bases == []  # every level's basis came from the first solve's cache
    assert session.result.converged
    np.testing.assert_allclose(session.nodes[corner], was + (0, 0.2, 0))  # by: from there
    assert session.mesh.volume == pytest.approx(ball(4).volume, rel=5e-4)


def _steps(session, edit):
    edit(session)
    gen = session.steps()
    while True:
        try:
            yield next(gen)
        except StopIteration:
            return


def test_a_closed_step_generator_keeps_the_nodes():
    session = isochor.Session(ball(), (3, 3, 3))
    session.move((2, 1, 1), by=(0.3, 0, 0))
    before = session.nodes.copy()
    steps = session.steps()
    next(steps)
    steps.close()
    assert np.array_equal(session.nodes, before) and session.result is None
    with pytest.raises(isochor.IsochorError, match="nothing solved yet"):
        _ = session.report


def test_load_a_model_file_export_and_save_a_scenario(tmp_path):
    save_mesh(tmp_path / "ball.obj", icosphere(3))
    session = isochor.load(tmp_path / "ball.obj", lattice=(3, 3, 3))
    session.move((2, 1, 1), by=(0.3, 0, 0))
    session.pin((0, 1, 1))
    session.solve()
    notes = session.export(tmp_path / "out.obj")
    assert notes == []
    out = trimesh.load(tmp_path / "out.obj", process=False)
    assert len(out.vertices) == icosphere(3).n_vertices
    assert out.volume == pytest.approx(volume(icosphere(3).vertices, icosphere(3).faces), rel=5e-4)
    with pytest.raises(isochor.IsochorError, match="would overwrite the model"):
        session.export(tmp_path / "ball.obj")
    session.save(tmp_path / "scene.json")
    again = isochor.load(tmp_path / "scene.json")
    assert again.lattice.shape == (3, 3, 3)
    assert np.array_equal(again.fixed, session.fixed)
    np.testing.assert_allclose(again.nodes[again.fixed], session.nodes[session.fixed])
    assert json.loads((tmp_path / "scene.json").read_text())["model"]["path"] == "ball.obj"


def test_a_mesh_from_memory_exports_but_has_no_scenario(tmp_path):
    session = isochor.Session(ball(), (3, 3, 3))
    session.move((2, 1, 1), by=(0.3, 0, 0))
    session.solve()
    session.export(tmp_path / "ball.glb")
    back = trimesh.load(tmp_path / "ball.glb", force="mesh", process=False)
    assert len(back.vertices) == len(ball().vertices)
    np.testing.assert_allclose(back.visual.uv, ball().visual.uv, atol=1e-6)
    with pytest.raises(isochor.IsochorError, match="no file a scenario can name"):
        session.save(tmp_path / "s.json")


def test_the_cow_from_a_file_keeps_its_volume():
    path = model("cow.obj")
    session = isochor.load(path)
    assert session.lattice.shape == (4, 3, 3)  # the editor's default for a long model
    session.move((0, 1, 1), by=(0, 1.0, 0))
    session.pin((3, 1, 1))
    assert session.solve().converged
    assert session.report["volume_final"] == pytest.approx(
        session.report["volume_original"], rel=5e-4
    )


def test_the_readme_scripting_example_runs(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Scripting") :]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # our own README
    assert namespace["result"].converged
    assert (tmp_path / "squashed.obj").exists()


def two_balls() -> trimesh.Trimesh:
    a = trimesh.creation.icosphere(3, radius=1.0)
    b = trimesh.creation.icosphere(3, radius=0.5)
    b.apply_translation([1.7, 0.0, 0.2])
    return trimesh.util.concatenate([a, b])


def test_deform_keeps_each_body_the_centroid_and_axis_pins():
    mesh = two_balls()
    rest = sorted(p.volume for p in mesh.split(only_watertight=False))
    bottom = [(i, j, 0) for i in range(3) for j in range(3)]
    top = {(i, j, 2): (0.0, 0.0, -0.5) for i in range(3) for j in range(3)}
    out = isochor.deform(mesh, (3, 3, 3), moves=top, pins=bottom, preserve="per-body")
    assert out.converged, out.report["message"]
    final = sorted(p.volume for p in out.mesh.split(only_watertight=False))
    np.testing.assert_allclose(final, rest, rtol=5e-4)  # measured by trimesh
    assert len(out.report["body_volumes"]) == 2 and out.report["preserve"] == "per-body"
    # the same squash keeping only the total leaves the bodies off their volumes
    total = isochor.deform(mesh, (3, 3, 3), moves=top, pins=bottom)
    final = sorted(p.volume for p in total.mesh.split(only_watertight=False))
    assert max(abs(f / r - 1) for f, r in zip(final, rest)) > 5e-3

    ball_ = trimesh.creation.icosphere(3)
    moves = {(2, 1, 1): (0.4, 0.3, 0.0)}
    kept = isochor.deform(ball_, (3, 3, 3), moves=moves, keep_centroid=True)
    assert kept.converged and kept.report["centroid_shift"] <= 1e-4
    shift = np.linalg.norm(kept.mesh.center_mass - ball_.center_mass) / 2.0
    assert shift <= 1e-4

    pins = [{"node": (0, 1, 1), "axes": "z"}, *[(0, j, k) for j in (0, 2) for k in (0, 2)]]
    axis = isochor.deform(ball_, (3, 3, 3), moves=moves, pins=pins)
    assert axis.converged
    lattice = _lattice_of(ball_)
    node = np.array(axis.report["nodes"])[lattice.index(0, 1, 1)]
    rest_node = lattice.rest_nodes[lattice.index(0, 1, 1)]
    assert node[2] == rest_node[2] and np.linalg.norm(node[:2] - rest_node[:2]) > 1e-4


def _lattice_of(mesh) -> isochor.core.lattice.Lattice:
    """The lattice deform fits around a mesh (the default padding)."""
    return isochor.core.lattice.Lattice.around(mesh.vertices, (3, 3, 3), 0.05)


def test_a_session_saves_version_2_only_when_it_uses_it(tmp_path):
    path = tmp_path / "ball.obj"
    save_mesh(path, icosphere(3))
    session = isochor.load(path, lattice=(3, 3, 3))
    session.move((2, 1, 1), by=(0.3, 0.0, 0.0))
    session.save(tmp_path / "plain.json")
    assert json.loads((tmp_path / "plain.json").read_text())["version"] == 1
    session.pin((0, 1, 1), axes="z")
    session.keep_centroid = True
    session.anchor = "none"
    session.save(tmp_path / "v2.json")
    doc = json.loads((tmp_path / "v2.json").read_text())
    assert doc["version"] == 2 and doc["keep_centroid"] is True and doc["anchor"] == "none"
    assert {"node": [0, 1, 1], "axes": "z"} in doc["pins"]
    again = isochor.load(tmp_path / "v2.json")
    assert again.goal == session.goal
    assert again.fixed[again.lattice.index(0, 1, 1)].tolist() == [False, False, True]
    assert again.solve().converged
    with pytest.raises(isochor.IsochorError, match="axes"):
        session.pin((0, 0, 0), axes="w")
    session.target = 0.01
    with pytest.raises(isochor.IsochorError, match=r"0\.05\.\.20"):
        session.solve()


def test_the_sessions_goal_attributes_are_the_goals_keywords_with_their_types():
    """The goal is declared once (isochor.core.goal.spec); the Session's annotations, which
    tell a caller's type checker its goal attributes, name exactly those keywords, typed as
    the declared defaults are, and a session sets each to the declared default."""
    from typing import get_type_hints

    from isochor.core.goal.spec import GOAL_FIELDS

    hints = get_type_hints(isochor.Session)
    assert {f.keyword: f.kind for f in GOAL_FIELDS} == {
        name: hints[name] for name in (f.keyword for f in GOAL_FIELDS)
    }
    ball = icosphere(2)
    session = isochor.Session((ball.vertices, ball.faces), lattice=(3, 3, 3))
    assert {f.keyword: getattr(session, f.keyword) for f in GOAL_FIELDS} == {
        f.keyword: f.default for f in GOAL_FIELDS
    }


@pytest.mark.parametrize(
    "basis, shape, node",
    [
        ("bspline", (6, 6, 6), (5, 5, 5)),  # a corner
        ("bspline", (6, 6, 6), (2, 5, 3)),  # the middle of a face
        ("bernstein", (4, 3, 3), (3, 2, 2)),
        ("bernstein", (4, 3, 3), (3, 1, 1)),
    ],
)
def test_a_small_edit_after_a_solve_reaches_a_fresh_solves_nodes(basis, shape, node):
    """A Session solve after a 1 % nudge of a moved node (same pins and goal) starts as a
    drag's release does (near the last result, its curvature kept); it meets the volume and
    reaches the nodes a fresh solve of the same edit reaches, to the solver's node
    tolerance (``tol_nodes`` of the object size: what the multi-level loop calls the same
    nodes)."""
    from isochor.core.solve.generators import run_to_end

    s = isochor.Session(trimesh.creation.icosphere(3), lattice=shape, basis=basis)
    s.fixed[s.lattice.grid_parameters()[:, 1] == 0] = True
    s.move(node, by=(0, 0.15 * s.lattice.size, 0))
    assert s.solve().converged
    s.move(node, by=(0.01 * s.lattice.size, 0, 0))
    start = s.nodes.copy()
    again = s.solve()
    fresh = run_to_end(s.problem.solve(start, s.fixed, goal=s.goal))
    assert again.converged and fresh.converged, (again.message, fresh.message)
    tol = s.problem.options
    assert abs(again.rel_volume_error) <= tol.tol_volume
    size = s.problem.surface.size
    assert np.abs(again.nodes - fresh.nodes).max() <= tol.tol_nodes * size


def test_a_small_edit_whose_near_solve_misses_is_solved_whole():
    """Where the solve near the last result does not converge, the Session solves the edit
    whole from the same nodes (a wrapper makes the near one report a miss)."""
    from dataclasses import replace

    class NearMisses:
        def __init__(self, problem):
            self.problem, self.calls = problem, []

        def __getattr__(self, name):
            return getattr(self.problem, name)

        def solve(self, *args, near=False, **kw):
            self.calls.append(near)
            run = self.problem.solve(*args, near=near, **kw)
            if not near:
                return run

            def missed():
                return replace((yield from run), converged=False)

            return missed()

    s = isochor.Session(trimesh.creation.icosphere(3), lattice=(6, 6, 6), basis="bspline")
    s.fixed[s.lattice.grid_parameters()[:, 1] == 0] = True
    s.move((5, 5, 5), by=(0, 0.15 * s.lattice.size, 0))
    assert s.solve().converged
    s.problem = wrapped = NearMisses(s.problem)
    s.move((5, 5, 5), by=(0.01 * s.lattice.size, 0, 0))
    seen = []
    s.progress = lambda stage, f: seen.append(f)
    result = s.solve()
    assert wrapped.calls == [True, False]
    assert result.converged and abs(result.rel_volume_error) <= s.problem.options.tol_volume
    assert seen == sorted(seen) and seen[-1] == 1.0  # one stage, never decreasing
