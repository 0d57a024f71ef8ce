"""The scene's problem as an Isochor scenario (File > Export, the panel's "Export
Scenario"): the meshes as they enter the Lattice modifier, written as one OBJ in the
lattice object's space, and a scenario JSON beside it that names it, with Blender's lattice
(points, interpolation, "outside", the rest grid as the frame), the pinned points (moved
ones as ``to`` moves), the volume ratio and how the volumes count. ``isochor solve`` and the
editor window open it and solve the same problem the add-on solves (free points from their
rest place, as a scenario has them)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .scene import Target
from .solving import Settings, check_pins


def obj_text(vertices: np.ndarray, faces: np.ndarray) -> str:
    """An OBJ of triangles, the coordinates to the last bit (17 digits)."""
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in np.asarray(vertices, float)]
    lines += [f"f {a} {b} {c}" for a, b, c in np.asarray(faces, np.int64) + 1]
    return "# the meshes under the lattice, in the lattice object's space\n" + "\n".join(lines)


def write_scenario(target: Target, settings: Settings, path: str | Path) -> tuple[Path, Path]:
    """Write the scenario to ``path`` (``.json``) and its model beside it (the same name,
    ``.obj``); returns both paths. Either is written whole or not at all."""
    from isochor.core.io.atomic import atomic_write_text

    path = Path(path).with_suffix(".json")
    model = path.with_suffix(".obj")
    rig = target.rig(settings.pins, settings.group)
    rig.preserve = settings.preserve
    check_pins(rig)
    session = rig.session(settings.ratio)
    atomic_write_text(model, obj_text(rig.vertices, rig.faces) + "\n")
    session.scenario().with_(model={"path": str(model.resolve())}).write(path)
    return path, model
