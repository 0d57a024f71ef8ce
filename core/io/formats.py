"""The file formats Isochor reads and writes, by file name suffix: their one owner.

Models are read from and written as OBJ, PLY, STL, OFF and glTF (.glb binary, .gltf text);
scenarios are JSON. Everything that decides by suffix (the reader, the writer, the command line, the
window's file dialogs, files dropped on the view) asks here.
"""

from __future__ import annotations

from pathlib import Path

#: model suffix -> file type
READ_FORMATS: dict[str, str] = {
    ".obj": "obj",
    ".ply": "ply",
    ".stl": "stl",
    ".off": "off",
    ".glb": "glb",
    ".gltf": "gltf",
}
#: suffixes of the deformed meshes Isochor writes
WRITE_FORMATS: tuple[str, ...] = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
#: the glTF containers (one format, binary or text)
GLTF_FORMATS: tuple[str, ...] = (".glb", ".gltf")
#: suffixes of scenario documents
SCENARIO_SUFFIXES: tuple[str, ...] = (".json",)


def listing(suffixes) -> str:
    """``"OBJ, PLY, STL"`` for ``(".obj", ".ply", ".stl")``."""
    return ", ".join(s[1:].upper() for s in suffixes)


def is_model(path: str | Path) -> bool:
    """True when ``path`` names a model file Isochor reads (by its suffix)."""
    return Path(path).suffix.lower() in READ_FORMATS


def is_scenario(path: str | Path) -> bool:
    """True when ``path`` names a scenario document (by its suffix)."""
    return Path(path).suffix.lower() in SCENARIO_SUFFIXES
