"""glTF 2.0 (.glb, .gltf): :func:`read_gltf` gives the default scene's world-space triangles;
:func:`rewrite_gltf` writes the file back deformed, all else kept, buffers merged into one,
a copy of a mesh for each transform it is used under; :func:`animate_gltf` keeps the file and
adds one morph target per frame of a sequence with the animation of their weights. A
written file travels: a GLB embeds every image it uses, a .gltf keeps only images beside
it as separate files and embeds the others. Refused in one line naming the
file: compression, quantized or sparse vertex data, GPU instancing, a required extension it
does not support (named), damaged files."""

from __future__ import annotations

import base64
import copy
import json
import struct
import warnings
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import NoReturn, cast
from urllib.parse import unquote

import numpy as np

from ..errors import IsochorError
from ..validate import MAX_COORDINATE, input_file, show
from .companions import confined

Deform = Callable[[np.ndarray], np.ndarray]  # (k, 3) world points -> (k, 3) deformed points
Jacobian = Callable[[np.ndarray], np.ndarray]  # (k, 3) -> (k, 3, 3): d deformed_a / d x_b

MAX_BUFFER_BYTES = 2 * 2**30  # the largest external .bin file read
#: a GLB holds at most 2 GiB (its length field is 32 bits, and readers use that limit)
MAX_GLB_BYTES = 2**31 - 1
_JSON, _BIN, _FLOAT = 0x4E4F534A, 0x004E4942, 5126
_COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_DEFORMED = {"POSITION": 3, "NORMAL": 3, "TANGENT": 4}  # semantic -> components
_COMPRESSION = {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression"}
#: required extensions that change nothing Isochor reads or writes (materials, textures,
#: lights): a file requiring only these is read; any other required one is refused
_HARMLESS_PREFIX = "KHR_materials_"
_HARMLESS = {
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "KHR_lights_punctual",
    "EXT_texture_webp",
    "EXT_texture_avif",
}
_DAMAGED = (LookupError, TypeError, ValueError, AttributeError, ArithmeticError, RecursionError)


def read_gltf(
    data: bytes,
    suffix: str,
    *,
    name: str = "model",
    base_dir: Path | None = None,
    parts: list[int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World-space vertices ``(m, 3) float64`` and triangles ``(f, 3) int64`` of every
    triangle primitive (mode 4) of every mesh instance in the default scene, depth first.
    ``parts``, when given, gets the number of triangles of each mesh instance, in order
    (separate objects, never welded together)."""
    points, faces, offset = [np.zeros((0, 3))], [np.zeros((0, 3), np.int64)], 0
    with _guard(name):
        gltf = _Gltf(data, suffix, name, base_dir)
        for _node, mesh, world in gltf.instances():
            if parts is not None:
                parts.append(sum(len(f) for f in faces))
            for prim in gltf.ref("meshes", mesh)["primitives"]:
                if prim.get("mode", 4) != 4 or "POSITION" not in prim["attributes"]:
                    continue
                local = gltf.attribute(prim["attributes"], "POSITION", 3)
                tri = gltf.triangles(prim, len(local)) + offset
                faces.append(tri[:, ::-1] if np.linalg.det(world[:3, :3]) < 0 else tri)
                points.append(local @ world[:3, :3].T + world[:3, 3])
                offset += len(local)
    vertices, faces = np.concatenate(points), np.concatenate(faces)
    if parts is not None:  # (starts so far: now the triangles of each instance)
        parts[:] = np.diff([*parts, len(faces)]).tolist()
    if not len(faces):
        raise IsochorError(f"{name}: no triangles found (no triangle mesh in the default scene)")
    if not np.all(np.abs(vertices) <= MAX_COORDINATE):
        raise IsochorError(f"{name}: a vertex coordinate is not a number or beyond +-1e+15")
    return vertices, faces


def rewrite_gltf(
    data: bytes,
    suffix: str,
    deform: Deform,
    jacobian: Jacobian,
    *,
    name: str = "model",
    base_dir: Path | None = None,
    morph_target: bool = False,
    out_suffix: str | None = None,
    out_dir: Path | None = None,
) -> tuple[bytes, list[str]]:
    """The file (as ``suffix``) with the default scene deformed in world space (local ->
    world by the node's global transform, deform, back), NORMAL by the Jacobian's inverse
    transpose, TANGENT xyz by the Jacobian, renormalised, min/max updated; or, with
    ``morph_target``, as a new morph target "isochor" of weight 1; written as ``out_suffix``
    (.glb or .gltf; default: as read) into ``out_dir`` (default: ``base_dir``; separate
    images are embedded unless a .gltf is written beside them). And notes for the user, one
    sentence each."""
    with _guard(name):
        gltf = _Gltf(data, suffix, name, base_dir)
        gltf.suffix = (out_suffix or suffix).lower()  # the container written
        gltf.merge_buffers()
        jobs, notes = gltf.plan(["isochor"] if morph_target else [], 1.0)
        notes += gltf.place_images(base_dir, out_dir)
        points = np.concatenate([old["POSITION"] @ w[:3, :3].T + w[:3, 3] for _, w, old in jobs])
    moved, jac = np.asarray(deform(points), float), np.asarray(jacobian(points), float)
    if moved.shape != points.shape or jac.shape != (len(points), 3, 3):
        raise ValueError(f"deform, jacobian gave shapes {moved.shape}, {jac.shape}")
    cuts = np.cumsum([len(old["POSITION"]) for _, _, old in jobs])[:-1]
    with _guard(name):
        for (prim, world, old), y, j in zip(jobs, np.split(moved, cuts), np.split(jac, cuts)):
            new = _deformed(world, old, y, j)
            if not all(np.all(np.abs(v) <= np.finfo(np.float32).max) for v in new.values()):
                gltf.fail("the deformed vertices are not finite numbers")
            if morph_target:
                deltas = {sem: gltf.append(new[sem][:, :3] - old[sem][:, :3]) for sem in new}
                prim.setdefault("targets", []).append(deltas)
            else:
                for sem, values in new.items():
                    gltf.put(prim["attributes"], sem, values, world)
        return gltf.to_bytes(), notes


def animate_gltf(
    data: bytes,
    suffix: str,
    frames: Sequence[tuple[Deform, Jacobian]],
    rate: float,
    *,
    name: str = "model",
    base_dir: Path | None = None,
    out_dir: Path | None = None,
) -> tuple[bytes, list[str]]:
    """The file as one GLB, all of it kept (mesh, UVs, materials, skin), with one morph
    target per frame ("frame 0", ...: POSITION, NORMAL, TANGENT deltas of the default
    scene deformed by that frame's ``(deform, jacobian)``) and an animation "isochor
    sequence" of the weights: weight 1 on target ``i`` at time ``i / rate``, linear between.
    And notes for the user, one sentence each."""
    names = [f"frame {i}" for i in range(len(frames))]
    with _guard(name):
        gltf = _Gltf(data, suffix, name, base_dir)
        gltf.suffix = ".glb"
        gltf.merge_buffers()
        jobs, notes = gltf.plan(names, 0.0)
        notes += gltf.place_images(base_dir, out_dir)
        points = np.concatenate([old["POSITION"] @ w[:3, :3].T + w[:3, 3] for _, w, old in jobs])
        size = len(gltf.buffers[0]) + 4 * len(frames) * sum(
            sum(3 * len(v) for v in old.values()) for _, _, old in jobs
        )
        if size > MAX_GLB_BYTES:
            gltf.fail(
                f"{len(frames)} frames make {size / 2**30:.1f} GB, more than a GLB holds: "
                "write a sequence of files (frame_####.obj) instead"
            )
    cuts = np.cumsum([len(old["POSITION"]) for _, _, old in jobs])[:-1]
    for deform, jacobian in frames:
        moved, jac = np.asarray(deform(points), float), np.asarray(jacobian(points), float)
        if moved.shape != points.shape or jac.shape != (len(points), 3, 3):
            raise ValueError(f"deform, jacobian gave shapes {moved.shape}, {jac.shape}")
        with _guard(name):
            for (prim, world, old), y, j in zip(jobs, np.split(moved, cuts), np.split(jac, cuts)):
                new = _deformed(world, old, y, j)
                if not all(np.all(np.abs(v) <= np.finfo(np.float32).max) for v in new.values()):
                    gltf.fail("the deformed vertices are not finite numbers")
                deltas = {sem: gltf.append(new[sem][:, :3] - old[sem][:, :3]) for sem in new}
                prim.setdefault("targets", []).append(deltas)
    with _guard(name):
        gltf.animate_weights(len(frames), rate)
        return gltf.to_bytes(), notes


@contextmanager
def _guard(name: str):
    """Numpy and Python warnings silenced; a damaged file's exceptions become one line."""
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    except _DAMAGED as exc:
        detail = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
        detail = f"missing {detail}" if isinstance(exc, KeyError) else detail
        raise IsochorError(f"{name}: not a valid glTF file ({detail})") from None


class _Gltf:
    """A parsed glTF document, its buffers, and the accessor reads and writes on them."""

    def __init__(self, data: bytes, suffix: str, name: str, base_dir: Path | None):
        self.name, self.suffix = name, suffix.lower()
        # original values, transforms written, appended bytes, .bin files, outside accessors
        self.cache: dict = {}
        self.done: dict = {}
        self.extra: list = []
        self.external: list[str] = []
        self.kept: set = set()
        if self.suffix not in (".glb", ".gltf"):
            self.fail(f"not a glTF file suffix {suffix!r} (use .glb or .gltf)")
        text, binary = self._split_glb(bytes(data)) if self.suffix == ".glb" else (data, None)
        try:
            self.doc = json.loads(bytes(text).decode("utf-8-sig"))
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
            self.fail(f"not valid glTF JSON ({(str(exc).splitlines() or [repr(exc)])[0]})")
        if not isinstance(self.doc, dict):
            self.fail("not a glTF file (its JSON is not an object)")
        version = str(self.doc.get("asset", {}).get("version", ""))
        if not version.startswith("2."):
            self.fail(f"glTF version {version or '(none)'} is not supported; Isochor reads 2.0")
        used = {*self.doc.get("extensionsUsed", []), *self.doc.get("extensionsRequired", [])}
        if used & _COMPRESSION:
            self.fail("compressed meshes are not supported; export without Draco or meshopt")
        self._required(self.doc.get("extensionsRequired", []))
        buffers = self.doc.get("buffers", [])
        self._confine(base_dir)  # every URI checked before any file is read
        self.buffers = [self._buffer(i, b, binary, base_dir) for i, b in enumerate(buffers)]

    def _confine(self, base_dir: Path | None) -> None:
        """Refuse, before anything is read, a buffer or image URI that is not a data: URI
        or a relative path under the model's folder (``../../etc/passwd``, ``file:``,
        ``/abs``): a crafted model must not copy a local file into an output."""
        for kind, what in (("buffers", "buffer"), ("images", "image")):
            items = self.doc.get(kind, [])
            for item in items if isinstance(items, list) else ():
                uri = item.get("uri") if isinstance(item, dict) else None
                if uri is None or (isinstance(uri, str) and uri.startswith("data:")):
                    continue
                if not isinstance(uri, str):
                    self.fail(f"a {what} uri is not a string")
                try:
                    confined(base_dir, uri, what)
                except IsochorError as exc:
                    self.fail(str(exc))

    def _required(self, names) -> None:
        """Refuse a file that requires an extension Isochor does not read (glTF 2.0: a
        loader must not load it), naming it."""
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            self.fail("extensionsRequired is not a list of names")
        for extension in names:
            if not extension.startswith(_HARMLESS_PREFIX) and extension not in _HARMLESS:
                self.fail(
                    f"it requires the glTF extension {show(extension)}, which Isochor does "
                    "not support; export it without that extension"
                )

    def fail(self, message: str) -> NoReturn:
        raise IsochorError(f"{self.name}: {message}")

    def ref(self, kind: str, index) -> dict:
        items = self.doc.get(kind, [])
        item = items[_int(index, f"{kind} index", 0, len(items))] if type(items) is list else 0
        if not isinstance(item, dict):
            raise ValueError(f"{kind}[{show(index)}] is not an object")
        return item

    def _split_glb(self, data: bytes) -> tuple[bytes, bytes | None]:
        if len(data) < 12 or data[:4] != b"glTF":
            self.fail("not a GLB file (it does not start with 'glTF')")
        length = struct.unpack_from("<I", data, 8)[0]  # (version 2: the asset version says)
        if length > len(data):
            self.fail(f"the file is truncated: its header says {length} bytes, it has {len(data)}")
        chunks, at = [], 12
        while at + 8 <= length:
            size, kind = struct.unpack_from("<2I", data, at)
            if at + 8 + size > length:
                self.fail("the file is truncated: a chunk runs past its end")
            chunks.append((kind, data[at + 8 : at + 8 + size]))
            at += 8 + size
        if not chunks or chunks[0][0] != _JSON:
            self.fail("not a GLB file (its first chunk is not JSON)")
        return chunks[0][1], chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _BIN else None

    def _buffer(self, i: int, buf: dict, binary: bytes | None, base_dir: Path | None):
        length, uri = _int(buf["byteLength"], f"buffers[{i}].byteLength"), buf.get("uri")
        if uri is None:
            if i or binary is None:
                self.fail(f"buffer {i} has no data (no uri and no GLB binary chunk)")
            data = binary
        elif str(uri).startswith("data:"):
            data = base64.b64decode(uri.partition(",")[2], validate=True)
        elif base_dir is None:
            self.fail(f"its buffer {uri!r} is a separate file and no folder was given to find it")
        else:
            path = confined(base_dir, uri, "buffer")
            try:
                input_file(path, "buffer", MAX_BUFFER_BYTES)
                data = path.read_bytes()
            except OSError as exc:
                self.fail(f"cannot read its buffer file {uri!r} ({exc.strerror or exc})")
            self.external.append(uri)
        if len(data) < length:
            self.fail(f"buffer {i} is truncated: it has {len(data)} of its {length} bytes")
        return bytearray(data[:length])

    def merge_buffers(self) -> None:
        """All buffers as one, buffer 0; the buffer views moved along."""
        blob, starts = bytearray(), []
        for buf in self.buffers:
            blob += bytes(-len(blob) % 4)  # keeps every accessor's alignment
            starts.append(len(blob))
            blob += buf
        for i, view in enumerate(self.doc.get("bufferViews", [])):
            b = _int(view.get("buffer"), f"bufferViews[{i}].buffer", 0, len(starts))
            start = _int(view.get("byteOffset", 0), f"bufferViews[{i}].byteOffset")
            view["buffer"], view["byteOffset"] = 0, start + starts[b]
        self.buffers = [blob]

    def to_bytes(self) -> bytes:
        blob = bytes(self.buffers[0] if self.buffers else b"") + b"".join(self.extra)
        if blob:
            self.doc["buffers"] = [{"byteLength": len(blob)}]
        if self.suffix == ".gltf":
            if blob:
                data = base64.b64encode(blob).decode()
                self.doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + data
            return json.dumps(self.doc, separators=(",", ":")).encode()
        text = json.dumps(self.doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        blob += bytes(-len(blob) % 4)
        chunks = struct.pack("<2I", len(text), _JSON) + text
        chunks += struct.pack("<2I", len(blob), _BIN) + blob if blob else b""
        return b"glTF" + struct.pack("<2I", 2, 12 + len(chunks)) + chunks

    def instances(self) -> list[tuple[int, int, np.ndarray]]:
        """(node, mesh, 4x4 global transform) of the default scene's mesh instances, depth first."""
        nodes = self.doc.get("nodes", [])
        if self.doc.get("scenes"):
            roots = self.ref("scenes", self.doc.get("scene", 0)).get("nodes", [])
        else:  # no scene: every node that is nobody's child
            children = {c for n in nodes for c in n.get("children", []) if type(c) is int}
            roots = [i for i in range(len(nodes)) if i not in children]
        out, seen = [], set()
        stack = [(root, np.eye(4)) for root in reversed(roots)]
        while stack:
            index, parent = stack.pop()
            node = self.ref("nodes", index)
            if index in seen:
                raise ValueError(f"node {index} is reached twice (the hierarchy is not a tree)")
            seen.add(index)
            world = parent @ _local_matrix(node, index)
            if "mesh" in node:
                self.ref("meshes", node["mesh"])
                if "EXT_mesh_gpu_instancing" in node.get("extensions", {}):
                    self.fail("GPU instancing (EXT_mesh_gpu_instancing) is not supported")
                out.append((index, node["mesh"], world))
            stack += [(c, world) for c in reversed(node.get("children", []))]
        return out

    def plan(
        self, targets: list[str], weight: float
    ) -> tuple[list[tuple[dict, np.ndarray, dict]], list[str]]:
        """(primitive, global transform, original POSITION/NORMAL/TANGENT) to deform, and
        notes; a mesh used under several transforms is copied first, once for each. With
        ``targets`` (names), each deformed mesh gets as many new morph targets, of
        ``weight``, and :attr:`morphed` lists (mesh, its nodes) for their animation."""
        morph = bool(targets)
        self.morphed: list[tuple[dict, list[int]]] = []
        groups: dict[int, dict[bytes, tuple[np.ndarray, list[int]]]] = {}
        for node, mesh, world in self.instances():
            key = np.round(world, 9).tobytes()
            groups.setdefault(mesh, {}).setdefault(key, (world, []))[1].append(node)
        meshes, nodes = self.doc.get("meshes", []), self.doc.get("nodes", [])
        notes = [f"the buffer file {uri} is now embedded in the file" for uri in self.external]
        for i in (i for i in range(len(meshes)) if i not in groups):
            notes.append(f"mesh {_label(meshes, i)} is not in the default scene; it was kept")
            self.kept |= {a for p in meshes[i]["primitives"] for a in p["attributes"].values()}
        jobs = []
        for index, parts in groups.items():
            label, first, parts = _label(meshes, index), meshes[index], list(parts.values())
            if len(parts) > 1:
                notes.append(f"mesh {label} is used under {len(parts)} transforms; each got a copy")
            if any("skin" in nodes[n] for _, group in parts for n in group):
                notes.append(f"mesh {label} is skinned; its skeleton (the joints) was not moved")
            if not morph and any(p.get("targets") for p in first["primitives"]):
                notes.append(f"the morph targets of mesh {label} were kept as they were")
            copies = [first] + [copy.deepcopy(first) for _ in parts[1:]]  # before any change
            for k, ((world, group), mesh) in enumerate(zip(parts, copies)):
                meshes += [mesh] if k else []
                for n in group:
                    nodes[n]["mesh"] = len(meshes) - 1 if k else index
                if not abs(np.linalg.det(world[:3, :3])) > 0:
                    self.fail(f"a node of mesh {label} has a zero scale; it cannot be deformed")
                for prim in mesh["primitives"]:
                    attributes = prim["attributes"]
                    sems = [s for s in _DEFORMED if s in attributes]
                    old = {s: self.attribute(attributes, s, _DEFORMED[s]) for s in sems}
                    jobs += [(prim, world, old)] if "POSITION" in old else []
                if morph:
                    self._add_weight(mesh, group, label, targets, weight)
                    self.morphed.append((mesh, group))
        if not jobs:
            self.fail("no mesh in the default scene to deform")
        return jobs, notes

    def _add_weight(
        self, mesh: dict, group: list[int], label: str, targets: list[str], weight: float
    ) -> None:
        """``weight`` for the new targets in the mesh's and nodes' weights; named ``targets``."""
        before = len(mesh["primitives"][0].get("targets", [])) if mesh["primitives"] else 0
        animated = [c["target"] for a in self.doc.get("animations", []) for c in a["channels"]]
        if any(t.get("path") == "weights" and t.get("node") in group for t in animated):
            self.fail(f"mesh {label}'s morph weights are animated; deform its vertices instead")
        weights, extras = mesh.get("weights"), mesh.setdefault("extras", {})
        known = isinstance(weights, list) and len(weights) == before
        mesh["weights"] = [
            *(cast(list, weights) if known else [0.0] * before),
            *[weight] * len(targets),
        ]
        for node in (self.doc["nodes"][n] for n in group if "weights" in self.doc["nodes"][n]):
            node["weights"] = [*node["weights"], *[weight] * len(targets)]
        if isinstance(extras, dict):
            names = extras.get("targetNames")
            known = isinstance(names, list) and len(names) == before
            extras["targetNames"] = [
                *(cast(list, names) if known else ["target"] * before),
                *targets,
            ]

    def animate_weights(self, count: int, rate: float) -> None:
        """An animation "isochor sequence" of the last ``count`` morph targets of every
        morphed mesh: at time ``i / rate`` weight 1 on the ``i``-th, the others as the
        mesh's defaults; linear between."""
        times = np.arange(count, dtype=np.float32)[:, None] / np.float32(rate)
        samplers, channels = [], []
        for mesh, group in self.morphed:
            rest = np.asarray(mesh["weights"][: len(mesh["weights"]) - count], np.float32)
            keys = np.hstack([np.tile(rest, (count, 1)), np.eye(count, dtype=np.float32)])
            samplers.append(
                {"input": self.append(times, scalar=True), "interpolation": "LINEAR"}
                | {"output": self.append(keys.reshape(-1, 1), scalar=True)}
            )
            channels += [
                {"sampler": len(samplers) - 1, "target": {"node": n, "path": "weights"}}
                for n in group
            ]
        animation = {"name": "isochor sequence", "samplers": samplers, "channels": channels}
        self.doc.setdefault("animations", []).append(animation)

    def place_images(self, base_dir: Path | None, out_dir: Path | None) -> list[str]:
        """Images that are separate files, so that the written file travels: a GLB embeds
        every one (a buffer view of its binary chunk); a .gltf written beside them keeps
        pointing at them, one written elsewhere embeds them (in its buffer, itself a data
        URI). Notes naming what was done."""
        images = [i for i in self.doc.get("images", []) if isinstance(i, dict)]
        files = [i for i in images if isinstance(i.get("uri"), str) and ":" not in i["uri"]]
        if not files:
            return []
        beside = out_dir is None or (base_dir is not None and _same_dir(base_dir, out_dir))
        if base_dir is None or (self.suffix == ".gltf" and beside):
            names = ", ".join(i["uri"] for i in files)
            return [f"the images {names} stay separate files beside it"]
        embedded, missing = [], []
        for image in files:
            path = confined(base_dir, image["uri"], "image")  # (checked when it was read)
            try:
                input_file(path, "image", MAX_BUFFER_BYTES)
                data = path.read_bytes()
            except (OSError, IsochorError):
                missing.append(unquote(image["uri"]))
                continue
            del image["uri"]
            image["bufferView"] = self._view(data)
            image["mimeType"] = _mime(data, path.suffix)
            embedded.append(path.name)
        notes = [f"the images {', '.join(embedded)} are embedded in it"] if embedded else []
        if missing:
            notes.append(
                f"warning: the images {', '.join(missing)} cannot be read, so they are not in "
                "it; it still refers to them by name"
            )
        return notes

    def _view(self, data: bytes) -> int:
        """A new buffer view holding ``data``, appended to buffer 0 at a 4-byte boundary."""
        size = (len(self.buffers[0]) if self.buffers else 0) + sum(len(b) for b in self.extra)
        self.extra += [bytes(-size % 4), bytes(data)]
        views = self.doc.setdefault("bufferViews", [])
        views.append({"buffer": 0, "byteOffset": size + -size % 4, "byteLength": len(data)})
        return len(views) - 1

    def _window(self, index, vertex: bool) -> tuple[np.ndarray, np.dtype]:
        """An accessor's bytes, ``(count, element size)`` uint8 strided, and its type."""
        acc = self.ref("accessors", index)
        ctype, kind = acc.get("componentType"), acc.get("type")
        if ctype not in _COMPONENTS or kind not in _WIDTH:
            raise ValueError(f"accessors[{index}] has an unknown componentType or type")
        if "sparse" in acc or "bufferView" not in acc:
            self.fail(f"sparse or data-less accessors (accessors[{index}]) are not supported")
        dtype, count = np.dtype(_COMPONENTS[ctype]), _int(acc.get("count"), "count", 1)
        size = dtype.itemsize * _WIDTH[kind]
        view = self.ref("bufferViews", acc["bufferView"])
        buffer = self.buffers[_int(view.get("buffer"), "buffer", 0, len(self.buffers))]
        start, length = (_int(view.get(key, 0), key) for key in ("byteOffset", "byteLength"))
        offset = _int(acc.get("byteOffset", 0), "byteOffset")
        step = (_int(view.get("byteStride", 0), "byteStride") if vertex else 0) or size
        need = step * (count - 1) + size
        if step < size or start + length > len(buffer) or offset + need > length:
            raise ValueError(f"accessors[{index}] is out of the range of its buffer")
        base = np.frombuffer(buffer, np.uint8, count=need, offset=start + offset)
        return np.lib.stride_tricks.as_strided(base, (count, size), (step, 1)), dtype

    def read(self, index, vertex: bool = True) -> np.ndarray:
        """An accessor's original values ``(count, width)`` in its own type."""
        if index not in self.cache:
            window, dtype = self._window(index, vertex)
            self.cache[index] = window.copy().view(dtype)
        return self.cache[index]

    def attribute(self, attributes: dict, sem: str, width: int) -> np.ndarray:
        """A float vertex attribute as float64 ``(count, width)``."""
        values = self.read(attributes[sem])
        if values.dtype != np.float32 or values.shape[1] != width:
            self.fail(f"quantized or non-float {sem} data (KHR_mesh_quantization) is not supported")
        return values.astype(np.float64)

    def triangles(self, prim: dict, count: int) -> np.ndarray:
        plain = np.arange(count, dtype=np.uint32)[:, None]
        idx = self.read(prim["indices"], False) if "indices" in prim else plain
        if idx.dtype.kind != "u" or idx.shape[1] != 1 or len(idx) % 3:
            raise ValueError("a primitive's indices are not unsigned integers, three a triangle")
        if len(idx) and idx.max() >= count:
            self.fail("a triangle refers to a vertex that does not exist")
        return idx.astype(np.int64).reshape(-1, 3)

    def append(self, values: np.ndarray, like: dict | None = None, scalar: bool = False) -> int:
        """A new float accessor holding ``values`` (tightly packed, appended to buffer 0),
        ``(k, 1)`` values as SCALAR with ``scalar``."""
        data = np.ascontiguousarray(values, "<f4")
        view = self._view(data.tobytes())
        accessors = self.doc.setdefault("accessors", [])
        accessors.append({k: like[k] for k in ("name", "extras") if like and k in like})
        accessors[-1] |= {"bufferView": view, "componentType": _FLOAT, "count": len(data)}
        kind = "SCALAR" if scalar else f"VEC{data.shape[1]}"
        accessors[-1] |= {"type": kind, "min": data.min(0).tolist()}
        accessors[-1]["max"] = data.max(0).tolist()
        return len(accessors) - 1

    def put(self, attributes: dict, sem: str, values: np.ndarray, world: np.ndarray) -> None:
        """New values: in place, or a new accessor if shared with another transform or mesh."""
        index, acc = attributes[sem], self.ref("accessors", attributes[sem])
        written = self.done.get(index, None if index in self.kept else world)
        if written is None or not np.allclose(written, world, rtol=1e-12, atol=1e-12):
            attributes[sem] = self.append(values, acc)
        elif index not in self.done:
            self.done[index] = world
            window, dtype = self._window(index, True)
            window[...] = np.ascontiguousarray(values, dtype).view(np.uint8)
            if sem == "POSITION" or "min" in acc:
                stored = values.astype(np.float32)
                acc["min"], acc["max"] = stored.min(0).tolist(), stored.max(0).tolist()


def _deformed(world: np.ndarray, old: dict, moved: np.ndarray, jac: np.ndarray) -> dict:
    """New local POSITION, NORMAL, TANGENT from the deformed world points and Jacobian."""
    lin, move, inv = world[:3, :3], world[:3, 3], np.linalg.inv(world[:3, :3])
    new = {"POSITION": (moved - move) @ inv.T}
    local = inv @ jac @ lin  # the Jacobian in the local frame
    if "NORMAL" in old:  # cof(J) = det(J) J^-T, defined where J is singular too
        c0, c1, c2 = local[:, :, 0], local[:, :, 1], local[:, :, 2]
        cof = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=-1)
        sign = np.where(np.einsum("pa,pa->p", c0, cof[:, :, 0]) < 0, -1.0, 1.0)
        new["NORMAL"] = _unit(np.einsum("pab,pb->pa", cof, old["NORMAL"]) * sign[:, None])
    if "TANGENT" in old:
        turned = _unit(np.einsum("pab,pb->pa", local, old["TANGENT"][:, :3]))
        new["TANGENT"] = np.column_stack([turned, old["TANGENT"][:, 3]])
    return new


#: an embedded image's type, by its first bytes (glTF's two core types), else its suffix
_MAGIC = {b"\x89PNG\r\n\x1a\n": "image/png", b"\xff\xd8\xff": "image/jpeg"}
_SUFFIX_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
_SUFFIX_MIME |= {".webp": "image/webp", ".ktx2": "image/ktx2"}


def _mime(data: bytes, suffix: str) -> str:
    for magic, mime in _MAGIC.items():
        if data.startswith(magic):
            return mime
    return _SUFFIX_MIME.get(suffix.lower(), "application/octet-stream")


def _same_dir(a: Path, b: Path) -> bool:
    try:
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False


def _int(value, what: str, least: int = 0, below: int | None = None) -> int:
    if type(value) is not int or value < least or (below is not None and value >= below):
        raise ValueError(f"{what} {show(value)} is out of range")
    return value


def _numbers(values, n: int, what: str) -> np.ndarray:
    out = np.asarray(values, dtype=np.float64) if isinstance(values, list) else np.zeros(0)
    if out.shape != (n,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{what} must be {n} finite numbers")
    return out


def _local_matrix(node: dict, index: int) -> np.ndarray:
    """A node's transform: its column-major ``matrix``, or T * R * S."""
    if "matrix" in node:
        return _numbers(node["matrix"], 16, f"nodes[{index}].matrix").reshape(4, 4).T
    q = _numbers(node.get("rotation", [0.0, 0.0, 0.0, 1.0]), 4, f"nodes[{index}].rotation")
    (x, y, z), w = q[:3] / np.linalg.norm(q), q[3] / np.linalg.norm(q)
    cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    rotation = (w * w - x * x - y * y - z * z) * np.eye(3) + 2 * np.outer([x, y, z], [x, y, z])
    scale = _numbers(node.get("scale", [1.0] * 3), 3, f"nodes[{index}].scale")
    move = _numbers(node.get("translation", [0.0] * 3), 3, f"nodes[{index}].translation")
    return np.block([[(rotation + 2 * w * cross) * scale, move[:, None]], [np.eye(4)[3]]])


def _label(meshes: list, index: int) -> str:
    return show(meshes[index].get("name", index))


def _unit(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, length, out=v.copy(), where=length > 0)
