"""The files Isochor ships: sample models, the paper's example scenarios and the icon.

- ``torus.obj``: the built-in torus (major radius 1, minor radius 0.4, axis z) at its level
  with 4096 triangles, outward wound;
- ``club.obj``: the paper's rounded club at its level with 5120 triangles, outward wound;
- ``cup.obj``: the built-in open cup at its level with 4032 triangles: one sheet open at
  its rim (Isochor caps the rim virtually, and keeps the capacity under it);
- ``examples/<name>.json``: one scenario file per built-in example of
  :data:`isochor.core.scenario.examples.EXAMPLES` (they name the built-in models,
  ``{"builtin": ...}``);
- ``icon.png``: the 256x256 application icon.

All of them are generated, byte for byte reproducibly, by ``make_assets.py`` next to this
file; after changing a built-in shape, an example or the icon, regenerate them with::

    python assets/make_assets.py          # or: python -m isochor.assets.make_assets

This module only names the files (no numpy, no Qt): the window and the tests use it.
"""

from __future__ import annotations

from pathlib import Path

#: The folder of the shipped files (this package's folder).
ASSETS_DIR: Path = Path(__file__).resolve().parent

#: The example names, in the order of :data:`isochor.core.scenario.examples.EXAMPLES` (kept as a
#: literal so this module does not import numpy; a test checks that the two agree).
EXAMPLE_NAMES: tuple[str, ...] = (
    "torus-compression",
    "torus-stretch",
    "club-compression",
    "club-bend",
    "cup-squeeze",
)

#: Sample model name -> file name in :data:`ASSETS_DIR`.
MODEL_FILES: dict[str, str] = {"torus": "torus.obj", "club": "club.obj", "cup": "cup.obj"}

#: The sub-folder of the example scenarios, and the icon's file name.
EXAMPLES_SUBDIR = "examples"
ICON_FILE = "icon.png"

__all__ = [
    "ASSETS_DIR",
    "EXAMPLES_SUBDIR",
    "EXAMPLE_NAMES",
    "ICON_FILE",
    "MODEL_FILES",
    "example_files",
    "icon_path",
    "model_files",
]


def example_files() -> dict[str, Path]:
    """Example name -> its scenario file (``examples/<name>.json``), in the order of
    :data:`isochor.core.scenario.examples.EXAMPLES`."""
    return {name: ASSETS_DIR / EXAMPLES_SUBDIR / f"{name}.json" for name in EXAMPLE_NAMES}


def model_files() -> dict[str, Path]:
    """Sample model name -> its OBJ file: ``{"torus": .../torus.obj, "club": .../club.obj}``."""
    return {name: ASSETS_DIR / file for name, file in MODEL_FILES.items()}


def icon_path() -> Path:
    """The 256x256 PNG application icon."""
    return ASSETS_DIR / ICON_FILE
