"""Never lose work: the recovery file of a document with unsaved changes (Qt-free).

While a document has unsaved changes, the window writes a recovery file after each edit
(debounced, :mod:`isochor.app.window.autosave`): the scenario of the current state, with
its model as an absolute path, and what the document was (its file, its title). The file
is written atomically (a temporary file, then a rename), so a kill mid-write leaves the
previous one. It lives in the user's state folder, ``$XDG_STATE_HOME/isochor`` (default
``~/.local/state/isochor``), named after the process (``recovery-<pid>.json``), so two
editors never write over each other; a clean quit or a save removes it. At the next start,
the files of processes that are no longer running are what a crash or a kill left: the
window offers to recover them.
"""

from __future__ import annotations

import json
import os
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


def own_file(pid: int | None = None) -> Path:
    """The recovery file of process ``pid`` (default: this one)."""
    return state_folder() / f"recovery-{os.getpid() if pid is None else int(pid)}.json"


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
    atomic_write_text(file, json.dumps(data, indent=1) + "\n")
    return file


def remove(file: Path | None = None) -> None:
    """Remove a recovery file (default: this process's); nothing when there is none."""
    (own_file() if file is None else Path(file)).unlink(missing_ok=True)


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
    out = []
    for f in folder.glob("recovery-*.json"):
        try:
            pid = int(f.stem.split("-", 1)[1])
        except ValueError:
            continue
        if not _running(pid):
            out.append(f)
    return sorted(out, key=lambda f: f.stat().st_mtime, reverse=True)
