"""Round trip into the artist's pipeline: a model file given back with its positions deformed.

The FFD is a map of space, so it is applied to the positions of the file as read (not to
the welded, repaired copy the solver uses): same vertices, same order, everything else kept
byte for byte. Normals are transformed by the inverse transpose of the Jacobian; STL facet
normals are recomputed. A value the map leaves exactly as it was keeps its bytes (the
identity gives the file back); new numbers are written ``%.17g`` (``%.9g`` for float32 in
ASCII PLY), which read back to the same bits.
"""

from __future__ import annotations

import os
import re
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path

import numpy as np

from ..errors import IsochorError
from .plyheader import PlyHeader

#: ``(k, 3)`` float64 points -> ``(k, 3)`` deformed points
Deform = Callable[[np.ndarray], np.ndarray]
#: ``(k, 3)`` points -> ``(k, 3, 3)``: ``J[p, a, b] = d deformed_a / d x_b``
Jacobian = Callable[[np.ndarray], np.ndarray]

ROUNDTRIP_FORMATS = (".obj", ".ply", ".stl", ".off")

_TOKEN = re.compile(rb"\S+")
_FLOAT = re.compile(rb"[-+]?((\d+\.?\d*|\.\d+)(e[-+]?\d+)?|inf(inity)?|nan)", re.I)
_NONE = np.zeros(0, np.int64)


@dataclass(frozen=True)
class Rewritten:
    """The new file, and what the user should know about it (one sentence each)."""

    data: bytes
    notes: list[str] = field(default_factory=list)


@dataclass
class _Parsed:
    """What a reader found, and how to write the file back: ``write(moved, normals, notes)``."""

    points: np.ndarray  # (m, 3) float64, in file order
    write: Callable[[np.ndarray, np.ndarray | None, list[str]], bytes]
    normals: np.ndarray | None = None  # (k, 3)
    normal_at: np.ndarray | None = None  # (k,) each one's vertex (m: centroid; None: its own)
    shared: tuple[np.ndarray, np.ndarray] = (_NONE, _NONE)  # other (normal, vertex) uses
    notes: list[str] = field(default_factory=list)


def rewrite(
    data: bytes,
    suffix: str,
    deform: Deform,
    jacobian: Jacobian,
    *,
    name: str = "model",
    source_dir: Path | None = None,
    out_dir: Path | None = None,
) -> Rewritten:
    """The bytes of a model file (``suffix`` .obj/.ply/.stl/.off, as read from disk) with its
    positions deformed and its normals transformed; everything else kept byte for byte where
    the format allows. ``deform`` is called once; ``jacobian`` once, for a file with normals
    only. An OBJ's ``mtllib`` names are made relative to ``out_dir`` when ``source_dir`` (the
    model's folder) holds the library. Raises :class:`IsochorError`, one line naming ``name``."""
    parsed = _parse(data, suffix, name, source_dir, out_dir)
    points, notes, normals = parsed.points, list(parsed.notes), None
    moved = _evaluate(deform, points, (3,), name, "deformation")
    if parsed.normals is not None:
        at = np.vstack([points, points.mean(axis=0)])  # the centroid: for unused normals
        jac = _evaluate(jacobian, at, (3, 3), name, "Jacobian")
        normal_at = np.arange(len(points)) if parsed.normal_at is None else parsed.normal_at
        normals = _transform_normals(jac[normal_at], parsed.normals)
        if unused := int(np.count_nonzero(normal_at == len(points))):
            notes.append(f"{unused} normal(s) used by no face took the deformation at the centroid")
        normal, other = parsed.shared
        same = np.isclose(jac[normal_at[normal]], jac[other], rtol=1e-9, atol=1e-12)
        if differ := len(np.unique(normal[~same.all(axis=(1, 2))])):
            notes.append(f"{differ} shared normal(s) took the deformation of their first vertex")
    with np.errstate(all="ignore"):
        return Rewritten(parsed.write(moved, normals, notes), notes)


def positions(data: bytes, suffix: str, *, name: str = "model") -> np.ndarray:
    """The ``(m, 3)`` float64 positions :func:`rewrite` deforms, in file order (STL: 3 a facet)."""
    return _parse(data, suffix, name, None, None).points.copy()


