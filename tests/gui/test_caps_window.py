"""The window opens an open model (the Stanford bunny with the holes in its base): it says
how many holes were capped, draws the model's own triangles, and shows the caps on demand
(View > Show Caps over Holes)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from tests.gui.conftest import wait_idle
from tests.models import model


def _shot(win, name: str) -> np.ndarray:
    """The 3D view as an (h, w, 3) array (and a PNG in $ISOCHOR_SHOTS, or /tmp)."""
    from PySide6.QtGui import QImage

    win.session.flush()
    win.viewport.update()
    img = win.viewport.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    folder = Path(os.environ.get("ISOCHOR_SHOTS", "/tmp"))
    folder.mkdir(parents=True, exist_ok=True)
    img.save(str(folder / f"{name}.png"))
    w, h = img.width(), img.height()
    buf = np.frombuffer(img.constBits(), dtype=np.uint8, count=img.bytesPerLine() * h)
    return buf.reshape(h, img.bytesPerLine())[:, : 3 * w].reshape(h, w, 3).copy()


def _blue(pixels: np.ndarray) -> int:
    """Pixels of the caps' sky blue over the clay (blue well above red)."""
    r, g, b = (pixels[..., c].astype(int) for c in range(3))
    return int(np.count_nonzero((b > r + 40) & (b > 90)))


def test_the_bunny_with_holes_opens_and_shows_its_caps_on_demand(qtbot, window):
    path = model("stanford_bunny.obj")
    win = window
    messages: list[str] = []
    win.statusBar().messageChanged.connect(messages.append)
    assert win.files.open_path(path, background=True)
    qtbot.waitUntil(lambda: not win.files.loading(), timeout=120_000)
    wait_idle(qtbot, win, timeout=120_000)
    assert win.doc.title == path.name
    full = win.state.surface.full
    assert full.cap_vertices == 5 and full.cap_faces == 223
    assert any("Capped 5 hole(s)" in m for m in messages), messages
    model_view = win.viewport.scene.model
    assert model_view.has_caps and model_view.full.n_faces == full.own_faces
    # the camera looks at the base, where the holes are
    win.action_set.views["bottom"].trigger()  # View > Bottom
    hidden = _shot(win, "bunny_caps_hidden")
    assert not model_view.full.caps.actor.GetVisibility()
    # View > Show Caps over Holes
    assert win.action_set.caps.isCheckable() and not win.action_set.caps.isChecked()
    win.action_set.caps.trigger()
    assert model_view.full.caps.actor.GetVisibility()
    shown = _shot(win, "bunny_caps_shown")
    assert _blue(shown) > _blue(hidden) + 200  # the caps are on screen now
    win.action_set.caps.trigger()
    assert not model_view.full.caps.actor.GetVisibility()
    # the volume shown is the capped solid's: the one the solver keeps
    assert model_view.volume == pytest.approx(win.state.surface.rest_volume, rel=1e-3)


def test_the_cup_example_opens_solves_and_shows_its_cap(qtbot, window):
    from isochor import assets

    win = window
    assert win.files.open_example(assets.example_files()["cup-squeeze"])
    wait_idle(qtbot, win)
    assert win.state.converged and win.state.moved.any()
    full = win.state.surface.full
    assert full.cap_vertices == 1
    model_view = win.viewport.scene.model
    win.action_set.views["top"].trigger()
    hidden = _shot(win, "cup_cap_hidden")
    win.action_set.caps.trigger()
    shown = _shot(win, "cup_cap_shown")
    assert _blue(shown) > _blue(hidden) + 500  # the rim's cap covers the opening
    assert model_view.volume == pytest.approx(win.state.surface.rest_volume, rel=1e-3)


def test_the_bunnys_proxy_hides_its_caps_too():
    """While a big open model moves, the window draws a coarser level, simplified from the
    capped solid: the triangles there that simplify the caps are not drawn with the model."""
    from isochor.app.view.modelview import capped_last
    from isochor.core.io.meshio import load_mesh
    from isochor.core.solve.pyramid import build_pyramid

    loaded = load_mesh(model("stanford_bunny.obj"))
    levels = build_pyramid(loaded.mesh, bodies=loaded.bodies)
    coarse = capped_last(levels[-2], levels[-1])
    assert 0 < coarse.cap_faces < 0.05 * coarse.n_faces  # the caps are 2.2% of the area
    assert coarse.n_faces == levels[-2].n_faces
    # the triangles set apart cover about what the full mesh's caps cover
    from isochor.core.io.caps import areas, summary

    apart = areas(coarse.vertices, coarse.faces)[coarse.own_faces :].sum()
    assert 0.5 < apart / summary(loaded.mesh).cap_area < 1.5
