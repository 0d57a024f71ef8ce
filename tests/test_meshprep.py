"""What drawing a model needs, computed off the GUI thread (app/view/meshprep.py): whether a
mesh is closed (its back faces may be culled), and the view's arrays for a model at given
nodes, the same as the view computed them itself."""

from __future__ import annotations

import numpy as np
import pytest

from isochor.app.view import meshprep
from isochor.core.scenario.shapes import torus_levels


@pytest.fixture(scope="module")
def torus():
    mesh = torus_levels(5)[-1]  # 4096 triangles, closed, wound outwards
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_a_closed_consistently_wound_mesh_is_closed(torus):
    _, faces = torus
    assert meshprep.closed(faces)
    shuffled = faces[np.random.default_rng(0).permutation(len(faces))]
    assert meshprep.closed(np.roll(shuffled, 1, axis=1))  # any order, any first corner


@pytest.mark.parametrize(
    "how",
    ["one face gone", "two faces gone", "one face flipped", "a face twice", "empty", "two tori"],
)
def test_open_or_inconsistent_meshes_are_not_closed_unless_they_are(torus, how):
    _, faces = torus
    broken = {
        "one face gone": faces[1:],
        "two faces gone": faces[2:],  # (an even count: the pairing itself must fail)
        "one face flipped": np.vstack([faces[:1, ::-1], faces[1:]]),
        "a face twice": np.vstack([faces, faces[:1], faces[:1, ::-1]]),
        "empty": faces[:0],
        "two tori": np.vstack([faces, faces + faces.max() + 1]),  # closed: two shells
    }[how]
    assert meshprep.closed(broken) is (how == "two tori")


def test_the_prepared_arrays_are_the_views_own(torus):
    """DisplayPrep (computed on a thread) gives what the view computed on the GUI thread:
    the deformed points, the normals and volume of Shading, every triangle once in the
    draw order, and the proxy's volume scale."""
    from isochor.app.editor.document import Document

    doc = Document.example()
    surface = doc.surface
    nodes = np.array(doc.state.nodes) * 1.1  # somewhere not at rest
    prep = meshprep.DisplayPrep.of(surface, nodes)
    assert prep.fits(surface, nodes) and not prep.fits(surface, nodes + 1e-9)
    points = surface.deform(nodes)
    assert np.array_equal(prep.full.points, points)
    normals, volume = meshprep.Shading(surface.full.faces, len(points), surface.center)(points)
    np.testing.assert_allclose(prep.full.normals, normals, rtol=0, atol=1e-12)
    assert prep.full.volume == pytest.approx(volume, rel=1e-12)
    cells = prep.full.cells.reshape(-1, 4)
    assert (cells[:, 0] == 3).all()
    drawn = {tuple(sorted(f)) for f in cells[:, 1:]}
    assert drawn == {tuple(sorted(f)) for f in np.asarray(surface.full.faces)}
    assert prep.full.closed
    if prep.proxy is not None:
        k = prep.proxy_k
        assert surface.levels[k].n_faces <= meshprep.PROXY_TRIANGLES
        assert np.array_equal(prep.proxy.points, surface.deform(nodes, level=k))


def test_an_open_models_caps_are_shaded_but_not_drawn_nor_culled(torus):
    """A capped open model (its last ``cap_faces`` triangles are virtual caps): the volume
    is the capped solid's, the triangles drawn (and picked) are the model's own, which are
    open, so its back faces are drawn (the inside shows through the hole)."""
    from types import SimpleNamespace

    points, faces = torus
    capped = SimpleNamespace(vertices=points, faces=faces, cap_faces=3)
    whole = SimpleNamespace(vertices=points, faces=faces)
    center = points.mean(axis=0)
    prep = meshprep.MeshPrep.of(capped, points, center)
    solid = meshprep.MeshPrep.of(whole, points, center)
    assert prep.volume == pytest.approx(solid.volume, rel=1e-12)  # the caps' volume kept
    assert np.array_equal(prep.faces, faces[:-3]) and not prep.closed and solid.closed
    assert len(prep.cells) == 4 * (len(faces) - 3) and solid.cap_cells is None
    assert np.array_equal(prep.cap_cells.reshape(-1, 4)[:, 1:], faces[-3:])
