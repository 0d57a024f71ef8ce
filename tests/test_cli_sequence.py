"""Keyframed poses and sequence output (issue 13), out of process: the real
``isochor solve SCENARIO --sequence ...`` as a user runs it, each run held to the contract
of :mod:`tests.test_cli_goals`."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

from isochor.core.defaults import TOL_VOLUME
from tests.test_cli_goals import SMALL_TORUS, cow, one_line, scenario, solve

#: an OBJ writes 6 significant digits: the volume measured from the file is this close
FILE_PRECISION = 1e-3


def _three_keys(model_doc: dict, nodes=(4, 3, 3), **timeline) -> dict:
    """Rest at frame 0, the head corner up at 12, down and forward at 24; frames 0..23."""
    corner = [nodes[0] - 1, 1, nodes[2] - 1]
    poses = [
        {"frame": 0},
        {"frame": 12, "moves": [{"node": corner, "by": [0.0, 0.6, 0.0]}]},
        {"frame": 24, "moves": [{"node": corner, "by": [0.5, -0.4, 0.0]}]},
    ]
    settings = {"start": 0, "end": 23, "interpolation": "smooth", **timeline}
    return scenario(model_doc, nodes=nodes, version=3, poses=poses, timeline=settings)


def _glb_json(path) -> dict:
    data = path.read_bytes()
    (length,) = struct.unpack("<I", data[12:16])
    return json.loads(data[20 : 20 + length])


def test_three_keys_over_24_frames_on_the_cow(tmp_path):
    (tmp_path / "out").mkdir()
    run = solve(tmp_path, _three_keys(cow()), "--sequence", "out/cow_####.obj")
    assert run.returncode == 0, run
    files = sorted((tmp_path / "out").glob("cow_*.obj"))
    assert [f.name for f in files] == [f"cow_{i:04d}.obj" for i in range(24)]
    r = run.report
    assert r["converged"] is True and len(r["frames"]) == 24 and len(r["keys"]) == 3
    rest = trimesh.load(cow()["path"], process=True)
    meshes = [trimesh.load(f, process=True) for f in files]
    for i, mesh in enumerate(meshes):  # every frame's volume, measured from its file
        assert abs(mesh.volume / rest.volume - 1) <= TOL_VOLUME + FILE_PRECISION, i
        assert abs(r["frames"][i]["relative_volume_error"]) <= TOL_VOLUME
    # no pops: a frame moves the model at most a small multiple of the keys' own pace
    verts = np.array([m.vertices for m in meshes])
    step = np.linalg.norm(np.diff(verts, axis=0), axis=2).max(axis=1)
    key_motion = max(
        np.linalg.norm(verts[12] - verts[0], axis=1).max(),
        np.linalg.norm(verts[23] - verts[12], axis=1).max(),
    )
    assert step.max() <= 3.0 * key_motion / 11, (step.max(), key_motion)
    assert step.max() > 0  # it moves


def test_an_animated_glb_holds_one_morph_target_per_frame(tmp_path):
    doc = _three_keys(SMALL_TORUS, nodes=(3, 2, 2), end=9, rate=12)
    run = solve(tmp_path, doc, "--sequence", "anim.glb")
    assert run.returncode == 0, run
    scene = trimesh.load(tmp_path / "anim.glb")
    assert len(scene.geometry) == 1
    gltf = _glb_json(tmp_path / "anim.glb")
    targets = gltf["meshes"][0]["primitives"][0]["targets"]
    assert len(targets) == 10 == len(gltf["meshes"][0]["weights"])
    sampler = gltf["animations"][0]["samplers"][0]
    times = gltf["accessors"][sampler["input"]]
    assert times["count"] == 10 and times["max"] == [pytest.approx(9 / 12)]
    assert gltf["accessors"][sampler["output"]]["count"] == 100


@pytest.mark.parametrize(
    ("change", "args", "names"),
    [
        ({"poses": []}, ["--sequence", "f_####.obj"], ["no \"poses\""]),
        ({}, ["--sequence", "frames.obj"], ["####"]),
        ({}, ["--sequence", "f_####.xyz"], ["--sequence"]),
        ({}, ["--sequence", "nofolder/f_####.obj"], ["nofolder"]),
        ({"poses": [{"frame": 0}, {"frame": 0}]}, ["--sequence", "a.glb"], ["poses[1].frame"]),
        ({"timeline": {"start": 5, "end": 1}}, ["--sequence", "a.glb"], ["timeline"]),
        ({"poses": [{"frame": 0, "moves": [{"node": [9, 0, 0], "by": [0, 0, 0]}]}]},
         ["--sequence", "a.glb"], ["poses[0].moves[0].node"]),
    ],
)  # fmt: skip
def test_bad_sequences_are_one_line_and_write_nothing(tmp_path, change, args, names):
    doc = _three_keys(SMALL_TORUS, nodes=(3, 2, 2), end=4)
    doc.update(change)
    if doc.get("poses") == []:
        doc.pop("timeline")
    run = solve(tmp_path, doc, *args)
    one_line(run, 1, *names)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]


def test_a_sequence_never_overwrites_the_model(tmp_path):
    model = tmp_path / "torus_0001.obj"
    model.write_text("not touched\n")
    doc = _three_keys(SMALL_TORUS, nodes=(3, 2, 2), end=3)
    doc["model"] = {"path": "torus_0001.obj"}
    run = solve(tmp_path, doc, "--sequence", "torus_####.obj")
    one_line(run, 1, "torus_0001.obj")
    assert model.read_text() == "not touched\n"
