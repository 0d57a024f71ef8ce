"""The OFF files Isochor writes, read by the tools a pipeline uses: pyvista (which reads
OFF through meshio, its ``io`` extra: without meshio ``pyvista.read`` of any ``.off``
says it cannot read it), trimesh and Isochor's own reader, each with the same points,
triangles and volume as the report says was written.

Two writers: a fresh file (``--out x.off`` of a built-in shape) and the round trip of an
OFF model into its own format."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from isochor.core.io.meshio import load_mesh
from tests.test_cli_goals import isochor

pyvista = pytest.importorskip("pyvista")
pytest.importorskip("meshio", reason="pyvista reads OFF through meshio (the test extra)")

#: relative volume difference between two sums over the same float64 triangles in
#: another order: about (triangles x eps); the files have at most 65536 triangles
VOLUME_ORDER = 65536 * np.finfo(float).eps * 8


def _outputs(folder: Path) -> dict[str, float]:
    """``{file: volume the report says it holds}`` for a fresh OFF and a round-tripped one."""
    ball = trimesh.creation.icosphere(subdivisions=3)
    (folder / "ball.off").write_text(trimesh.exchange.off.export_off(ball, digits=17))
    scene = {
        "format": "isochor-scenario",
        "version": 1,
        "model": {"path": "ball.off"},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": [2, 2, 2], "by": [0.3, 0.1, 0.0]}],
    }
    (folder / "ball.json").write_text(json.dumps(scene))
    runs = {
        "torus.off": ["--example", "torus-compression"],
        "ball_out.off": ["ball.json"],
    }
    written = {}
    for out, what in runs.items():
        run = isochor("solve", *what, "--out", out, "--report", f"{out}.json", "-q", cwd=folder)
        assert run.returncode == 0, run
        written[out] = json.loads((folder / f"{out}.json").read_text())["written"]["volume"]
    return written


def test_pyvista_trimesh_and_isochor_read_the_off_written(tmp_path):
    for name, volume in _outputs(tmp_path).items():
        path = tmp_path / name
        grid = pyvista.read(path)
        points = np.asarray(grid.points, dtype=np.float64)
        faces = grid.cells_dict[pyvista.CellType.TRIANGLE]
        mesh = trimesh.load(path, process=False)
        np.testing.assert_array_equal(points, mesh.vertices)
        np.testing.assert_array_equal(faces, mesh.faces)
        ours = load_mesh(path).mesh  # (welded: a file of distinct points keeps them all)
        assert ours.vertices.shape == points.shape and len(ours.faces) == len(faces)
        surface = grid.extract_surface(algorithm="dataset_surface")
        assert surface.volume == pytest.approx(volume, rel=VOLUME_ORDER), name
        assert mesh.volume == pytest.approx(volume, rel=VOLUME_ORDER), name
