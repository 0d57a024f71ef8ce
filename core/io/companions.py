"""The files a model reads besides itself, and where a glTF may read them from.

- :func:`model_inputs`: the model file and every file it names that exists: an OBJ's
  material libraries (``mtllib``) and their textures (``map_Kd``, ``bump``, ...), a glTF's
  buffers and images. Every output (the command line's, ``Session.save``/``export``, the
  window's) is checked against this list before any work
  (:func:`isochor.core.io.atomic.check_outputs`), so no output destroys a file the model
  needs.
- :func:`confined`: a glTF ``uri`` as a file under the model's folder, or one line saying
  why it is refused (an absolute path, a scheme such as ``file:`` or ``http:``, a ``..``
  leading out of the folder, a link pointing out of it). ``data:`` URIs are read in place.

Listing never fails: a file that cannot be read or parsed adds nothing (reading it later
says what is wrong with it).
"""

from __future__ import annotations

import json
import os
import re
import stat
import struct
from pathlib import Path
from urllib.parse import unquote

from ..errors import IsochorError

#: the most bytes read of a file to find the names it holds (an OBJ's mtllib lines, a
#: material library, a glTF's JSON); beyond it the rest of a file is not searched
MAX_SCAN_BYTES = 512 * 2**20

_MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+([^\r\n#]*)", re.M)
#: a material library's statements that name a file (the file name comes last)
_MAPS = re.compile(rb"^[ \t]*(?:map_\w+|bump|disp|decal|refl|norm)[ \t]+([^\r\n#]*)", re.M | re.I)
_URI_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


def model_inputs(path: str | Path, role: str = "the model") -> list[tuple[Path, str]]:
    """``(path, role)`` of the model file and of every existing file it reads.

    Roles name the file for the user: ``"the model"``, ``"the model's material library
    m.mtl"``, ``"the model's texture wood.png"``, ``"the model's buffer ico.bin"``."""
    path = Path(os.path.abspath(path))
    found = [(path, role)]
    try:
        suffix = path.suffix.lower()
        if suffix == ".obj":
            found += _obj_files(path)
        elif suffix in (".gltf", ".glb"):
            found += _gltf_files(path)
    except (OSError, ValueError, LookupError, TypeError, RecursionError, struct.error):
        pass  # unreadable or damaged: reading the model will say so
    return found


def confined(base_dir: str | Path | None, uri: str, what: str) -> Path:
    """The file a glTF's relative ``uri`` names under ``base_dir`` (None: only the URI's
    own form is checked, and the relative path is returned).

    Raises
    ------
    IsochorError
        The URI is absolute, has a scheme, or leads out of the folder (by ``..`` or by a
        symbolic link): a model may only read files beside it or below."""
    text = unquote(str(uri))
    why = None
    if _URI_SCHEME.match(text) or text.startswith(("/", "\\")) or os.path.isabs(text):
        why = "it is not a relative path"
    elif "\0" in text:
        why = "it holds a NUL byte"
    else:
        parts = Path(text.replace("\\", "/")).parts
        if ".." in parts:
            why = "it leads out of the model's folder"
    if why is None and base_dir is None:
        return Path(text)
    if why is None and base_dir is not None:
        base = Path(os.path.realpath(base_dir))
        path = Path(base_dir) / text
        real = Path(os.path.realpath(path))
        if real != base and base not in real.parents:
            why = "it leads out of the model's folder (a link)"
        else:
            return path
    shown = text if len(text) <= 80 else text[:77] + "..."
    raise IsochorError(
        f"its {what} {shown!r} is refused: {why}; a glTF may only name files in its own "
        "folder or below, or embed them as data: URIs"
    )


# -- OBJ ------------------------------------------------------------------------------------
def _regular(path: Path) -> bool:
    """A regular file (never open a FIFO or a device: reading one can block for ever)."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def _read_head(path: Path) -> bytes:
    if not _regular(path):
        return b""
    with open(path, "rb") as fh:
        return fh.read(MAX_SCAN_BYTES)


def _names(body: bytes, folder: Path) -> list[Path]:
    """The files a statement's body names: the whole body if it is a file (a name with
    spaces), else each word that is."""
    body = body.strip()
    if not body:
        return []
    words = body.split()
    # the whole rest, or the rest after some options (-s 1 1 1 wood map.png): a name
    # with spaces
    for start in range(len(words)):
        whole = folder / os.fsdecode(b" ".join(words[start:]))
        if _regular(whole):
            return [whole]
    return [p for p in (folder / os.fsdecode(w) for w in words) if _regular(p)]


def _obj_files(path: Path) -> list[tuple[Path, str]]:
    found = []
    for m in _MTLLIB.finditer(_read_head(path)):
        for lib in _names(m.group(1), path.parent):
            found.append((lib, f"the model's material library {lib.name}"))
            for t in _textures(lib):
                found.append((t, f"the model's texture {t.name}"))
    return found


def _textures(library: Path) -> list[Path]:
    try:
        text = _read_head(library)
    except OSError:
        return []
    found: list[Path] = []
    for m in _MAPS.finditer(text):
        # options come first (-s 1 1 1 -clamp on ...): the file is the whole rest, a name
        # with spaces, or else its words that are files (the last one, in practice)
        found += [p for p in _names(m.group(1), library.parent) if p not in found]
    return found


# -- glTF -----------------------------------------------------------------------------------
def _gltf_json(path: Path) -> dict:
    if not _regular(path):
        return {}
    if path.suffix.lower() == ".gltf":
        with open(path, "rb") as fh:
            text = fh.read(MAX_SCAN_BYTES)
    else:
        with open(path, "rb") as fh:
            head = fh.read(20)
            if len(head) < 20 or head[:4] != b"glTF":
                return {}
            size, kind = struct.unpack_from("<2I", head, 12)
            if kind != 0x4E4F534A or size > MAX_SCAN_BYTES:
                return {}
            text = fh.read(size)
    doc = json.loads(text.decode("utf-8-sig"))
    return doc if isinstance(doc, dict) else {}


def _gltf_files(path: Path) -> list[tuple[Path, str]]:
    doc = _gltf_json(path)
    found = []
    for kind, what in (("buffers", "buffer"), ("images", "image")):
        items = doc.get(kind, [])
        for item in items if isinstance(items, list) else ():
            uri = item.get("uri") if isinstance(item, dict) else None
            if not isinstance(uri, str) or uri.startswith("data:"):
                continue
            try:
                file = confined(path.parent, uri, what)
            except IsochorError:
                continue  # never read: reading the model refuses it
            if _regular(file):
                found.append((file, f"the model's {what} {file.name}"))
    return found
