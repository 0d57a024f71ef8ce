"""Seeded damage to model files and scenario documents, for the fuzz test (tests/test_fuzz.py).

Every mutator takes a ``random.Random`` and the data, and returns the damaged data with a
short description of what it did (or ``None`` when it does not apply to that format), so a
failing case can be told and reproduced from the seed and its index alone.

Base models are small (a box and an icosphere) in every format Isochor reads: OBJ, binary
and ASCII PLY, binary and ASCII STL, OFF. Base scenarios are small valid scenarios on those
models and on the built-in shapes (at most 3 levels, 2x2x2 or 3x2x2 lattices).
"""

from __future__ import annotations

import json
import random
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from isochor.core.io.meshio import mesh_bytes
from isochor.core.mesh import TriMesh
from tests.models import box, icosphere


# -- base models --------------------------------------------------------------------------
def ascii_ply(mesh: TriMesh) -> bytes:
    v, f = mesh.vertices, mesh.faces
    head = (
        "ply\nformat ascii 1.0\ncomment written by hand for the fuzz test\n"
        f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = [f"{a!r} {b!r} {c!r}" for a, b, c in v.tolist()]
    rows += [f"3 {a} {b} {c}" for a, b, c in f.tolist()]
    return (head + "\n".join(rows) + "\n").encode("ascii")


def ascii_stl(mesh: TriMesh) -> bytes:
    out = ["solid fuzz"]
    for tri in mesh.vertices[mesh.faces]:
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        n = n / (np.linalg.norm(n) or 1.0)
        out.append(f"  facet normal {n[0]:.9g} {n[1]:.9g} {n[2]:.9g}")
        out.append("    outer loop")
        out += [f"      vertex {p[0]:.17g} {p[1]:.17g} {p[2]:.17g}" for p in tri]
        out += ["    endloop", "  endfacet"]
    out.append("endsolid fuzz")
    return ("\n".join(out) + "\n").encode("ascii")


def off(mesh: TriMesh) -> bytes:
    v, f = mesh.vertices, mesh.faces
    rows = ["OFF", f"{len(v)} {len(f)} 0"]
    rows += [f"{a!r} {b!r} {c!r}" for a, b, c in v.tolist()]
    rows += [f"3 {a} {b} {c}" for a, b, c in f.tolist()]
    return ("\n".join(rows) + "\n").encode("ascii")


#: format name -> (file suffix, writer)
FORMATS: dict[str, tuple[str, Callable[[TriMesh], bytes]]] = {
    "obj": (".obj", lambda m: mesh_bytes(m, ".obj")),
    "ply-binary": (".ply", lambda m: mesh_bytes(m, ".ply")),
    "ply-ascii": (".ply", ascii_ply),
    "stl-binary": (".stl", lambda m: mesh_bytes(m, ".stl")),
    "stl-ascii": (".stl", ascii_stl),
    "off": (".off", off),
}

#: shape name -> mesh (small: 12 and 320 triangles)
SHAPES: dict[str, Callable[[], TriMesh]] = {
    "box": lambda: box((1.0, 2.0, 0.5)),
    "icosphere": lambda: icosphere(2),
}


def base_model(shape: str, fmt: str) -> tuple[bytes, str, TriMesh]:
    """(file bytes, suffix, mesh) of a base model."""
    mesh = SHAPES[shape]()
    suffix, write = FORMATS[fmt]
    return write(mesh), suffix, mesh


# -- model mutators -----------------------------------------------------------------------
#: what a number token in a model file is replaced with
NUMBER_TOKENS: list[bytes] = [
    b"1e308",
    b"-1e308",
    b"nan",
    b"inf",
    b"1e-320",
    b"0",
    b"99999999999999999999",
    b"7" * 400,
    b"-",
    b"",
]

_NUMBER = re.compile(rb"(?<![\w.+-])[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?(?![\w.])")


@dataclass
class ModelCase:
    fmt: str
    data: bytes
    mesh: TriMesh  # the unmutated mesh (vertex and face counts)


def _ply_split(data: bytes) -> tuple[bytes, bytes] | None:
    at = data.find(b"end_header\n")
    if at < 0:
        return None
    at += len(b"end_header\n")
    return data[:at], data[at:]


def flip_bytes(rng: random.Random, case: ModelCase):
    data = bytearray(case.data)
    if not data:
        return None
    k = rng.randint(1, 8)
    spots = sorted(rng.randrange(len(data)) for _ in range(k))
    for at in spots:
        data[at] ^= rng.randint(1, 255)
    return bytes(data), f"flip bytes at {spots}"


def truncate(rng: random.Random, case: ModelCase):
    at = rng.randrange(len(case.data)) if case.data else 0
    return case.data[:at], f"truncate to {at} of {len(case.data)} bytes"


def duplicate_line(rng: random.Random, case: ModelCase):
    lines = case.data.split(b"\n")
    i = rng.randrange(len(lines))
    lines.insert(i, lines[i])
    return b"\n".join(lines), f"duplicate line {i} ({lines[i][:40]!r})"


def delete_line(rng: random.Random, case: ModelCase):
    lines = case.data.split(b"\n")
    i = rng.randrange(len(lines))
    gone = lines.pop(i)
    return b"\n".join(lines), f"delete line {i} ({gone[:40]!r})"


def replace_number(rng: random.Random, case: ModelCase):
    """A number token of the text (the header only, for binary PLY) becomes an edge value."""
    if case.fmt == "stl-binary":
        return None
    data, tail = case.data, b""
    if case.fmt == "ply-binary":
        parts = _ply_split(data)
        if parts is None:
            return None
        data, tail = parts
    spots = list(_NUMBER.finditer(data))
    if not spots:
        return None
    hit = rng.choice(spots)
    new = rng.choice(NUMBER_TOKENS)
    data = data[: hit.start()] + new + data[hit.end() :]
    return data + tail, f"number {hit.group()!r} at byte {hit.start()} -> {new[:30]!r}"


def _bad_indices(n_vertices: int) -> list[int]:
    # OBJ is 1-based and counts negative indices from the end: 0 and -(n+5) are both bad
    return [n_vertices, n_vertices + 1, n_vertices + 1000, 0, -1, -(n_vertices + 5), 2**31, 10**20]


def bad_face_index(rng: random.Random, case: ModelCase):
    """A face refers to a vertex that does not exist (or to index 0 / a negative one)."""
    nv, nf = case.mesh.n_vertices, case.mesh.n_faces
    value = rng.choice(_bad_indices(nv))
    corner = rng.randrange(3)
    if case.fmt in ("obj", "off", "ply-ascii"):
        lines = case.data.split(b"\n")
        if case.fmt == "obj":
            rows = [i for i, s in enumerate(lines) if s.startswith(b"f ")]
        elif case.fmt == "off":
            rows = list(range(2 + nv, 2 + nv + nf))
        else:
            if b"end_header" not in lines:
                return None
            start = lines.index(b"end_header") + 1
            rows = list(range(start + nv, start + nv + nf))
        # earlier mutations may have moved the lines: only rows that still look like faces
        rows = [i for i in rows if i < len(lines) and len(lines[i].split()) >= 4]
        if not rows:
            return None
        i = rng.choice(rows)
        tokens = lines[i].split()
        tokens[1 + corner] = str(value).encode()
        lines[i] = b" ".join(tokens)
        return b"\n".join(lines), f"face line {i}: corner {corner} -> {value}"
    if case.fmt == "ply-binary":
        value = rng.choice([nv, nv + 1000, -1, -(2**31), 2**31 - 1])
        row = rng.randrange(nf)
        at = len(case.data) - nf * 13 + row * 13 + 1 + 4 * corner
        if at < 0 or at + 4 > len(case.data):
            return None
        data = case.data[:at] + struct.pack("<i", value) + case.data[at + 4 :]
        return data, f"binary face {row}: corner {corner} -> {value}"
    return None


def ply_header_count(rng: random.Random, case: ModelCase):
    if not case.fmt.startswith("ply"):
        return None
    spots = list(re.finditer(rb"element (vertex|face) (\d+)", case.data))
    if not spots:
        return None
    hit = rng.choice(spots)
    n = int(hit.group(2))
    new = rng.choice([0, 1, n - 1, n + 1, 2 * n, 2**31 - 1, 2**32 + n, 10**20, -1])
    data = case.data[: hit.start(2)] + str(new).encode() + case.data[hit.end(2) :]
    return data, f"PLY header: element {hit.group(1).decode()} {n} -> {new}"


def stl_triangle_count(rng: random.Random, case: ModelCase):
    if case.fmt != "stl-binary" or len(case.data) < 84:
        return None
    n = case.mesh.n_faces
    new = rng.choice([0, 1, n - 1, n + 1, 2 * n, 2**31, 2**32 - 1])
    data = case.data[:80] + struct.pack("<I", new) + case.data[84:]
    return data, f"binary STL triangle count {n} -> {new}"


MODEL_MUTATORS: list[Callable[[random.Random, ModelCase], tuple[bytes, str] | None]] = [
    flip_bytes,
    truncate,
    duplicate_line,
    delete_line,
    replace_number,
    replace_number,  # the richest one: twice the weight
    bad_face_index,
    ply_header_count,
    stl_triangle_count,
]


def mutate_model(rng: random.Random) -> tuple[str, bytes, str]:
    """A damaged base model: (suffix, file bytes, description)."""
    shape = rng.choice(sorted(SHAPES))
    fmt = rng.choice(list(FORMATS))
    data, suffix, mesh = base_model(shape, fmt)
    done = [f"{shape} as {fmt}"]
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        case = ModelCase(fmt, data, mesh)
        for _attempt in range(20):
            got = rng.choice(MODEL_MUTATORS)(rng, case)
            if got is not None:
                data, what = got
                done.append(what)
                break
    return suffix, data, "; ".join(done)


# -- base scenarios -----------------------------------------------------------------------
def base_scenario(rng: random.Random) -> tuple[dict[str, Any], dict[str, bytes], str]:
    """A small valid scenario: (document, model files to write next to it, description)."""
    nodes = rng.choice([[3, 2, 2], [2, 2, 2]])
    files: dict[str, bytes] = {}
    kind = rng.choice(["torus", "sphere", "club", "file", "file"])
    if kind == "file":
        shape = rng.choice(sorted(SHAPES))
        fmt = rng.choice(list(FORMATS))
        data, suffix, _ = base_model(shape, fmt)
        name = f"{shape}{suffix}"
        files[name] = data
        model = {"path": name}
        what = f"{shape} as {fmt}"
        size = 2.0  # both base models are about 2 across
    else:
        model = {"builtin": kind, "n_levels": rng.randint(1, 3)}
        what = f"builtin {kind}"
        size = 3.0 if kind != "sphere" else 2.0
    doc: dict[str, Any] = {
        "format": "isochor-scenario",
        "version": 1,
        "model": model,
        "lattice": {"nodes": nodes, "padding": 0.05},
        "moves": [{"node": [0, 0, 0], "by": [0.1 * size, 0.0, 0.05 * size]}],
        "pins": [],
        "target_volume_ratio": 1.0,
        "tolerance": {"volume": 0.0005, "nodes": 0.001},
    }
    if nodes[0] == 3:
        doc["moves"].append({"node": [2, 1, 1], "to": [size, 0.6 * size, 0.4 * size]})
        doc["pins"].append([1, 0, 0])
    if rng.random() < 0.3:
        doc["target_volume_ratio"] = rng.choice([0.8, 1.2])
    return doc, files, f"{what}, lattice {nodes}"


def model_doc_for(name: str, rng: random.Random) -> str:
    """A valid scenario (JSON text) on the model file ``name`` (a base model: about 2 units
    across), for the damaged-model cases."""
    nodes = rng.choice([[3, 2, 2], [2, 2, 2]])
    doc = {
        "format": "isochor-scenario",
        "version": 1,
        "model": {"path": name},
        "lattice": {"nodes": nodes, "padding": 0.05},
        "moves": [{"node": [0, 0, 0], "by": [0.2, 0.0, 0.1]}],
        "pins": [[1, 1, 1]] if nodes[0] == 3 else [],
    }
    return json.dumps(doc, indent=1)


# -- scenario mutators --------------------------------------------------------------------
#: values a scenario value is replaced with: every JSON type and the numbers at the edges
RANDOM_VALUES: list[Any] = [
    "x",
    "",
    "\u0000",
    [],
    [1, 2, 3],
    [[0, 0, 0]],
    {},
    {"a": 1},
    None,
    True,
    False,
    10**30,
    2**64,
    -(2**64),
    2**63 - 1,
    1e308,
    -1e308,
    5e-324,
    1e-300,
    0,
    0.0,
    -0.0,
    -1,
]

#: raw JSON text put where a value was
RAW_TOKENS: list[str] = [
    "Infinity",
    "-Infinity",
    "NaN",
    "1e999",
    "-1e999",
    "9" * 5000,
    "1." + "0" * 5000,
    "[" * 100000 + "]" * 100000,
    "[" * 100000,
    '{"a":' * 100000 + "1" + "}" * 100000,
]


@dataclass
class Doc:
    """A scenario under mutation: the document and raw texts its sentinels stand for."""

    doc: Any
    raw: dict[str, str] = field(default_factory=dict)

    def sentinel(self, text: str) -> str:
        key = f"@@RAW{len(self.raw)}@@"
        self.raw[key] = text
        return key

    def text(self) -> str:
        out = json.dumps(self.doc, indent=1)
        for key, text in self.raw.items():
            out = out.replace(json.dumps(key), text)
        return out


def _spots(obj: Any, path: tuple = ()) -> list[tuple[tuple, Any, Any]]:
    """Every (path, container, key) below ``obj``."""
    out = []
    if isinstance(obj, dict):
        items = list(obj.items())
    elif isinstance(obj, list):
        items = list(enumerate(obj))
    else:
        return out
    for key, value in items:
        out.append(((*path, key), obj, key))
        out += _spots(value, (*path, key))
    return out


def _where(path: tuple) -> str:
    return "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in path).lstrip(".")


def replace_value(rng: random.Random, d: Doc):
    spots = _spots(d.doc)
    if not spots:
        return None
    path, box_, key = rng.choice(spots)
    value = rng.choice(RANDOM_VALUES)
    box_[key] = value
    shown = repr(value) if not isinstance(value, int) or abs(value) < 10**12 else f"int {value}"
    return f"{_where(path)} = {shown}"


def insert_raw(rng: random.Random, d: Doc):
    spots = [s for s in _spots(d.doc) if not isinstance(s[1][s[2]], (dict, list))]
    spots = spots or _spots(d.doc)
    if not spots:
        return None
    path, box_, key = rng.choice(spots)
    text = rng.choice(RAW_TOKENS)
    box_[key] = d.sentinel(text)
    shown = text if len(text) < 20 else f"{text[:12]}... ({len(text)} characters)"
    return f"{_where(path)} = raw {shown}"


def delete_key(rng: random.Random, d: Doc):
    spots = [s for s in _spots(d.doc) if isinstance(s[1], dict)]
    if not spots:
        return None
    path, box_, key = rng.choice(spots)
    del box_[key]
    return f"delete {_where(path)}"


def add_unknown_key(rng: random.Random, d: Doc):
    boxes = [d.doc] + [s[1][s[2]] for s in _spots(d.doc) if isinstance(s[1][s[2]], dict)]
    target = rng.choice(boxes)
    key = rng.choice(["extra", "Model", "lattice ", "__proto__", "by", "path", "nodes", ""])
    if key in target:
        key = key + "_unknown"
    target[key] = rng.choice(RANDOM_VALUES)
    return f"add unknown key {key!r}"


def bad_node(rng: random.Random, d: Doc):
    nodes = []
    for mv in d.doc.get("moves", []) if isinstance(d.doc.get("moves"), list) else []:
        if isinstance(mv, dict) and "node" in mv:
            nodes.append((mv, "node"))
    pins = d.doc.get("pins")
    if isinstance(pins, list):
        nodes += [(pins, i) for i in range(len(pins))]
    if not nodes:
        d.doc.setdefault("pins", [])
        if not isinstance(d.doc["pins"], list):
            return None
        d.doc["pins"].append([0, 0, 0])
        nodes = [(d.doc["pins"], len(d.doc["pins"]) - 1)]
    box_, key = rng.choice(nodes)
    value = rng.choice(
        [
            [10, 0, 0],
            [3, 0, 0],
            [0, 2, 0],
            [0, 0, -1],
            [-1, -1, -1],
            [2**64, 0, 0],
            [-(2**63), 0, 0],
            [0, 0],
            [0, 0, 0, 0],
            [1.5, 0, 0],
            [True, 0, 0],
        ]
    )
    box_[key] = value
    return f"lattice node -> {value}"


def change_version(rng: random.Random, d: Doc):
    value = rng.choice([0, 2, "1", None, True, 2**64, -1, 1.5, "one", [1]])
    d.doc["version"] = value
    return f"version = {value!r}"


SCENARIO_MUTATORS: list[Callable[[random.Random, Doc], str | None]] = [
    replace_value,
    replace_value,
    insert_raw,
    delete_key,
    add_unknown_key,
    bad_node,
    change_version,
]


def mutate_scenario(rng: random.Random) -> tuple[str, dict[str, bytes], str]:
    """A damaged base scenario: (JSON text, model files to write next to it, description)."""
    doc, files, what = base_scenario(rng)
    d = Doc(doc)
    done = [what]
    if rng.random() < 0.15:
        text = d.text()
        at = rng.randrange(len(text))
        return text[:at], files, f"{what}; truncate the JSON to {at} of {len(text)} characters"
    for _ in range(rng.choice([1, 1, 2])):
        for _attempt in range(20):
            if not isinstance(d.doc, dict):
                break
            what_done = rng.choice(SCENARIO_MUTATORS)(rng, d)
            if what_done is not None:
                done.append(what_done)
                break
    text = d.text()
    if rng.random() < 0.1:
        at = rng.randrange(len(text))
        text = text[:at]
        done.append(f"truncate the JSON to {at} characters")
    return text, files, "; ".join(done)


# -- issue 28's families: files a model reads, URIs, keys, far models, float32, signals -----
@dataclass
class HardCase:
    """A case of one of issue 28's families: the files to write, the command line's
    arguments (after ``solve``), what it checks, and a signal to send (or None)."""

    family: str
    description: str
    files: dict[str, bytes]
    args: list[str]
    outputs: list[str]
    #: "refused": exit 1 naming ``words``; "solved": exit 0/3, checked against ``truth``
    expect: str
    words: str = ""
    truth: dict[str, Any] = field(default_factory=dict)
    links: list[tuple[str, str, str]] = field(default_factory=list)  # (kind, name, target)
    signal: tuple[int, float] | None = None  # (signal number, seconds after start)


def _scenario_text(model: dict, rng: random.Random, **extra) -> bytes:
    doc = {
        "model": model,
        "lattice": {"nodes": rng.choice([[3, 3, 3], [3, 2, 2]]), "padding": 0.05},
        "moves": [{"node": [2, 1, 1], "by": [0.2, 0.0, 0.0]}],
        **extra,
    }
    return json.dumps(doc, indent=1).encode()


def _obj_with_files(rng: random.Random) -> dict[str, bytes]:
    mesh = icosphere(rng.choice([1, 2]))
    lib = rng.choice(["m.mtl", "my lib.mtl", "sub/m.mtl"])
    tex = rng.choice(["wood.png", "tex/wood.png", "wood map.png"])
    mtl_folder = lib.rpartition("/")[0]
    tex_name = tex if not mtl_folder else f"../{tex}"
    files = {
        "m.obj": f"mtllib {lib}\n".encode() + mesh_bytes(mesh, ".obj"),
        lib: f"newmtl a\nmap_Kd -s 1 1 1 {tex_name}\n".encode(),
        tex: b"texture bytes",
    }
    return files


def _gltf_with_files(rng: random.Random) -> dict[str, bytes]:
    import trimesh

    exported = trimesh.exchange.gltf.export_gltf(
        trimesh.Scene(trimesh.creation.icosphere(rng.choice([1, 2]))), include_normals=True
    )
    doc = json.loads(exported["model.gltf"])
    doc["images"] = [{"uri": "skin.png"}]
    files = {k: v for k, v in exported.items() if k != "model.gltf"}
    files["model.gltf"] = json.dumps(doc).encode()
    files["skin.png"] = b"image bytes"
    return files


def _spell(rng: random.Random, name: str) -> tuple[str, list[tuple[str, str, str]]]:
    """``name`` spelled another way, with the links that spelling needs."""
    how = rng.choice(["plain", "dot", "up", "symlink", "hardlink", "absolute"])
    if how == "dot":
        return f"./{name}", []
    if how == "up":
        return f"sub2/../{name}", [("folder", "sub2", "")]
    if how == "symlink":
        return "alias.out", [("symlink", "alias.out", name)]
    if how == "hardlink":
        return "hard.out", [("hardlink", "hard.out", name)]
    if how == "absolute":
        return f"@ABS@/{name}", []
    return name, []


def companion_case(rng: random.Random) -> HardCase:
    """An output naming a file the model reads (a material library, a texture, a glTF
    buffer or image, the model, the scenario), by some spelling: refused, nothing touched."""
    files = _obj_with_files(rng) if rng.random() < 0.5 else _gltf_with_files(rng)
    model = "m.obj" if "m.obj" in files else "model.gltf"
    files["s.json"] = _scenario_text({"path": model}, rng)
    victim = rng.choice(sorted(files))
    spelled, links = _spell(rng, victim)
    role = rng.choice(["--out", "--report"])
    args = ["s.json", role, spelled]
    if role == "--out":
        args += ["--report", "r.json"]
    what = f"{role} onto {victim} as {spelled!r}"
    words = "would overwrite" if spelled != "o.ply" else ""
    return HardCase("companion", what, files, args, [], "refused", words, links=links)


URIS = [
    "../outside.bin",
    "../../../../../../etc/passwd",
    "/etc/passwd",
    "file:///etc/passwd",
    "sub/../../outside.bin",
    "%2e%2e/outside.bin",
    "http://example.com/a.bin",
    "C:\\Windows\\win.ini",
    "link.bin",
]


def uri_case(rng: random.Random) -> HardCase:
    """A glTF whose buffer or image URI leads out of its folder: refused, nothing read."""
    files = _gltf_with_files(rng)
    doc = json.loads(files["model.gltf"])
    kind = rng.choice(["buffers", "images"])
    uri = rng.choice(URIS)
    doc[kind][0]["uri"] = uri
    files["model.gltf"] = json.dumps(doc).encode()
    files["s.json"] = _scenario_text({"path": "model.gltf"}, rng)
    links = [("symlink", "link.bin", "/etc/hostname")] if uri == "link.bin" else []
    args = ["s.json", "--out", "o.glb", "--report", "r.json"]
    return HardCase(
        "uri", f"{kind} uri {uri!r}", files, args, [], "refused", "is refused", links=links
    )


def duplicate_key_case(rng: random.Random) -> HardCase:
    """A scenario with a key given twice in one object: refused naming the key."""
    key = rng.choice(["model", "lattice", "moves", "nodes", "padding", "target_volume_ratio"])
    if key in ("nodes", "padding"):
        text = (
            '{"model": {"builtin": "sphere", "n_levels": 2}, "lattice": {"nodes": [3, 3, 3], '
            f'"padding": 0.05, "{key}": {json.dumps([2, 2, 2] if key == "nodes" else 0.1)}}}}}'
        )
    else:
        base = {
            "model": {"builtin": "sphere", "n_levels": 2},
            "lattice": {"nodes": [3, 3, 3]},
            "moves": [],
            "target_volume_ratio": 1.0,
        }
        body = json.dumps(base)[1:-1]
        text = "{" + body + f', "{key}": {json.dumps(base[key])}' + "}"
    args = ["s.json", "--out", "o.ply", "--report", "r.json"]
    return HardCase(
        "dupkey",
        f"{key} twice",
        {"s.json": text.encode()},
        args,
        [],
        "refused",
        f"'{key}' is given twice",
    )


def pinned_moved_case(rng: random.Random) -> HardCase:
    node = [rng.randint(0, 2), rng.randint(0, 2), rng.randint(0, 2)]
    pin: Any = node if rng.random() < 0.5 else {"node": node, "axes": rng.choice(["x", "yz"])}
    doc = {
        "version": 2,
        "model": {"builtin": "sphere", "n_levels": 2},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": node, "by": [0.1, 0, 0]}],
        "pins": [pin],
    }
    args = ["s.json", "--out", "o.ply", "--report", "r.json"]
    return HardCase(
        "pinmove",
        f"node {node} pinned ({pin}) and moved",
        {"s.json": json.dumps(doc).encode()},
        args,
        [],
        "refused",
        "is also moved",
    )


def far_case(rng: random.Random) -> HardCase:
    """A box of a power-of-two size at a large offset (its corners exact): refused as too
    far for its size, or solved with the original volume equal to the closed form and
    the final within the tolerance."""
    size = 2.0 ** rng.randint(-2, 24)
    offset = rng.choice([0.0, 1e6, 1e10, 1e12, 1e13, 1e14, 5e14, 9e14]) * rng.choice([1, -1])
    offset = float(np.round(offset / 2**20) * 2**20) if abs(offset) > 2**20 else offset
    mesh = box((size, size / 2, size / 4))
    v = mesh.vertices + offset
    fmt = rng.choice([".ply", ".obj", ".off"])
    files = {f"m{fmt}": mesh_bytes(TriMesh(v, mesh.faces), fmt)}
    doc = {
        "model": {"path": f"m{fmt}"},
        "lattice": {"nodes": [3, 3, 3]},
        "moves": [{"node": [2, 2, 2], "by": [size / 8, 0, 0]}],
    }
    files["s.json"] = json.dumps(doc).encode()
    args = ["s.json", "--out", "o.ply", "--report", "r.json", "--quiet"]
    truth = {"volume": size**3 / 8, "area": 2 * (size**2 / 2 + size**2 / 4 + size**2 / 8)}
    return HardCase(
        "far",
        f"box {size:g} at {offset:g} as {fmt}",
        files,
        args,
        ["o.ply", "r.json"],
        "solved",
        "too far from the origin",
        truth,
    )


def fold_case(rng: random.Random) -> HardCase:
    """The built-in sphere squashed or twisted hard: whatever the run says, a result
    reported converged must have det J > 0 at dense points inside (checked from the
    report's nodes)."""
    nodes = rng.choice([[3, 3, 3], [4, 4, 4], [4, 3, 3]])
    l, m, n = nodes
    moves = []
    for _ in range(rng.randint(1, 3)):
        node = [rng.randrange(l), rng.randrange(m), rng.randrange(n)]
        if any(mv["node"] == node for mv in moves):
            continue
        moves.append({"node": node, "by": [round(rng.uniform(-2.5, 2.5), 3) for _ in range(3)]})
    doc = {
        "model": {"builtin": "sphere", "n_levels": 3},
        "lattice": {"nodes": nodes},
        "moves": moves,
        "target_volume_ratio": rng.choice([1.0, 0.3, 0.1, 0.05, 2.0]),
    }
    args = ["s.json", "--out", "o.ply", "--report", "r.json", "--quiet"]
    return HardCase(
        "fold",
        f"sphere {nodes} {moves} x{doc['target_volume_ratio']}",
        {"s.json": json.dumps(doc).encode()},
        args,
        ["o.ply", "r.json"],
        "solved",
        truth={"scenario": doc},
    )


def float32_case(rng: random.Random) -> HardCase:
    """A thin box written to float32 formats: the report's written volume is the file's."""
    thick = 10.0 ** rng.uniform(-5, 0)
    mesh = box((1.0, 1.0, thick))
    v = mesh.vertices + rng.choice([0.0, 10.0, 1000.0, 1e5])
    files = {"m.ply": mesh_bytes(TriMesh(v, mesh.faces), ".ply")}
    doc = {
        "model": {"path": "m.ply"},
        "lattice": {"nodes": [3, 3, 2]},
        "moves": [{"node": [2, 2, 1], "by": [0.1, 0, 0]}],
    }
    files["s.json"] = json.dumps(doc).encode()
    out = rng.choice(["o.stl", "o.glb", "o.ply"])
    args = ["s.json", "--out", out, "--report", "r.json", "--quiet"]
    return HardCase(
        "float32",
        f"box 1x1x{thick:.2g} to {out}",
        files,
        args,
        [out, "r.json"],
        "solved",
        truth={"out": out},
    )


def signal_case(rng: random.Random) -> HardCase:
    """A solve (one output set, or a sequence of frames) signalled at a random moment from
    start-up to the end: interrupted (128+n, one line, nothing written) or finished."""
    import signal as _signal

    files = {"m.obj": mesh_bytes(icosphere(rng.choice([3, 4])), ".obj")}
    doc: dict[str, Any] = {
        "version": 3,
        "model": {"path": "m.obj"},
        "lattice": {"nodes": [4, 4, 4], "padding": 0.05},
        "moves": [{"node": [3, 3, 3], "by": [0.8, 0.8, 0.0]}],
    }
    sequence = rng.random() < 0.3
    if sequence:
        doc["poses"] = [
            {"frame": 0, "moves": [], "pins": []},
            {"frame": 6, "moves": [{"node": [3, 3, 3], "by": [0.6, 0.0, 0.0]}], "pins": []},
        ]
        args = ["s.json", "--sequence", "f_####.obj", "--report", "r.json"]
        outputs = [f"f_{i:04d}.obj" for i in range(7)] + ["r.json"]
    else:
        args = ["s.json", "--out", "o.ply", "--report", "r.json"]
        outputs = ["o.ply", "r.json"]
    files["s.json"] = json.dumps(doc).encode()
    sig = rng.choice([_signal.SIGINT, _signal.SIGTERM, _signal.SIGHUP])
    delay = rng.uniform(0.0, 6.0)
    return HardCase(
        "signal",
        f"{sig.name} at {delay:.3f} s{' (sequence)' if sequence else ''}",
        files,
        args,
        outputs,
        "signal",
        signal=(int(sig), delay),
    )


HARD_FAMILIES: dict[str, Callable[[random.Random], HardCase]] = {
    "companion": companion_case,
    "uri": uri_case,
    "dupkey": duplicate_key_case,
    "pinmove": pinned_moved_case,
    "far": far_case,
    "fold": fold_case,
    "float32": float32_case,
    "signal": signal_case,
}


def hard_case(seed: int, index: int) -> HardCase:
    """Case ``index`` of ``seed``: the families in turn, each drawn from its own seed."""
    names = list(HARD_FAMILIES)
    rng = random.Random(seed * 1_000_003 + index)
    return HARD_FAMILIES[names[index % len(names)]](rng)
