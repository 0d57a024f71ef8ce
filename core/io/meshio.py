"""Model files: read OBJ, PLY, STL, OFF and glTF into a clean closed :class:`TriMesh`;
write meshes.

Reading (:func:`load_mesh`) goes through trimesh (polygons are triangulated by its readers;
glTF through :mod:`isochor.core.io.gltf`, node transforms applied; OBJ through
:mod:`isochor.core.io.objfile`, errors naming the line; a binary PLY of triangles or of
mixed polygons, as Blender writes it, and a plain OBJ of triangles straight into numpy,
:func:`binary_ply` and :func:`plain_obj`), then
:func:`isochor.core.io.repair.clean_closed_surface` welds, checks and orients the surface.
Any problem a file can have ends in one :class:`IsochorError` that names the file;
trimesh's own exceptions and log lines never reach the user.

Writing a mesh anew (:func:`save_mesh`, :func:`mesh_bytes`): OBJ (``%.17g``, exact round
trip), binary PLY with float64 vertices, binary STL (float32 by the format), OFF, or glTF,
chosen by extension, written atomically. Exporting a deformed *model* keeps its own file's
contents: :mod:`isochor.core.export`.
"""

from __future__ import annotations

import io
import logging
import re
import struct
import warnings
from collections.abc import Iterable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np

from ..errors import IsochorError
from ..mesh import TriMesh
from ..validate import MAX_COORDINATE, input_file
from ..volume import signed_volume
from .atomic import atomic_write_bytes
from .companions import outside_names
from .formats import GLTF_FORMATS, READ_FORMATS, WRITE_FORMATS, listing
from .objfile import read_obj
from .plyheader import PlyHeader
from .repair import clean_closed_surface

#: the largest model file read (a safeguard: a huge or sparse file fails at once, with one
#: line, instead of filling the memory); some 40 million triangles as binary PLY
MAX_MODEL_BYTES = 2 * 2**30
#: bytes looked at to tell whether a file can be of its format at all
SNIFF_BYTES = 64 * 1024


@dataclass(frozen=True)
class LoadedMesh:
    """A model read from a file and made ready for the solver.

    Attributes
    ----------
    mesh : the closed, outward-wound, full-resolution triangle mesh
    warnings : what was repaired, one sentence each, for the user
    bodies : number of separate closed bodies (face-connected components)
    path : the file it came from
    """

    mesh: TriMesh
    warnings: list[str] = field(default_factory=list)
    bodies: int = 1
    path: Path | None = None

    @property
    def volume(self) -> float:
        """Enclosed volume (positive) of all bodies together."""
        return signed_volume(self.mesh.vertices, self.mesh.faces)


# -- reading ----------------------------------------------------------------------------------
def load_mesh(path: str | Path) -> LoadedMesh:
    """Read a closed triangle surface from an OBJ, PLY, STL, OFF or glTF (.glb, .gltf) file.

    Raises
    ------
    IsochorError
        The file is missing, unreadable, of an unknown format, holds no triangles, or its
        surface is not closed. The message starts with the file name.
    """
    path = Path(path)
    vertices, faces, parts = _read_raw(path)
    try:
        mesh, warns, bodies = clean_closed_surface(vertices, faces, parts)
    except IsochorError as exc:
        raise IsochorError(f"{path.name}: {exc}") from None
    outside = [f"Its material library or texture {line}." for line in outside_names(path)]
    return LoadedMesh(mesh, warns + outside, bodies, path)


