"""The OBJ reader: vertices, triangles and objects of a Wavefront OBJ file, as the format
defines them, every error naming the file and the line.

- ``v x y z [w | r g b]``: a vertex; vertices are numbered from 1 in the order they appear.
- ``f a b c ...``: a polygon of three corners or more, each ``v``, ``v/vt``, ``v//vn`` or
  ``v/vt/vn``; a positive index counts from the first vertex of the file (1), a negative
  one back from the last vertex read so far (-1). Index 0, an index past the vertices, a
  polygon of fewer than three corners (an empty ``f`` included) are refused with the line,
  in the file's terms. Polygons become fans from their first corner (trimesh's triangles).
- ``o`` and ``g`` start the file's objects: the object of each triangle is returned, so
  objects closed on their own are kept apart (:func:`isochor.core.io.repair.weld_parts`),
  whether their faces count from the start or back.
- A line ending in ``\\`` continues on the next. Everything else (``vt``, ``vn``, ``l``,
  ``usemtl``, ``mtllib``, ``s``, free-form statements, comments) is not geometry and is
  skipped; material libraries are never opened here.

The plain fast path of :mod:`isochor.core.io.meshio` (``plain_obj``) gives the same arrays
for the files it takes.
"""

from __future__ import annotations

import numpy as np

from ..errors import IsochorError
from ..validate import MAX_COORDINATE

_CUT = 30  # longest token shown in a message


def _shown(token: bytes) -> str:
    text = token.decode("latin-1")
    return repr(text if len(text) <= _CUT else text[: _CUT - 3] + "...")


def _lines(data: bytes):
    """(line number, tokens) of each statement: CRLF, CR and LF end lines, a UTF-8 byte
    order mark is skipped, a trailing backslash joins the next line to this statement,
    ``#`` starts a comment."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    text = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    pending: list[bytes] = []
    start = 0
    for number, line in enumerate(text.split(b"\n"), 1):
        line = line.split(b"#", 1)[0] if b"#" in line else line
        if line.endswith(b"\\"):
            if not pending:
                start = number
            pending.append(line[:-1])
            continue
        if pending:
            line, number = b" ".join([*pending, line]), start
            pending = []
        tokens = line.split()
        if tokens:
            yield number, tokens
    if pending:
        yield start, b" ".join(pending).split()


def read_obj(data: bytes, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Vertices ``(m, 3) float64`` (those the triangles use, in the file's order),
    triangles ``(f, 3) int64`` and the object of each triangle (None: one object).

    Raises
    ------
    IsochorError
        ``name: line N: ...``: a vertex without three numbers, a face corner that is not a
        vertex index, index 0, an index past the vertices, a face of fewer than three
        corners; or a file without faces."""
    coords: list[bytes] = []
    v_line: list[int] = []
    corners: list[int] = []  # vertex (0-based) of every corner, polygons one after another
    sizes: list[int] = []  # corners per polygon
    f_line: list[int] = []
    f_part: list[int] = []
    relative: list[tuple[int, int, int]] = []  # (line, index, vertices so far) to check
    forward: list[tuple[int, int]] = []  # (line, index) past the vertices read so far
    part = 0
    for number, tokens in _lines(data):
        key = tokens[0]
        if key == b"v":
            if len(tokens) < 4:
                raise IsochorError(
                    f"{name}: line {number}: a vertex needs three coordinates (v x y z), "
                    f"this one has {len(tokens) - 1}"
                )
            coords += tokens[1:4]
            v_line.append(number)
        elif key == b"f":
            n = len(tokens) - 1
            if n < 3:
                raise IsochorError(
                    f"{name}: line {number}: a face needs at least three vertices, "
                    f"this one has {n}" + (" (an empty f line)" if n == 0 else "")
                )
            seen = len(v_line)
            for token in tokens[1:]:
                head = token.split(b"/", 1)[0]
                try:
                    if len(head) > 19:
                        raise ValueError
                    index = int(head)
                except ValueError:
                    raise IsochorError(
                        f"{name}: line {number}: {_shown(token)} is not a vertex index "
                        "(f takes v, v/vt, v//vn or v/vt/vn, v a whole number)"
                    ) from None
                if index == 0:
                    raise IsochorError(
                        f"{name}: line {number}: vertex index 0 does not exist "
                        "(OBJ counts vertices from 1, or back from -1)"
                    )
                if index < 0:
                    if -index > seen:
                        relative.append((number, index, seen))
                    corners.append(seen + index)
                else:
                    if index > seen:
                        forward.append((number, index))
                    corners.append(index - 1)
            sizes.append(n)
            f_line.append(number)
            f_part.append(part)
        elif key in (b"o", b"g"):
            part += 1
    total = len(v_line)
    for number, index, seen in relative:
        raise IsochorError(
            f"{name}: line {number}: vertex index {index} does not exist: it counts back "
            f"from the {seen} vertices read before this line"
        )
    for number, index in forward:
        if index > total:
            raise IsochorError(
                f"{name}: line {number}: vertex index {index} does not exist: the file has "
                f"{total} vertices"
            )
    if not sizes:
        raise IsochorError(f"{name}: no faces found (no f lines)")
    vertices = _numbers(coords, v_line, name)
    flat = np.asarray(corners, dtype=np.int64)
    counts = np.asarray(sizes, dtype=np.int64)
    first = np.cumsum(counts) - counts
    fans = counts - 2
    apex = np.repeat(first, fans)
    side = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    faces = np.stack([flat[apex], flat[apex + side], flat[apex + side + 1]], axis=1)
    parts = np.repeat(np.asarray(f_part, dtype=np.int64), fans)
    used = np.zeros(total, dtype=bool)
    used[faces] = True
    bad = used & ~np.all(np.abs(vertices) <= MAX_COORDINATE, axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        what = "is not a number" if not np.all(np.isfinite(vertices[k])) else "is beyond +-1e+15"
        raise IsochorError(f"{name}: line {v_line[k]}: a coordinate of this vertex {what}")
    renumber = np.cumsum(used) - 1
    return vertices[used], renumber[faces], (parts if len(np.unique(parts)) > 1 else None)


def _numbers(tokens: list[bytes], lines: list[int], name: str) -> np.ndarray:
    """The vertices' coordinates, or an error naming the line of the first that is not a
    number."""
    if not tokens:
        return np.zeros((0, 3))
    try:
        return np.array(tokens, dtype=np.bytes_).astype(np.float64).reshape(-1, 3)
    except ValueError:
        for i, token in enumerate(tokens):
            try:
                float(token)
            except ValueError:
                raise IsochorError(
                    f"{name}: line {lines[i // 3]}: {_shown(token)} is not a number"
                ) from None
        raise IsochorError(f"{name}: a vertex coordinate is not a number") from None
