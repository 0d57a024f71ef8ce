"""The PLY header (``ply`` ... ``end_header``): its one parser and the one table of PLY's
scalar types.

Both readers of PLY files stand on it: the fast binary reader of
:mod:`isochor.core.io.meshio` (which takes only the common triangle layout and leaves every
other file to trimesh) and the rewriting of :mod:`isochor.core.io.roundtrip` (which keeps
every byte but the positions). A header names the data's encoding and its elements in
order, each with a count and its properties: a scalar, or a list with the type of its
count.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import IsochorError

#: PLY's scalar type names (the old and the new spelling) -> numpy's type code, without a
#: byte order (prefix :attr:`PlyHeader.byte_order` for the data's)
SCALARS: dict[str, str] = {
    **dict.fromkeys(("char", "int8"), "i1"),
    **dict.fromkeys(("uchar", "uint8"), "u1"),
    **dict.fromkeys(("short", "int16"), "i2"),
    **dict.fromkeys(("ushort", "uint16"), "u2"),
    **dict.fromkeys(("int", "int32"), "i4"),
    **dict.fromkeys(("uint", "uint32"), "u4"),
    **dict.fromkeys(("float", "float32"), "f4"),
    **dict.fromkeys(("double", "float64"), "f8"),
}
#: the data encodings -> numpy's byte order prefix ("" for ASCII text)
ENCODINGS: dict[str, str] = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}


@dataclass(frozen=True)
class Property:
    """One property of an element: ``name``, its numpy type code ``kind`` (without a byte
    order) and, for a list, the type code of its count (``count`` None for a scalar)."""

    name: str
    kind: str
    count: str | None = None


@dataclass(frozen=True)
class Element:
    """One element of the header (``vertex``, ``face``, ...): how many rows, and the
    properties of each row in order."""

    name: str
    rows: int
    properties: tuple[Property, ...]

    @property
    def has_lists(self) -> bool:
        return any(p.count is not None for p in self.properties)


@dataclass(frozen=True)
class PlyHeader:
    """What a PLY header says.

    Attributes
    ----------
    encoding : ``"ascii"``, ``"binary_little_endian"`` or ``"binary_big_endian"``; None
        when the header has no format line
    version : the format line's version (``"1.0"``), None when it has none
    elements : the elements in the order their data follows
    body : the offset of the first byte after the header (the data)
    """

    encoding: str | None
    version: str | None
    elements: tuple[Element, ...]
    body: int

    @property
    def byte_order(self) -> str:
        """numpy's prefix for the data: ``"<"``, ``">"``, or ``""`` for ASCII (and for a
        header without a format line)."""
        return ENCODINGS.get(self.encoding or "", "")

    def element(self, name: str) -> int | None:
        """The index of the first element called ``name``, None when there is none."""
        return next((i for i, e in enumerate(self.elements) if e.name == name), None)

    @classmethod
    def parse(cls, data: bytes, name: str = "model") -> PlyHeader:
        """Read the header at the start of ``data`` (a UTF-8 byte order mark allowed).

        Raises
        ------
        IsochorError
            Not a PLY header, or a line of it that is not valid (one sentence naming
            ``name``).
        """
        end = data.find(b"end_header")
        if not data.lstrip(b"\xef\xbb\xbf").startswith(b"ply") or end < 0:
            raise IsochorError(f"{name}: not a PLY file (no ply ... end_header header)")
        encoding, version = None, None
        elements: list[tuple[str, int, list[Property]]] = []
        for line in data[:end].decode("latin-1").splitlines()[1:]:
            w = line.split() or ["comment"]
            try:
                if w[0] == "format":
                    if w[1] not in ENCODINGS:
                        raise ValueError
                    encoding, version = w[1], (w[2] if len(w) > 2 else None)
                elif w[0] == "element" and int(w[2]) >= 0:
                    elements.append((w[1], int(w[2]), []))
                elif w[0] == "property" and len(w) == (5 if w[1] == "list" else 3):
                    count = SCALARS[w[2]] if len(w) == 5 else None
                    elements[-1][2].append(Property(w[-1], SCALARS[w[-2]], count))
                elif w[0] not in ("comment", "obj_info"):
                    raise ValueError
            except (ValueError, KeyError, IndexError):
                line = line.strip()[:60]
                raise IsochorError(f"{name}: not a valid PLY header line: {line!r}") from None
        body = data.find(b"\n", end) + 1 or len(data)
        parts = tuple(Element(n, rows, tuple(props)) for n, rows, props in elements)
        return cls(encoding, version, parts, body)
