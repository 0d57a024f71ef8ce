"""The shipped assets (isochor.assets): reproducible, readable, and what they claim to be."""

from __future__ import annotations

import subprocess
import sys
from math import pi
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from isochor import assets
from isochor.assets import make_assets
from isochor.core.io.meshio import load_mesh
from isochor.core.scenario.document import Scenario
from isochor.core.scenario.examples import EXAMPLES, example_scenario
from isochor.core.scenario.shapes import club_levels, cup_levels, torus_levels, torus_volume
from isochor.core.volume import signed_volume

SHIPPED = {
    "torus.obj",
    "club.obj",
    "cup.obj",
    "icon.png",
    *(f"examples/{name}.json" for name in EXAMPLES),
}


def _files(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("assets")
    make_assets.write_assets(out)
    return out


# -- reproducibility --------------------------------------------------------------------------
def test_generator_writes_exactly_the_shipped_files(regenerated):
    assert _files(regenerated) == SHIPPED
    shipped = _files(assets.ASSETS_DIR)
    assert shipped >= SHIPPED
    examples = {p for p in shipped if p.startswith("examples/")}
    assert examples == {p for p in SHIPPED if p.startswith("examples/")}, "stale examples"


@pytest.mark.parametrize("name", sorted(SHIPPED - {"icon.png"}))
def test_shipped_text_files_are_reproduced_byte_for_byte(regenerated, name):
    assert (regenerated / name).read_bytes() == (assets.ASSETS_DIR / name).read_bytes(), (
        f"assets/{name} is stale: run `python assets/make_assets.py`"
    )


def test_shipped_icon_is_reproduced(regenerated):
    # Pixels, not bytes: the compressed PNG stream depends on the zlib build Pillow bundles.
    with Image.open(regenerated / "icon.png") as new, Image.open(assets.icon_path()) as old:
        assert new.mode == old.mode and new.size == old.size
        assert new.tobytes() == old.tobytes(), "assets/icon.png is stale: run make_assets.py"


def test_generator_is_deterministic(regenerated, tmp_path):
    make_assets.write_assets(tmp_path)
    for name in SHIPPED:
        assert (tmp_path / name).read_bytes() == (regenerated / name).read_bytes(), name


def test_script_runs_as_a_module_into_a_given_folder(tmp_path):
    out = tmp_path / "new" / "assets"
    proc = subprocess.run(
        [sys.executable, "-m", "isochor.assets.make_assets", str(out)],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert _files(out) == SHIPPED
    assert (out / "torus.obj").read_bytes() == (assets.ASSETS_DIR / "torus.obj").read_bytes()


# -- example scenarios ------------------------------------------------------------------------
def test_example_names_match_the_core_examples():
    assert tuple(EXAMPLES) == assets.EXAMPLE_NAMES
    assert list(assets.example_files()) == list(EXAMPLES)


@pytest.mark.parametrize("name", list(EXAMPLES))
def test_shipped_example_reads_as_the_builtin_scenario(name):
    path = assets.example_files()[name]
    assert path.name == f"{name}.json" and path.parent.name == "examples"
    scenario = Scenario.read(path)
    assert scenario.to_dict() == example_scenario(name).to_dict()
    assert "builtin" in scenario.model


# -- models -----------------------------------------------------------------------------------
def _raw_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and 0-based faces of an OBJ, read directly (no repair)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("# ") and "make_assets.py" in lines[0]
    assert all(line[:2] in ("v ", "f ") for line in lines[1:])
    v = np.array([line.split()[1:] for line in lines if line.startswith("v ")], float)
    f = np.array([line.split()[1:] for line in lines if line.startswith("f ")], np.int64) - 1
    return v, f


def _assert_closed_and_consistent(faces: np.ndarray) -> None:
    """Every edge is shared by exactly two triangles, which run it in opposite directions."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, counts = np.unique(directed, axis=0, return_counts=True)
    assert counts.max() == 1, "an edge is run twice in the same direction"
    undirected = np.sort(directed, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    assert np.all(counts == 2), "the surface is not closed"


@pytest.mark.parametrize(
    ("name", "levels", "n_triangles"),
    [("torus", torus_levels, 4096), ("club", club_levels, 5120)],
)
def test_shipped_model_is_the_builtin_level(name, levels, n_triangles):
    path = assets.model_files()[name]
    assert path.name == f"{name}.obj"
    assert path.stat().st_size < 400_000
    builtin = next(m for m in levels(6) if m.n_faces == n_triangles)
    expected = signed_volume(builtin.vertices, builtin.faces)

    v, f = _raw_obj(path)
    assert f.shape == (n_triangles, 3) and len(v) == builtin.n_vertices
    np.testing.assert_allclose(v, builtin.vertices, rtol=0, atol=1e-8)
    _assert_closed_and_consistent(f)
    assert signed_volume(v, f) > 0, "not outward wound"

    loaded = load_mesh(path)
    assert loaded.warnings == []
    assert loaded.bodies == 1
    assert loaded.mesh.n_faces == n_triangles
    _assert_closed_and_consistent(loaded.mesh.faces)
    assert loaded.volume == pytest.approx(expected, rel=1e-6)


def test_shipped_cup_is_open_at_its_rim_and_keeps_its_capacity():
    """The container: one sheet, the builtin level's own faces, one open rim; loaded, the
    rim is capped and the volume is the capacity, measured here with a cap of our own."""
    path = assets.model_files()["cup"]
    v, f = _raw_obj(path)
    builtin = next(m for m in cup_levels(5) if m.own_faces == len(f))
    np.testing.assert_allclose(v, builtin.own.vertices, rtol=0, atol=1e-8)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    reverse = {tuple(e) for e in directed[:, ::-1].tolist()}
    rim = np.array([e for e in directed.tolist() if tuple(e) not in reverse])
    assert len(np.unique(rim[:, 0])) == len(rim) == 64  # one loop: the rim's 64 segments
    assert np.ptp(v[rim[:, 0], 2]) < 1e-12  # a flat rim: our cap is a flat polygon
    apex = len(v)
    capped = np.vstack([f, np.c_[rim[:, 1], rim[:, 0], np.full(len(rim), apex)]])
    capacity = signed_volume(np.vstack([v, v[rim[:, 0]].mean(axis=0)]), capped)
    assert capacity > 0
    loaded = load_mesh(path)
    assert loaded.mesh.cap_vertices == 1 and loaded.mesh.cap_faces == 64
    assert loaded.mesh.own_faces == len(f) and loaded.bodies == 1
    assert loaded.volume == pytest.approx(capacity, rel=1e-12)
    assert any("Capped 1 hole" in w for w in loaded.warnings)


def test_torus_volume_is_close_to_the_closed_form():
    loaded = load_mesh(assets.model_files()["torus"])
    assert torus_volume() == pytest.approx(2 * pi**2 * 1.0 * 0.4**2)
    assert loaded.volume == pytest.approx(torus_volume(), rel=0.01)
    lo, hi = loaded.mesh.vertices.min(axis=0), loaded.mesh.vertices.max(axis=0)
    np.testing.assert_allclose(hi, [1.4, 1.4, 0.4], atol=1e-3)
    np.testing.assert_allclose(lo, [-1.4, -1.4, -0.4], atol=1e-3)


# -- icon and API -----------------------------------------------------------------------------
def test_icon_is_a_256_png_with_many_colours():
    path = assets.icon_path()
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(path) as img:
        assert img.format == "PNG"
        assert img.size == (256, 256)
        colours = img.convert("RGBA").getcolors(maxcolors=256 * 256)
    assert colours is not None and len(colours) > 16
    rgb = {c[:3] for _, c in colours}
    assert {(0x56, 0xB4, 0xE9), (0xE6, 0x9F, 0x00), (0xD8, 0xD2, 0xC4)} <= rgb


def test_api_returns_existing_files():
    assert Path(assets.__file__).resolve().parent == assets.ASSETS_DIR
    files = [*assets.example_files().values(), *assets.model_files().values(), assets.icon_path()]
    assert all(isinstance(p, Path) and p.is_file() for p in files)
    assert list(assets.model_files()) == ["torus", "club", "cup"]
    assert assets.icon_path().name == "icon.png"


def test_api_imports_neither_numpy_nor_qt():
    code = (
        "import sys, isochor.assets as a; a.example_files(); a.model_files(); a.icon_path(); "
        "bad = [m for m in ('numpy', 'PySide6', 'PIL') if m in sys.modules]; "
        "sys.exit(repr(bad) if bad else 0)"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
