"""Run code in a fresh interpreter and see which GUI libraries it imported.

For the tests that promise a module, or a whole command, works without Qt, VTK or pyvista.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

#: top-level names of the libraries only the editor may import
GUI_LIBRARIES = frozenset(
    {
        "PySide6",
        "shiboken6",
        "PySide2",
        "PyQt5",
        "PyQt6",
        "qtpy",
        "vtk",
        "vtkmodules",
        "pyvista",
        "pyvistaqt",
        "matplotlib",
    }
)

_REPORT = (
    "\nimport sys as _sys\n"
    "print('GUI:' + ','.join(sorted(n for n in _sys.modules "
    "if n.partition('.')[0] in {names!r})))\n"
)


def run_fresh(
    code: str,
    cwd: str | Path | None = None,
    timeout: float = 120,
    extra: frozenset[str] = frozenset(),
) -> tuple[subprocess.CompletedProcess, list[str]]:
    """Run ``code`` with this interpreter; return the process and the GUI modules (plus any
    module named in ``extra``) loaded when the code ended. The code must not call
    ``sys.exit``: set a variable and assert on the printed output instead."""
    names = set(GUI_LIBRARIES)
    report = _REPORT.format(names=names)
    if extra:
        report = report.replace(
            "if n.partition('.')[0] in", f"if n in {set(extra)!r} or n.partition('.')[0] in"
        )
    proc = subprocess.run(
        [sys.executable, "-c", code + report],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    line = next((s for s in proc.stdout.splitlines() if s.startswith("GUI:")), "GUI:")
    loaded = [n for n in line[4:].split(",") if n]
    return proc, loaded
