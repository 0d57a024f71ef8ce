"""Writing the user's files without ever destroying one.

Two promises, for the command line and the window alike:

- **Checked before any work** (:func:`check_outputs`): an output that is a folder, a
  device, a pipe or a socket, that names an input (the model, the scenario) or another
  output of the same run, or whose folder is missing or cannot be written, is refused with
  one sentence that names the path as the user gave it. A symbolic link given as an output
  writes the file it points to and stays a link.
- **All or none** (:func:`write_outputs`): every output is first written to a temporary
  file beside its target (``.NAME.XXXX.tmp``) and flushed to disk; only then are they
  renamed into place, one after the other. If anything fails, or the process is
  interrupted, the renamed ones are put back as they were (from a hard link, or a copy,
  of the file they replaced) and no temporary file is left.

Temporary files not yet renamed are listed in :data:`PENDING`; :func:`discard_pending`
removes them (the command line calls it on its way out, whatever happened).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import IsochorError

#: temporary files written but not yet renamed into place (absolute paths)
PENDING: set[str] = set()


@dataclass(frozen=True)
class Output:
    """One file to write.

    Attributes
    ----------
    path : the path as the user gave it (used in every message)
    target : where the bytes go: ``path`` made absolute, or the file a symbolic link names
    role : how messages call it ("--out", "the report", ...)
    """

    path: Path
    target: Path
    role: str


# -- checks, before any work --------------------------------------------------------------
def check_outputs(
    outputs: Iterable[tuple[str | Path, str]],
    inputs: Iterable[tuple[str | Path, str]] = (),
    *,
    probe: bool = True,
) -> list[Output]:
    """Check that every output can be written without destroying anything.

    Parameters
    ----------
    outputs : ``(path, role)`` pairs; ``role`` names the output in messages ("--out")
    inputs : ``(path, role)`` pairs of the files the outputs are made from ("the model")
    probe : also create and remove a temporary file in each output folder, the one sure
        test that it can be written (permissions, a read-only disk, no such folder)

    Returns
    -------
    list of :class:`Output`, in the order given

    Raises
    ------
    IsochorError
        The first problem found, as one sentence naming the user's path.
    """
    checked: list[Output] = []
    known_inputs = [(p, role) for p, role in inputs if "\0" not in str(p)]
    for raw, role in outputs:
        path = Path(raw)
        target = _target(path)
        _check_kind(path, target)
        for other in checked:
            if _same_file(other.target, target):
                raise IsochorError(
                    f"{path}: {role} and {other.role} name the same file; give each its own"
                )
        for source, what in known_inputs:
            if _same_file(Path(os.path.realpath(source)), target):
                raise IsochorError(
                    f"{path}: {role} would overwrite {what} it is made from; "
                    "choose another file name"
                )
        if probe:
            _probe_folder(path, target.parent)
        checked.append(Output(path, target, role))
    return checked


def _target(path: Path) -> Path:
    """Where writing ``path`` puts the bytes: the file a symbolic link (chain) names."""
    if "\0" in str(path):
        raise IsochorError(f"{str(path)!r}: not a valid file name (it holds a NUL byte)")
    try:
        absolute = Path(os.path.abspath(path))
        if not absolute.is_symlink():
            return absolute
        real = Path(os.path.realpath(absolute))
        if real.is_symlink():
            raise IsochorError(f"{path}: a loop of symbolic links; give a file name")
        return real
    except OSError as exc:
        raise IsochorError(f"{path}: {exc.strerror or exc}") from None


def _check_kind(path: Path, target: Path) -> None:
    try:
        info = target.stat()
    except FileNotFoundError:
        info = None
    except OSError as exc:
        raise IsochorError(f"{path}: {exc.strerror or exc}") from None
    if info is not None:
        if stat.S_ISDIR(info.st_mode):
            raise IsochorError(f"{path}: is a folder, not a file name")
        if not stat.S_ISREG(info.st_mode):
            raise IsochorError(
                f"{path}: is not a regular file (a device, a pipe or a socket); "
                "give the name of a file to write"
            )
        if not os.access(target, os.W_OK):
            raise IsochorError(f"{path}: the file is read-only")
    folder = target.parent
    if not folder.is_dir():
        raise IsochorError(f"{path}: the folder {folder} does not exist")


def _same_file(a: Path, b: Path) -> bool:
    """The same file: the same absolute path, or the same inode (a hard link)."""
    if os.path.normcase(a) == os.path.normcase(b):
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def _probe_folder(path: Path, folder: Path) -> None:
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise IsochorError(
            f"{path}: cannot write in the folder {folder} ({exc.strerror or exc})"
        ) from None
    os.close(fd)
    os.unlink(tmp)


# -- writing, all or none ------------------------------------------------------------------
def write_outputs(
    items: Sequence[tuple[Output, bytes]], on_commit: Callable[[], None] | None = None
) -> None:
    """Write every output or none of them.

    Each is written to a temporary file beside its target and flushed; then
    ``on_commit()`` is called (the command line stops answering signals there) and all
    are renamed into place. On any failure or interrupt the files already renamed are
    restored (or removed, if they are new) and every temporary file is removed.

    Raises
    ------
    IsochorError
        A file could not be written; the message names the user's path and the reason.
    """
    temps: list[str] = []
    backups: list[str] = []
    done: list[tuple[Output, str | None]] = []  # renamed into place, with the old file
    current: Output | None = None
    try:
        for out, data in items:
            current = out
            temps.append(_write_temp(out.target, data))
        if on_commit is not None:
            on_commit()
        for (out, _), tmp in zip(items, temps):
            current = out
            backup = _keep_old(out.target)
            if backup is not None:
                backups.append(backup)
            os.replace(tmp, out.target)
            PENDING.discard(tmp)
            done.append((out, backup))
    except BaseException as exc:
        try:
            _roll_back(done)
        finally:
            discard(temps + backups)
        if isinstance(exc, OSError) and current is not None:
            raise IsochorError(
                f"{current.path}: cannot write the file ({exc.strerror or exc})"
            ) from None
        raise
    discard(backups)
    for folder in {str(out.target.parent) for out, _ in items}:
        _sync_folder(folder)


def atomic_write_bytes(
    path: str | Path, data: bytes, inputs: Iterable[tuple[str | Path, str]] = ()
) -> None:
    """Write one file atomically (see :func:`write_outputs`); a symbolic link writes its
    target. ``inputs`` are ``(path, role)`` of files it must not replace (see
    :func:`check_outputs`). Raises :class:`IsochorError` naming ``path`` when it cannot be
    written."""
    write_outputs([(check_outputs([(path, "the file")], inputs, probe=False)[0], data)])


def atomic_write_text(
    path: str | Path, text: str, inputs: Iterable[tuple[str | Path, str]] = ()
) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically; see :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"), inputs)


def discard(paths: Iterable[str]) -> None:
    """Remove these temporary files (those that exist) and forget them."""
    for p in list(paths):
        with contextlib.suppress(OSError):
            os.unlink(p)
        PENDING.discard(p)


def discard_pending() -> None:
    """Remove every temporary file not yet renamed into place."""
    discard(list(PENDING))


def _write_temp(target: Path, data: bytes) -> str:
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    PENDING.add(tmp)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _file_mode(target))
    except BaseException:
        discard([tmp])
        raise
    return tmp


def _keep_old(target: Path) -> str | None:
    """A temporary second name (a hard link, else a copy) of the file about to be replaced,
    to put back if a later output fails; None when there is no such file."""
    if not target.exists():
        return None
    fd, backup = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    PENDING.add(backup)
    try:
        os.unlink(backup)
        os.link(target, backup)
    except OSError:  # no hard links on this file system
        shutil.copy2(target, backup)
    return backup


def _roll_back(done: Sequence[tuple[Output, str | None]]) -> None:
    """Put back the files these outputs replaced; remove the ones that are new."""
    for out, backup in reversed(done):
        try:
            if backup is None:
                os.unlink(out.target)
            else:
                os.replace(backup, out.target)
                PENDING.discard(backup)
        except OSError:
            pass


def _sync_folder(folder: str) -> None:
    """Flush the folder's entries (the renames) to disk, where the system allows it."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _file_mode(path: Path) -> int:
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask
