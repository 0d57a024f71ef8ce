"""core/ never imports Qt, VTK or pyvista: checked in a fresh interpreter."""

import pkgutil
import subprocess
import sys
from pathlib import Path

import core

ROOT = Path(__file__).resolve().parents[1]


def test_importing_every_core_module_imports_no_gui_or_vtk():
    modules = [f"core.{m.name}" for m in pkgutil.iter_modules(core.__path__)]
    assert {"core.lattice", "core.volume", "core.springs", "core.solver",
            "core.multilevel"} <= set(modules)
    code = (
        "import importlib, sys\n"
        f"for m in {modules!r}: importlib.import_module(m)\n"
        "bad = sorted(n for n in sys.modules if n.split('.')[0] in "
        "{'PySide6', 'PyQt5', 'PyQt6', 'shiboken6', 'vtk', 'vtkmodules', 'pyvista', 'pyvistaqt', 'qtpy'})\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"core imported: {out.stdout.strip()}"