def _parse(data: bytes, suffix: str, name: str, source_dir, out_dir) -> _Parsed:
    kind = suffix.lower()
    if kind not in ROUNDTRIP_FORMATS:
        raise IsochorError(f"{name}: cannot rewrite {suffix!r} files (only OBJ, PLY, STL, OFF)")
    if not data.strip():
        raise IsochorError(f"{name}: the file is empty")
    try:
        with np.errstate(all="ignore"):
            parsed = _PARSERS[kind](data, name, source_dir, out_dir)
    except (ValueError, IndexError, OverflowError, StopIteration, struct.error) as exc:
        detail = (str(exc).splitlines() or ["it ends too early"])[0]
        raise IsochorError(f"{name}: not a readable {kind[1:].upper()} file ({detail})") from None
    if not len(parsed.points):
        raise IsochorError(f"{name}: the file has no vertices")
    for what, values in (("vertex", parsed.points), ("normal", parsed.normals)):
        if values is not None and len(bad := np.flatnonzero(~np.isfinite(values).all(axis=1))):
            raise IsochorError(f"{name}: {what} {bad[0] + 1} has a coordinate that is not finite")
    return parsed


def _evaluate(fn, points: np.ndarray, shape: tuple, name: str, what: str) -> np.ndarray:
    """``fn(points)`` as float64 of shape ``(len(points), *shape)``, checked finite."""
    with np.errstate(all="ignore"):
        out = np.asarray(fn(points.copy()), dtype=np.float64)
    if out.shape != (len(points), *shape):
        raise ValueError(f"the {what} gave shape {out.shape} for {len(points)} points")
    if bad := int(np.count_nonzero(~np.isfinite(out.reshape(len(out), -1)).all(axis=1))):
        raise IsochorError(f"{name}: the {what} is not finite at {bad} of {len(out)} points")
    return out


