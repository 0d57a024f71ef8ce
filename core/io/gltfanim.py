"""A solved sequence as one animated glTF binary (GLB): the model at rest with one morph
target per frame, and an animation of the morph weights (frame ``i`` at time ``i / rate``
has weight 1 on target ``i``, linear between frames). Blender imports it as shape keys with
their animation; any glTF viewer plays it.

A model file is animated as itself (:func:`isochor.core.io.gltf.animate_gltf`); one in
another format first becomes a GLB with its UVs, materials and colours
(:func:`model_as_glb`). :func:`animated_glb` writes a bare mesh (positions only), for a
built-in shape that has no file.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import IsochorError
from .companions import confined
from .gltf import MAX_GLB_BYTES

_FLOAT, _UINT = 5126, 5125
_ARRAY, _ELEMENTS = 34962, 34963


def animated_glb(
    vertices: np.ndarray, faces: np.ndarray, frames: Sequence[np.ndarray], rate: float
) -> bytes:
    """The GLB of ``vertices`` (v, 3) and ``faces`` (f, 3) animated through ``frames``
    (each (v, 3), the deformed vertices of one frame) at ``rate`` frames a second."""
    rest = np.asarray(vertices, dtype=np.float32)
    count = len(frames)
    size = 12 * len(rest) * (count + 1) + 12 * len(faces) + 4 * count * (count + 1)
    if size > MAX_GLB_BYTES:
        raise IsochorError(
            f"{count} frames of {len(rest)} vertices make {size / 2**30:.1f} GB, more than a "
            "GLB holds: write a sequence of files (frame_####.obj) instead"
        )
    blobs: list[bytes] = []
    views: list[dict] = []
    accessors: list[dict] = []

    def add(data, component: int, kind: str, target: int | None = None, bounds=True) -> int:
        raw = np.ascontiguousarray(data).tobytes()
        offset = sum(len(b) for b in blobs)
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(raw)}
        if target is not None:
            view["target"] = target
        views.append(view)
        blobs.append(raw + b"\0" * (-len(raw) % 4))
        acc = {
            "bufferView": len(views) - 1,
            "componentType": component,
            "count": int(data.shape[0]),
            "type": kind,
        }
        if bounds:  # POSITION and animation inputs must state them
            flat = data.reshape(len(data), -1)
            acc["min"] = [float(a) for a in flat.min(axis=0)]
            acc["max"] = [float(a) for a in flat.max(axis=0)]
        accessors.append(acc)
        return len(accessors) - 1

    tris = np.asarray(faces, dtype=np.uint32).reshape(-1)
    indices = add(tris, _UINT, "SCALAR", _ELEMENTS, bounds=False)
    position = add(rest, _FLOAT, "VEC3", _ARRAY)
    targets = [
        {"POSITION": add(np.asarray(f, dtype=np.float32) - rest, _FLOAT, "VEC3", _ARRAY)}
        for f in frames
    ]
    times = add(np.arange(count, dtype=np.float32) / np.float32(rate), _FLOAT, "SCALAR")
    weights = add(np.eye(count, dtype=np.float32).reshape(-1), _FLOAT, "SCALAR", bounds=False)
    names = [f"frame {i}" for i in range(count)]
    doc = {
        "asset": {"version": "2.0", "generator": "Isochor"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "isochor"}],
        "meshes": [
            {
                "name": "isochor",
                "primitives": [
                    {"attributes": {"POSITION": position}, "indices": indices, "targets": targets}
                ],
                "weights": [0.0] * count,
                "extras": {"targetNames": names},
            }
        ],
        "animations": [
            {
                "name": "isochor sequence",
                "samplers": [{"input": times, "output": weights, "interpolation": "LINEAR"}],
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
            }
        ],
        "buffers": [{"byteLength": sum(len(b) for b in blobs)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = b"".join(blobs)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return b"".join(
        [
            struct.pack("<4sII", b"glTF", 2, total),
            struct.pack("<I4s", len(text), b"JSON"),
            text,
            struct.pack("<I4s", len(binary), b"BIN\0"),
            binary,
        ]
    )


def model_as_glb(path: Path) -> bytes:
    """The model file (OBJ, PLY, STL, OFF) as a GLB with what glTF can carry of it: its
    positions as they are in the file, texture coordinates, materials and their images,
    vertex colours; polygons as triangles (trimesh's reader and glTF writer)."""
    import trimesh

    try:
        loaded: Any = trimesh.load(  # a scene or mesh
            str(path), process=False, maintain_order=True, resolver=_confined_resolver(path)
        )
        return bytes(loaded.export(file_type="glb"))
    except Exception as exc:  # trimesh raises anything on a file it rejects
        detail = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
        raise IsochorError(f"{path.name}: cannot write it as glTF ({detail})") from None


def _confined_resolver(path: Path):
    """trimesh's file resolver for ``path``'s material libraries and textures, confined to
    the model's folder (:func:`isochor.core.io.companions.confined`): a name leading out
    of it is not found, and never opened."""
    import trimesh.resolvers

    class Confined(trimesh.resolvers.FilePathResolver):
        def get(self, name: str) -> bytes:
            try:
                inside = confined(path.parent, name, "file", "OBJ")
            except IsochorError:
                raise FileNotFoundError(name) from None
            if not inside.is_file():
                raise FileNotFoundError(name)
            return inside.read_bytes()

    return Confined(str(path))
