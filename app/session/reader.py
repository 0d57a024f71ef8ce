"""Reading a model file in a child process: the loading thread's model loader.

fast-simplification, which builds the level pyramid (:mod:`isochor.core.solve.pyramid`), keeps
Python's global interpreter lock for the whole of each simplification: 1.2 s for the
armadillo's finest level. On a thread of the window's process that would still freeze the
window, so :class:`ChildReader` runs :func:`isochor.core.scenario.problem.load_model` in a child
Python process and gets the :class:`~isochor.core.scenario.problem.Model` back pickled, while the
loading thread waits without the lock. Cancelling kills the child.

When no child can be started (no interpreter to start, or it cannot import Isochor), the
model is read on the calling thread, as before.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import threading
from dataclasses import replace
from pathlib import Path

from ...core.errors import IsochorError
from ...core.mesh import TriMesh
from ...core.scenario.problem import Model, load_model

#: the child's exit code when it cannot import Isochor (then the parent reads the model)
NO_IMPORT = 3

#: what the child runs: ``load_model(argv[1])``, the outcome pickled to standard output
CHILD = f"""
import pickle, sys
from pathlib import Path
out, sys.stdout = sys.stdout.buffer, sys.stderr  # only the outcome goes to the pipe
try:
    from isochor.core.errors import IsochorError
    from isochor.core.scenario.problem import load_model
except ImportError:
    sys.exit({NO_IMPORT})
try:
    outcome = ("model", load_model(sys.argv[1]))
except IsochorError as exc:
    outcome = ("error", str(exc))
except Exception as exc:
    outcome = ("error", f"{{Path(sys.argv[1]).name}}: {{type(exc).__name__}}: {{exc}}")
out.write(pickle.dumps(outcome, protocol=pickle.HIGHEST_PROTOCOL))
out.flush()
"""


class ChildReader:
    """A :data:`~isochor.core.scenario.problem.ModelLoader` that reads in a child process.

    One reader serves one load; :meth:`kill` (from any thread) stops its child, and the
    load then fails with a message nobody shows."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._child: subprocess.Popen | None = None
        self.killed = False

    def __call__(self, path: Path) -> Model:
        try:
            child = subprocess.Popen(
                [sys.executable, "-c", CHILD, os.fspath(path)],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                env=_child_env(),
            )
        except OSError:
            return load_model(path)
        with self._lock:
            self._child = child
            if self.killed:
                child.kill()
        data, _ = child.communicate()
        with self._lock:
            self._child = None
        if self.killed:
            raise IsochorError(f"{Path(path).name}: opening cancelled")
        if child.returncode == NO_IMPORT and not data:
            return load_model(path)
        try:
            kind, payload = pickle.loads(data)
        except Exception:
            raise IsochorError(
                f"{Path(path).name}: the model reader stopped unexpectedly "
                f"(exit code {child.returncode})"
            ) from None
        if kind == "error":
            raise IsochorError(payload)
        return _frozen(payload)

    def kill(self) -> None:
        with self._lock:
            self.killed = True
            if self._child is not None:
                self._child.kill()


def _child_env() -> dict[str, str]:
    """This environment, with this interpreter's import path: the child finds Isochor
    where this process found it."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))
    return env


def _frozen(model: Model) -> Model:
    """The model as :func:`load_model` makes it: read-only mesh arrays (unpickled ones
    are writeable)."""
    return replace(
        model,
        levels=tuple(
            TriMesh(m.vertices, m.faces, m.cap_vertices, m.cap_faces) for m in model.levels
        ),
    )
