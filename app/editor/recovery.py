"""Never lose work: the recovery file of a document with unsaved changes (Qt-free).

While a document has unsaved changes, the window writes a recovery file after each edit
(debounced, :mod:`isochor.app.window.autosave`): the scenario of the current state, with
its model as an absolute path, and what the document was (its file, its title). The file
is written atomically (a temporary file, then a rename), so a kill mid-write leaves the
previous one. It lives in the user's state folder, ``$XDG_STATE_HOME/isochor`` (default
``~/.local/state/isochor``), named after the process and a token of its own
(``recovery-<pid>-<token>.json``), so two editors never write over each other, not even
one that got the pid of an editor killed before a reboot; a clean quit or a save removes
it. Beside it, the process holds an exclusive lock on ``recovery-<pid>-<token>.lock`` for
as long as it runs (``flock``: the system lets go of it when the process ends, however it
ends). At the next start, the files whose lock can be taken are what a crash or a kill
left: the window offers to recover them. (Without ``flock``, and for the files of older
versions named ``recovery-<pid>.json``, whether that pid runs decides.)
"""

from __future__ import annotations

import json
import os
import secrets
import time
from dataclasses import dataclass
from pathlib import Path

from ...core.errors import IsochorError
from ...core.io.atomic import atomic_write_text
from ...core.scenario.document import Scenario

FORMAT = "isochor-recovery"
VERSION = 1


def state_folder() -> Path:
    """The user's state folder for Isochor: ``$XDG_STATE_HOME/isochor``, by default
    ``~/.local/state/isochor``."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(
        os.path.expanduser("~"), ".local", "state"
    )
    return Path(base) / "isochor"


try:
    import fcntl
except ImportError:  # pragma: no cover - not on POSIX: the pid decides
    fcntl = None

#: this process's token in its recovery file's name (a new one in a forked child)
_token = {"pid": os.getpid(), "token": secrets.token_hex(4)}
#: the lock this process holds while it has a recovery file (its open file, by path)
_held: dict[Path, int] = {}


def own_file() -> Path:
    """This process's recovery file."""
    if _token["pid"] != os.getpid():  # a forked child is a process of its own
        _token.update(pid=os.getpid(), token=secrets.token_hex(4))
    return state_folder() / f"recovery-{_token['pid']}-{_token['token']}.json"


def files_of(pid: int) -> list[Path]:
    """The recovery files process ``pid`` wrote (whatever its token)."""
    folder = state_folder()
    return sorted(folder.glob(f"recovery-{int(pid)}-*.json")) + [
        f for f in [folder / f"recovery-{int(pid)}.json"] if f.is_file()
    ]


def _lock_of(file: Path) -> Path:
    return file.with_suffix(".lock")


def _hold(file: Path) -> None:
    """Take, and keep while this process runs, the lock that says ``file``'s owner lives."""
    if fcntl is None or file in _held:
        return
    fd = os.open(_lock_of(file), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return
    _held[file] = fd


@dataclass(frozen=True)
class Recovered:
    """What a recovery file holds."""

    file: Path  #: the recovery file itself
    scenario: Scenario  #: the edit, model path absolute
    title: str  #: the document's title then
    path: Path | None  #: the scenario file the document was saved to, if any
    saved_at: float  #: when the recovery file was written (seconds since the epoch)

    def when(self) -> str:
        """``"2026-11-28 06:12"``, local time."""
        return time.strftime("%Y-%m-%d %H:%M", time.localtime(self.saved_at))


def write(scenario: Scenario, *, title: str, path: Path | None, file: Path | None = None) -> Path:
    """Write the recovery file (atomically; the folder made if needed); returns it."""
    file = own_file() if file is None else Path(file)
    doc = scenario.to_dict()
    if "path" in scenario.model:
        doc["model"]["path"] = str(scenario.model_path())
    data = {
        "format": FORMAT,
        "version": VERSION,
        "pid": os.getpid(),
        "saved_at": time.time(),
        "title": title,
        "path": None if path is None else str(path),
        "scenario": doc,
    }
    file.parent.mkdir(parents=True, exist_ok=True)
    _hold(file)
    atomic_write_text(file, json.dumps(data, indent=1) + "\n")
    return file


def remove(file: Path | None = None) -> None:
    """Remove a recovery file (default: this process's) and its lock; nothing when there
    is none."""
    file = own_file() if file is None else Path(file)
    file.unlink(missing_ok=True)
    _lock_of(file).unlink(missing_ok=True)
    fd = _held.pop(file, None)
    if fd is not None:
        os.close(fd)


def read(file: Path) -> Recovered:
    """A recovery file's contents; :class:`IsochorError` when it is not one."""
    try:
        data = json.loads(Path(file).read_text(encoding="utf-8"))
        if data.get("format") != FORMAT:
            raise ValueError("not a recovery file")
        scenario = Scenario.from_dict(data["scenario"])
        path = data.get("path")
        return Recovered(
            Path(file),
            scenario,
            str(data.get("title") or "recovered"),
            Path(path) if path else None,
            float(data.get("saved_at", 0.0)),
        )
    except (OSError, ValueError, KeyError, TypeError, AttributeError, IsochorError) as exc:
        raise IsochorError(f"{file}: cannot be recovered ({exc})") from None


def _owner_lives(file: Path) -> bool:
    """Whether the process that wrote ``file`` still runs: it holds the file's lock (or,
    where there is no lock to ask, a process of its pid runs)."""
    if file in _held:
        return True
    lock = _lock_of(file)
    if fcntl is not None and lock.is_file():
        try:
            fd = os.open(lock, os.O_RDWR)
        except OSError:
            return True  # cannot ask: keep it for later, never offer a live one
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True  # held: its process runs
        finally:
            os.close(fd)  # closing lets go of the lock taken here
        return False
    try:
        pid = int(file.stem.split("-")[1])
    except (IndexError, ValueError):
        return True
    return _running(pid)


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # someone else's process: alive
    return True


def left_behind() -> list[Path]:
    """The recovery files of processes no longer running, newest first."""
    folder = state_folder()
    if not folder.is_dir():
        return []
    out = [f for f in folder.glob("recovery-*.json") if not _owner_lives(f)]
    return sorted(out, key=lambda f: f.stat().st_mtime, reverse=True)