def _transform_normals(jac: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``J^-T n`` normalised, through the cofactor matrix ``det(J) J^-T`` (defined also where
    ``J`` is singular); zero stays zero; where ``J`` is exactly the identity, ``n`` stays."""
    c0, c1, c2 = jac[:, :, 0], jac[:, :, 1], jac[:, :, 2]
    with np.errstate(all="ignore"):
        c12 = np.cross(c1, c2)
        out = normals[:, :1] * c12 + normals[:, 1:2] * np.cross(c2, c0)
        out += normals[:, 2:] * np.cross(c0, c1)
        out[np.einsum("pi,pi->p", c0, c12) < 0] *= -1  # det < 0: the direction of J^-T n
        out, keep = _unit(out), np.all(jac == np.eye(3), axis=(1, 2))
    out[keep] = normals[keep]
    return out


def _unit(vectors: np.ndarray) -> np.ndarray:
    """The rows of ``vectors`` scaled to length 1; zero stays zero."""
    length = np.linalg.norm(vectors, axis=1, keepdims=True)
    return np.divide(vectors, length, out=np.zeros_like(vectors), where=length > 0)


def _floats(tokens: list[bytes], name: str, where: Callable[[int], str]) -> np.ndarray:
    """The numbers of text tokens, or an error naming the first that is not one."""
    try:
        return np.array(tokens, dtype=np.bytes_).astype(np.float64)
    except ValueError:
        i = next((i for i, t in enumerate(tokens) if not _FLOAT.fullmatch(t)), 0)
        text = tokens[i].decode("latin-1")[:30]
        raise IsochorError(f"{name}: {where(i)}: {text!r} is not a number") from None


def _text(data: bytes, slots: list[tuple], fixed: Sequence[tuple] = ()):
    """A text file's writer: it writes anew the changed numbers of ``slots`` (positions, normals:
    ``(spans (k, 3, 2), old values, float32)``) and makes the ``(start, end, text)`` ``fixed``."""

    def write(moved, normals, _notes):
        edits = list(fixed)
        for (spans, old, f32), new in zip(slots, (moved, normals)):
            changed = np.flatnonzero(np.asarray(new != old).ravel()) if new is not None else []
            values = np.asarray(new, np.float64).ravel()[changed]
            fmt, values = (b"%.9g", values.astype(np.float32)) if f32 else (b"%.17g", values)
            places = np.asarray(spans, np.int64).reshape(-1, 2)[changed].tolist()
            edits += [(s, e, fmt % v) for (s, e), v in zip(places, values.tolist())]
        pieces, pos = [], 0
        for start, end, text in sorted(edits, key=lambda edit: edit[0]):
            pieces += (data[pos:start], text)
            pos = end
        return b"".join([*pieces, data[pos:]])

    return write


# -- OBJ ----------------------------------------------------------------------------------
_OBJ_SEP = rb"(?:[ \t]|\\\r?\n)+"  # a line continuation separates like a space
_OBJ_XYZ = re.compile(3 * (_OBJ_SEP + rb"((?:[^\s\\]|\\(?!\r?\n))+)"))
#: a statement: its keyword and the rest, with the lines it continues on (not after a #)
_OBJ_STATEMENT = re.compile(
    rb"^(?:\xef\xbb\xbf)?[ \t]*([^\s\\#]*)((?:[^#\n]*\\\r?\n)*.*?)\r?$", re.M
)
_OBJ_CORNER = re.compile(rb"(-?\d+)/-?\d*/(-?\d+)")  # v/vt/vn or v//vn


def _parse_obj(data: bytes, name: str, source_dir, out_dir) -> _Parsed:
    if lone := re.search(rb"\r(?![\r\n])", data):  # old Mac line ends: lines would be lost
        raise IsochorError(f"{name}: {_line(data, lone.start())} ends in a lone carriage return")
    found: dict[bytes, tuple[list, list]] = {b"v": ([], []), b"vn": ([], [])}  # spans, tokens
    faces, libraries = [], []
    for s in _OBJ_STATEMENT.finditer(data):
        if (word := s.group(1)) in found:
            if not (m := _OBJ_XYZ.match(data, s.end(1))):
                raise IsochorError(f"{name}: {_line(data, s.start())}: {word.decode()} needs x y z")
            found[word][0].append([m.span(g) for g in (1, 2, 3)])
            found[word][1].extend(m.groups())
        elif word == b"f":
            body = s.group(2).split(b"#", 1)[0]
            faces.append((body, len(found[b"v"][0]), len(found[b"vn"][0]), s.start()))
        elif word == b"mtllib" and b"\\" not in s.group(2):
            libraries.append((s.start(2), s.group(2)))
    (v_spans, v_tokens), (n_spans, n_tokens) = found.values()
    where = lambda spans: lambda i: _line(data, spans[i // 3][0][0])  # noqa: E731
    points = _floats(v_tokens, name, where(v_spans)).reshape(-1, 3)
    normals = _floats(n_tokens, name, where(n_spans)).reshape(-1, 3)
    fixed, notes = _mtllib_edits(libraries, source_dir, out_dir)
    write = _text(data, [(v_spans, points, False), (n_spans, normals, False)], fixed)
    if not len(normals):
        return _Parsed(points, write, notes=notes)
    # the vertex each vn is first used with (len(points): none), and its other uses
    corners = [(int(v), int(n), *c) for b, *c in faces for v, n in _OBJ_CORNER.findall(b)]
    v, n, nv, nn, at = np.array(corners, np.int64).reshape(-1, 5).T
    v = np.where(v > 0, v - 1, np.where(v < 0, nv + v, -1))  # negative: relative
    n = np.where(n > 0, n - 1, np.where(n < 0, nn + n, -1))
    if len(bad := np.flatnonzero((v < 0) | (v >= len(points)) | (n < 0) | (n >= len(normals)))):
        where = _line(data, int(at[bad[0]]))
        raise IsochorError(f"{name}: {where}: a face corner names no vertex or normal")
    normal_at = np.full(len(normals), len(points), dtype=np.int64)
    ids, first = np.unique(n, return_index=True)
    normal_at[ids] = v[first]
    other = v != normal_at[n]
    return _Parsed(points, write, normals, normal_at, (n[other], v[other]), notes)


def _line(data: bytes, pos: int) -> str:
    return f"line {data.count(10, 0, pos) + 1}"  # 10: newline


def _mtllib_edits(libraries: list, source_dir, out_dir) -> tuple[list, list[str]]:
    """Edits making ``mtllib`` names relative to ``out_dir`` where the library exists."""
    edits, notes = [], []
    source, out = (d and Path(d).resolve() for d in (source_dir, out_dir))
    for start, rest in libraries if source and out and source != out else ():
        body = rest.split(b"#", 1)[0].strip()
        names = [body] if (source / os.fsdecode(body)).is_file() else body.split()
        new = list(names)
        for i, path in enumerate(source / os.fsdecode(lib) for lib in names):
            if not path.is_file():
                notes.append(f"the material library {path.name} was not found; mtllib kept as is")
            elif not Path(os.fsdecode(names[i])).is_absolute():
                new[i] = os.fsencode(Path(os.path.relpath(path, out)).as_posix())
        if new != names:
            begin = start + rest.find(body)
            edits.append((begin, begin + len(body), b" ".join(new)))
    return edits, notes


# -- PLY ----------------------------------------------------------------------------------
def _parse_ply(data: bytes, name: str, *_) -> _Parsed:
    header = PlyHeader.parse(data, name)
    index = header.element("vertex")
    if header.encoding is None or index is None or not header.elements[index].rows:
        raise IsochorError(f"{name}: the PLY header has no format line, or no vertices")
    vertex = header.elements[index]
    if vertex.has_lists:
        raise IsochorError(f"{name}: Isochor cannot rewrite PLY vertices with list properties")
    floats = {p.name for p in vertex.properties if p.kind[0] == "f"}
    want = ["x", "y", "z"] + ["nx", "ny", "nz"] * ({"nx", "ny", "nz"} <= floats)
    if bad := [p for p in want if p not in floats]:
        raise IsochorError(f"{name}: the PLY vertex has no float or double property {bad[0]}")
    scan = _ply_binary if header.byte_order else _ply_ascii
    values, write = scan(data, header, index, want, name)
    return _Parsed(values[:, :3], write, values[:, 3:] if len(want) == 6 else None)


def _ply_binary(data: bytes, header: PlyHeader, index: int, want: list[str], name: str):
    pos, endian = header.body, header.byte_order
    for element in header.elements[:index]:  # the elements before the vertices
        props = element.properties
        sizes = [np.dtype(p.kind).itemsize for p in props]
        if not element.has_lists:
            pos += element.rows * sum(sizes)
            continue
        try:  # rows with lists, one by one
            for _ in range(element.rows):
                for p, size in zip(props, sizes):
                    c = p.count
                    n = struct.unpack_from(endian + np.dtype(c).char, data, pos)[0] if c else 1
                    if not 0 <= n == int(n):
                        raise struct.error
                    pos += (np.dtype(c).itemsize if c else 0) + int(n) * size
        except struct.error:
            label = element.name
            raise IsochorError(f"{name}: the PLY file is damaged or ends in its {label}") from None
    count = header.elements[index].rows
    row = np.dtype([(p.name, endian + p.kind) for p in header.elements[index].properties])
    if pos + count * row.itemsize > len(data):
        raise IsochorError(f"{name}: the PLY file is truncated (it ends in its vertex data)")
    values = np.frombuffer(data, row, count, pos)

    def write(moved, normals, _notes):
        out = bytearray(data)
        table = np.frombuffer(out, row, count, pos)  # a view: writes go to ``out``
        news = moved if normals is None else np.hstack([moved, normals])
        for p, new in zip(want, news.T):
            table[p] = new
        return bytes(out)

    return np.column_stack([values[p] for p in want]).astype(np.float64), write


def _ply_ascii(data: bytes, header: PlyHeader, index: int, want: list[str], name: str):
    pos = header.body
    for _ in range(sum(e.rows for e in header.elements[:index])):  # one row a line
        if not (pos := data.find(b"\n", pos) + 1):
            raise IsochorError(f"{name}: the PLY file ends before its vertices")
    count = header.elements[index].rows
    names = [p.name for p in header.elements[index].properties]
    kinds = {p.name: p.kind for p in header.elements[index].properties}
    n = count * len(names)
    flat = list(islice(_TOKEN.finditer(data, pos), n + 1))  # and the token after them
    rows = len(flat) >= n and data.count(10, flat[0].start(), flat[n - 1].end()) == count - 1
    if not rows or (len(flat) > n and 10 not in data[flat[n - 1].end() : flat[n].start()]):
        raise IsochorError(f"{name}: the PLY vertex lines do not hold {len(names)} values each")
    flat = flat[:n]
    columns = [flat[names.index(w) :: len(names)] for w in want]
    spans = np.array([[m.span() for m in col] for col in columns], np.int64).transpose(1, 0, 2)
    tokens = [m.group() for col in columns for m in col]
    values = _floats(tokens, name, lambda i: f"vertex {i % count + 1}").reshape(len(want), -1).T
    single = [kinds[w] == "f4" for w in want]
    slots = [(spans[:, j : j + 3], values[:, j : j + 3], all(single[j : j + 3])) for j in (0, 3)]
    return values, _text(data, slots[: len(want) // 3])


# -- STL ----------------------------------------------------------------------------------
_STL_ROW = np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
_STL_LINE = re.compile(rb"^[ \t]*(facet[ \t]+normal|vertex)" + 3 * rb"[ \t]+(\S+)", re.I | re.M)


def _parse_stl(data: bytes, name: str, *_) -> _Parsed:
    count = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
    ascii_like = data.lstrip()[:5].lower() == b"solid" and b"\0" not in data[:1024]
    if count >= 0 and (len(data) == 84 + 50 * count or not ascii_like):
        if count == 0 or len(data) < 84 + 50 * count:
            raise IsochorError(f"{name}: {count} binary STL triangles need {84 + 50 * count} bytes")
        rows = np.frombuffer(data, _STL_ROW, count, 84)
        points = rows["v"].reshape(-1, 3).astype(np.float64)

        def write(moved, _normals, notes):
            out = rows.copy()
            out["v"] = moved.reshape(-1, 3, 3)
            stored = out["v"].reshape(-1, 3).astype(np.float64)  # as the file keeps them
            out["n"] = _stl_normals(rows["n"], points, stored, notes)
            return data[:84] + out.tobytes() + data[84 + 50 * count :]

        return _Parsed(points, write)
    if not ascii_like:
        raise IsochorError(f"{name}: not an STL file (too short for a binary STL)")
    matches = list(_STL_LINE.finditer(data))
    facet = np.array([m.group(1)[:1].lower() == b"f" for m in matches], dtype=bool)
    if not len(facet) or len(facet) % 4 or np.any(facet != (np.arange(len(facet)) % 4 == 0)):
        raise IsochorError(f"{name}: not an ASCII STL file of facets with three vertices each")
    spans = np.array([[m.span(g) for g in (2, 3, 4)] for m in matches]).reshape(-1, 4, 3, 2)
    tokens = [t for m in matches for t in m.groups()[1:]]
    values = _floats(tokens, name, lambda i: f"facet {i // 12 + 1}").reshape(-1, 4, 3)
    points, old = values[:, 1:].reshape(-1, 3), values[:, 0]
    text = _text(data, [(spans[:, 1:], points, False), (spans[:, 0], old, False)])
    return _Parsed(points, lambda m, _, notes: text(m, _stl_normals(old, points, m, notes), notes))


def _stl_normals(old, points: np.ndarray, stored: np.ndarray, notes: list[str]) -> np.ndarray:
    """Unit normals of the moved triangles by their winding (degenerate: 0); others stay."""
    changed = np.any((stored != points).reshape(-1, 9), axis=1)
    normals = np.array(old, dtype=np.float64)
    tri = stored.reshape(-1, 3, 3)[changed]
    normals[changed] = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    if flat := int(np.count_nonzero(~np.any(normals[changed], axis=1))):
        notes.append(f"{flat} facet(s) are degenerate after the deformation; their normals are 0")
    return normals


# -- OFF ----------------------------------------------------------------------------------
_OFF_KEY = re.compile(rb"(ST)?(C)?(N)?(4)?(n)?OFF")
_OFF_LINE = re.compile(rb"^[^#\r\n]*", re.M)  # a line without its comment


def _parse_off(data: bytes, name: str, *_) -> _Parsed:
    lines = (m for m in _OFF_LINE.finditer(data) if m.group().strip())
    words = next(lines).group().split()
    key = _OFF_KEY.fullmatch(words[0])
    if key is None or key.group(4) or key.group(5) or words[1:2] == [b"BINARY"]:
        raise IsochorError(f"{name}: {words[0][:20].decode('latin-1')!r}: not a 3D ASCII OFF file")
    need, count = 6 if key.group(3) else 3, int((words[1:] or next(lines).group().split())[0])
    rows = list(islice(lines, count))
    found = [list(islice(_TOKEN.finditer(data, r.start(), r.end()), need)) for r in rows]
    if len(rows) < count or min(map(len, found), default=need) < need:
        raise IsochorError(f"{name}: the OFF file ends before {count} vertices of {need} numbers")
    spans = np.array([[t.span() for t in row] for row in found], np.int64).reshape(-1, need, 2)
    where = lambda i: _line(data, rows[i // need].start())  # noqa: E731
    values = _floats([t.group() for row in found for t in row], name, where).reshape(-1, need)
    slots = [(spans[:, j : j + 3], values[:, j : j + 3], False) for j in range(0, need, 3)]
    return _Parsed(values[:, :3], _text(data, slots), values[:, 3:] if need == 6 else None)


_PARSERS = {".obj": _parse_obj, ".ply": _parse_ply, ".stl": _parse_stl, ".off": _parse_off}