def _read_raw(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Vertices ``(m, 3) float64`` and triangles ``(f, 3) int64`` as the file holds them,
    and the file's object of each triangle (None: one object, or not known)."""
    kind = READ_FORMATS.get(path.suffix.lower())
    if kind is None:
        known = listing(READ_FORMATS)
        raise IsochorError(
            f"{path.name}: unknown model format {path.suffix or '(no extension)'!r}; "
            f"Isochor reads {known}"
        )
    try:
        size = input_file(path, "model", MAX_MODEL_BYTES)
        with open(path, "rb") as fh:
            _sniff(path, kind, fh.read(SNIFF_BYTES), size)
            fh.seek(0)
            data = fh.read()
    except OSError as exc:
        raise IsochorError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    except ValueError:  # a NUL byte in the name
        raise IsochorError(f"{str(path)!r}: not a valid file name") from None
    if not data or data.isspace():
        raise IsochorError(f"{path.name}: the file is empty")
    if kind in ("glb", "gltf"):
        from .gltf import read_gltf

        counts: list[int] = []
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            vertices, faces = read_gltf(
                data, path.suffix.lower(), name=path.name, base_dir=path.parent, parts=counts
            )
        parts = np.repeat(np.arange(len(counts)), counts) if len(counts) > 1 else None
        return (*_checked(path, kind, vertices, faces), parts)
    if kind == "ply" and (direct := binary_ply(data)) is not None:
        return (*_checked(path, kind, *direct), None)
    if kind == "obj":
        direct = plain_obj(data)
        if direct is not None:
            return (*_checked(path, kind, *direct), None)
        vertices, faces, parts = read_obj(data, path.name)
        return (*_checked(path, kind, vertices, faces), parts)
    import trimesh  # heavy: imported on the first read

    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"), _quiet("trimesh"):
            warnings.simplefilter("ignore")
            loaded = trimesh.load_mesh(io.BytesIO(data), file_type=kind, process=False)
            if isinstance(loaded, trimesh.Scene):
                loaded = loaded.to_mesh()
            vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), np.float64)
            faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), np.int64)
    except Exception as exc:
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise IsochorError(
            f"{path.name}: not a readable {kind.upper()} file (damaged or truncated?): {detail}"
        ) from None
    vertices, faces = _checked(path, kind, vertices, faces)
    return vertices, faces, file_objects(kind, data, vertices, faces)


_OBJ_OBJECT = re.compile(rb"^[og][ \t]", re.M)
_STL_SOLIDS = re.compile(rb"^\s*endsolid", re.M)


def file_objects(kind: str, data: bytes, vertices: np.ndarray, faces: np.ndarray):
    """(f,) the file's object of each triangle as trimesh read them: an ASCII STL's
    ``solid`` blocks (an OBJ's objects come from :func:`.objfile.read_obj`); None for one
    object, or when the file's triangles cannot be matched one to one with what was read
    (nothing is assumed)."""
    if kind == "stl" and len(_STL_SOLIDS.findall(data)) > 1:
        blocks = _STL_SOLIDS.split(data)[:-1]
        counts = [len(re.findall(rb"^\s*facet\b", b, re.M)) for b in blocks]
        if sum(counts) != len(faces):
            return None
        return np.repeat(np.arange(len(counts)), counts)
    return None


