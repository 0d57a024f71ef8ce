"""The files a model reads besides itself, and where a glTF may read them from.

- :func:`model_inputs`: the model file and every file it names that exists: an OBJ's
  material libraries (``mtllib``) and their textures (``map_Kd``, ``bump``, ...), a glTF's
  buffers and images. Every output (the command line's, ``Session.save``/``export``, the
  window's) is checked against this list before any work
  (:func:`isochor.core.io.atomic.check_outputs`), so no output destroys a file the model
  needs.
- :func:`confined`: a glTF ``uri``, or an OBJ's material library or texture name, as a
  file under the model's folder, or one line saying why it is refused (an absolute path, a
  scheme such as ``file:`` or ``http:``, a ``..`` leading out of the folder, a link
  pointing out of it). ``data:`` URIs are read in place. Nothing outside the model's
  folder is ever opened: :func:`outside_names` says which names were refused, one line
  each, for the loader's warnings.

Listing never fails: a file that cannot be read or parsed adds nothing (reading it later
says what is wrong with it).
"""

from __future__ import annotations

import contextlib
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


def confined(base_dir: str | Path | None, uri: str, what: str, owner: str = "glTF") -> Path:
    """The file a glTF's relative ``uri`` (or, with ``owner`` "OBJ", a material library's
    or texture's name, taken literally) names under ``base_dir`` (None: only the name's own
    form is checked, and the relative path is returned).

    Raises
    ------
    IsochorError
        The name is absolute, has a scheme, or leads out of the folder (by ``..`` or by a
        symbolic link): a model may only read files beside it or below."""
    text = unquote(str(uri)) if owner == "glTF" else str(uri)
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
    tail = ", or embed them as data: URIs" if owner == "glTF" else ""
    raise IsochorError(
        f"its {what} {shown!r} is refused: {why}; a{'n' if owner == 'OBJ' else ''} {owner} "
        f"may only name files in its own folder or below{tail}"
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


def _names(body: bytes, folder: Path, base: Path, refused: list[str]) -> list[Path]:
    """The files a statement's body names, relative to ``folder``, confined to ``base``
    (the model's folder): the whole body if it is a file (a name with spaces), else each
    word that is. A name leading out of ``base`` is never opened, nor even looked at: its
    sentence goes to ``refused``."""
    body = body.strip()
    if not body:
        return []
    words = body.split()
    # the whole rest, or the rest after some options (-s 1 1 1 wood map.png): a name
    # with spaces
    for start in range(len(words)):
        whole = _inside(folder, base, os.fsdecode(b" ".join(words[start:])))
        if whole is not None and _regular(whole):
            return [whole]
    found = []
    for w in words:
        path = _inside(folder, base, os.fsdecode(w), refused)
        if path is not None and _regular(path):
            found.append(path)
    return found


def _inside(folder: Path, base: Path, name: str, refused: list[str] | None = None):
    """``folder / name`` when it lies in ``base`` or below, else None (and, given
    ``refused``, the sentence saying so, for a name that looks like a file)."""
    try:
        relative = os.path.relpath(os.path.join(folder, name), base)
        path = confined(base, relative, "file", "OBJ") if not os.path.isabs(name) else None
    except (IsochorError, ValueError):
        path = None
    if path is None and refused is not None and re.search(r"[./\\]", name):
        shown = name if len(name) <= 80 else name[:77] + "..."
        line = (
            f"{shown!r} is outside the model's folder: not read (an OBJ may only name "
            "files in its own folder or below)"
        )
        if line not in refused:
            refused.append(line)
    return path


def _obj_files(path: Path, refused: list[str] | None = None) -> list[tuple[Path, str]]:
    found = []
    refused = [] if refused is None else refused
    base = path.parent
    for m in _MTLLIB.finditer(_read_head(path)):
        for lib in _names(m.group(1), base, base, refused):
            found.append((lib, f"the model's material library {lib.name}"))
            for t in _textures(lib, base, refused):
                found.append((t, f"the model's texture {t.name}"))
    return found


def outside_names(path: str | Path) -> list[str]:
    """One sentence for each name an OBJ's ``mtllib`` lines or its material libraries'
    texture statements give that leads out of the model's folder (never opened)."""
    path = Path(os.path.abspath(path))
    refused: list[str] = []
    if path.suffix.lower() == ".obj":
        with contextlib.suppress(OSError, ValueError):
            _obj_files(path, refused)
    return refused


def _textures(library: Path, base: Path, refused: list[str]) -> list[Path]:
    try:
        text = _read_head(library)
    except OSError:
        return []
    found: list[Path] = []
    for m in _MAPS.finditer(text):
        # options come first (-s 1 1 1 -clamp on ...): the file is the whole rest, a name
        # with spaces, or else its words that are files (the last one, in practice)
        names = _names(m.group(1), library.parent, base, refused)
        found += [p for p in names if p not in found]
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