def _checked(
    path: Path, kind: str, vertices: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The raw arrays, refused when they cannot be a triangle mesh of real numbers."""
    if faces.size == 0:
        raise IsochorError(
            f"{path.name}: no triangles found (not a valid {kind.upper()} file, or an empty mesh)"
        )
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise IsochorError(f"{path.name}: not a triangle mesh")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise IsochorError(f"{path.name}: a face refers to a vertex that does not exist")
    mask = np.zeros(len(vertices), dtype=bool)
    mask[faces] = True
    used = vertices[mask]
    if not np.all(np.isfinite(used)):
        raise IsochorError(f"{path.name}: a vertex has a coordinate that is not a number")
    largest = float(np.abs(used).max())
    if largest > MAX_COORDINATE:
        raise IsochorError(
            f"{path.name}: a vertex coordinate of {largest:.3g} is beyond "
            f"+-{MAX_COORDINATE:g} (a damaged file?)"
        )
    return vertices, faces


_OBJ_LINE = re.compile(rb"^(?![vf][ \t]|[#s]|[og][ \t]|[ \t\r]*$)", re.M)
_OBJ_V = re.compile(rb"^v[ \t]", re.M)
_OBJ_F = re.compile(rb"^f[ \t]", re.M)
_OBJ_VERTEX = re.compile(rb"^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t\r]*$", re.M)
_OBJ_TRIANGLE = re.compile(rb"^f[ \t]+([0-9]+)[ \t]+([0-9]+)[ \t]+([0-9]+)[ \t\r]*$", re.M)


def plain_obj(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices and triangles of a plain OBJ, read without trimesh (whose import costs a
    cold command about 0.3 s): ``v x y z`` and ``f i j k`` lines (positive indices, no
    texture or normal indices), comments, smoothing groups and at most one object or
    group name before the first face, nothing else. The same arrays as trimesh's reader
    gives (``process=False``): the vertices the triangles use, in the file's order. None
    for any other file (trimesh reads it, or says what is wrong with it)."""
    if _OBJ_LINE.search(data) or b"\\" in data:
        return None
    objects = list(_OBJ_OBJECT.finditer(data))
    first_face = _OBJ_F.search(data)
    if (
        first_face is None
        or len(objects) > 1
        or (objects and objects[0].start() > first_face.start())
    ):
        return None
    vertices = _OBJ_VERTEX.findall(data)
    triangles = _OBJ_TRIANGLE.findall(data)
    if len(vertices) != len(_OBJ_V.findall(data)) or len(triangles) != len(_OBJ_F.findall(data)):
        return None
    try:  # (a token that is not a number ends the parse: a warning, or an error)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            v = np.fromstring(b" ".join(b" ".join(t) for t in vertices).decode(), sep=" ")
            f = np.fromstring(b" ".join(b" ".join(t) for t in triangles), sep=" ", dtype=np.int64)
    except (ValueError, UnicodeDecodeError):
        return None
    if v.size != 3 * len(vertices) or f.size != 3 * len(triangles):
        return None
    v, f = v.reshape(-1, 3), f.reshape(-1, 3) - 1
    if len(v) == 0 or f.min() < 0 or f.max() >= len(v):
        return None  # (trimesh says what is wrong)
    used = np.zeros(len(v), dtype=bool)
    used[f] = True
    renumber = np.cumsum(used) - 1
    return v[used], renumber[f]


def binary_ply(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices and triangles of a binary little-endian PLY of the common layout, read
    straight into numpy (several times faster than trimesh on a large model): a vertex
    element of scalar properties with x, y and z, then a face element of one list of
    vertex indices, nothing else. Polygons of mixed sizes (Blender's PLY: triangles and
    quads, which trimesh's reader refuses) are split into fans (:func:`polygon_fans`).
    None for any other file (trimesh reads it, or says what is wrong with it)."""
    end = data.find(b"end_header\n", 0, SNIFF_BYTES)
    if not data.startswith(b"ply\n") or end < 0:
        return None
    try:
        header = PlyHeader.parse(data[: end + len(b"end_header\n")])
    except IsochorError:
        return None
    if (
        header.encoding != "binary_little_endian"
        or header.version != "1.0"
        or [e.name for e in header.elements] != ["vertex", "face"]
    ):
        return None
    vertex, face = header.elements
    names = [p.name for p in vertex.properties]
    if (
        vertex.has_lists
        or len(set(names)) != len(names)
        or not {"x", "y", "z"} <= set(names)
        or len(face.properties) != 1
        or face.properties[0].count is None
        or face.properties[0].name not in ("vertex_indices", "vertex_index")
    ):
        return None
    n_vertices, n_faces = vertex.rows, face.rows
    index = face.properties[0]
    assert index.count is not None  # a list property: checked above
    vtype = np.dtype([(p.name, "<" + p.kind) for p in vertex.properties])
    ftype = np.dtype([("n", "<" + index.count), ("i", "<" + index.kind, (3,))])
    start = header.body
    if n_faces <= 0 or ftype["i"].base.kind not in "iu" or ftype["n"].kind not in "iu":
        return None
    body = start + n_vertices * vtype.itemsize
    if len(data) < body:
        return None
    rows = np.frombuffer(data, vtype, n_vertices, start)
    vertices = np.empty((n_vertices, 3))
    for j, name in enumerate("xyz"):
        vertices[:, j] = rows[name]
    if len(data) - body == n_faces * ftype.itemsize:
        tris = np.frombuffer(data, ftype, n_faces, body)
        if np.all(tris["n"] == 3):
            return vertices, tris["i"].astype(np.int64)
    faces = polygon_fans(data, body, n_faces, ftype["n"], ftype["i"].base)
    return None if faces is None else (vertices, faces)


def polygon_fans(
    data: bytes, start: int, rows: int, count: np.dtype, index: np.dtype
) -> np.ndarray | None:
    """(t, 3) int64 the fan triangles of ``rows`` polygons of a binary PLY's face list
    (a ``count`` then that many ``index`` values each, from ``start``; mixed triangles and
    quads, as Blender writes them), corner 0 to each other side. None unless the rows end
    exactly at the end of ``data`` with every polygon of three corners or more, of more
    than one size (trimesh reads polygons of one size: its triangles, in its order)."""
    step, size = count.itemsize, index.itemsize
    unpack = struct.Struct("<" + count.char).unpack_from
    u8 = np.frombuffer(data, np.uint8)
    counts = np.empty(rows, dtype=np.int64)
    at = np.empty(rows, dtype=np.int64)  # where each polygon's indices start
    pos, end, k, block, prev, same = start, len(data), 0, 64, -1, 0
    # a row's place is known only from the rows before it: one by one, but after 8 rows
    # of one size, blocks of rows of that size at once (doubling while they hold)
    while k < rows:
        if pos + step > end:
            return None
        n = int(unpack(data, pos)[0])
        length = step + n * size
        same, prev = (same + 1 if n == prev else 0), n
        if same < 8:
            at[k], counts[k] = pos + step, n
            pos, k = pos + length, k + 1
            continue
        m = min(rows - k, block, (end - pos) // length)
        if m < 1:
            return None
        offsets = pos + length * np.arange(m)
        ahead = u8[offsets[:, None] + np.arange(step)].view("<" + count.char).ravel()
        run = m if np.all(ahead == n) else int(np.argmin(ahead == n))
        at[k : k + run], counts[k : k + run] = offsets[:run] + step, n
        pos, k = pos + run * length, k + run
        block, same = (2 * block, same) if run == m else (64, 0)
    if pos != end or counts.min() < 3 or counts.min() == counts.max():
        return None  # (polygons of one size: trimesh reads them, as it always has)
    first = np.cumsum(counts) - counts  # each polygon's first corner in the flat list
    corner = np.arange(int(counts.sum())) - np.repeat(first, counts)
    where = np.repeat(at, counts) + size * corner
    raw = np.frombuffer(data, np.uint8)[where[:, None] + np.arange(size)]
    flat = np.ascontiguousarray(raw).view("<" + index.char).ravel().astype(np.int64)
    fans = counts - 2
    apex = np.repeat(first, fans)
    side = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    return np.stack([flat[apex], flat[apex + side], flat[apex + side + 1]], axis=1)


@contextmanager
def _quiet(logger: str):
    """Silence a library's logging for a while: trimesh logs what it tolerates in a damaged
    file (with a traceback), which is not for the user; what matters reaches them as one
    :class:`IsochorError` or a warning of the repair."""
    log = logging.getLogger(logger)  # its modules' loggers inherit the level
    before = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        log.setLevel(before)


def _sniff(path: Path, kind: str, head: bytes, size: int) -> None:
    """Refuse at once, from its first bytes, a file that cannot be of its format (a file
    of zeros, a renamed image), before a parser spends memory and time on all of it."""
    if not head.strip():
        return  # empty or blank: said by the caller
    text_head = head.lstrip(b"\xef\xbb\xbf")  # a UTF-8 byte order mark
    if kind == "ply":
        if not text_head.startswith(b"ply"):
            raise IsochorError(f"{path.name}: not a PLY file (it does not start with 'ply')")
        if b"end_header" not in head and size > len(head):
            raise IsochorError(f"{path.name}: not a PLY file (no end_header in its first bytes)")
    elif kind == "stl":
        ascii_stl = text_head.lstrip().startswith(b"solid") and b"\0" not in head
        if not ascii_stl and len(head) >= 84:
            count = int(np.frombuffer(head[80:84], "<u4")[0])
            if count == 0 or 84 + 50 * count > size:
                raise IsochorError(
                    f"{path.name}: not a binary STL file: its header says {count} "
                    f"triangle(s), which need {84 + 50 * count} bytes, and it has {size}"
                )
    elif kind == "glb":
        if not head.startswith(b"glTF"):
            raise IsochorError(f"{path.name}: not a GLB file (it does not start with 'glTF')")
    elif b"\0" in head:
        raise IsochorError(f"{path.name}: not a {kind.upper()} file (it is not text)")


# -- writing ----------------------------------------------------------------------------------
def save_mesh(
    path: str | Path, mesh: TriMesh, inputs: Iterable[tuple[str | Path, str]] = ()
) -> None:
    """Write ``mesh`` as OBJ, PLY or STL (by the extension), atomically.

    OBJ keeps every digit (``%.17g``); PLY is binary with float64 vertices; STL is binary
    with float32 coordinates, as the format defines.

    ``inputs``: ``(path, role)`` of files the mesh must not replace (the model it was
    made from), see :func:`isochor.core.io.atomic.check_outputs`.

    Raises
    ------
    IsochorError
        An unsupported extension; a folder that does not exist or cannot be written; a
        path that names one of ``inputs``, a folder or a device.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_FORMATS:
        known = listing(WRITE_FORMATS)
        raise IsochorError(
            f"{path.name}: cannot write {suffix or 'a file without extension'};"
            f" use one of {known} (by the file extension)"
        )
    atomic_write_bytes(path, mesh_bytes(mesh, suffix), inputs)


def mesh_bytes(mesh: TriMesh, suffix: str) -> bytes:
    """The file contents of ``mesh`` in the format of ``suffix`` (see
    :data:`isochor.core.io.formats.WRITE_FORMATS`)."""
    v, f = mesh.vertices, mesh.faces
    if suffix == ".obj":
        buf = io.BytesIO()
        buf.write(b"# written by Isochor\n")
        np.savetxt(buf, v, fmt="v %.17g %.17g %.17g")
        np.savetxt(buf, f + 1, fmt="f %d %d %d")
        return buf.getvalue()
    if suffix == ".ply":
        header = (
            "ply\nformat binary_little_endian 1.0\ncomment written by Isochor\n"
            f"element vertex {len(v)}\nproperty double x\nproperty double y\n"
            f"property double z\nelement face {len(f)}\n"
            "property list uchar int vertex_indices\nend_header\n"
        ).encode("ascii")
        rows = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
        rows["n"], rows["i"] = 3, f
        return header + v.astype("<f8").tobytes() + rows.tobytes()
    if suffix == ".stl":
        tri = v[f]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
        rows = np.zeros(len(f), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
        rows["n"], rows["v"] = normals, tri
        head = b"binary STL written by Isochor".ljust(80, b" ")
        return head + np.uint32(len(f)).tobytes() + rows.tobytes()
    if suffix == ".off":
        buf = io.BytesIO()
        buf.write(f"OFF\n{len(v)} {len(f)} 0\n".encode())
        np.savetxt(buf, v, fmt="%.17g %.17g %.17g")
        np.savetxt(buf, f, fmt="3 %d %d %d")
        return buf.getvalue()
    if suffix in GLTF_FORMATS:
        import trimesh

        tm = trimesh.Trimesh(v, f, process=False)
        if suffix == ".glb":
            return cast(bytes, tm.export(file_type="glb"))
        files = cast(dict, tm.export(file_type="gltf", embed_buffers=True))
        return next(data for key, data in files.items() if key.endswith(".gltf"))
    raise IsochorError(f"cannot write {suffix!r} files")
