"""Isochor: volume-preserving free-form deformation (Hirota, Maheshwari, Lin 1999).

One distribution, one import name. The source folders of the repository install under it:

- :mod:`isochor.core`   the numerical library: numpy, scipy, trimesh, fast-simplification;
  never imports Qt, VTK or pyvista
- :mod:`isochor.app`    the desktop editor and the ``isochor`` command line (PySide6 +
  pyvistaqt; imported only when the editor starts)
- :mod:`isochor.assets` the sample models, example scenarios and the icon the program ships

The package is typed: it ships the PEP 561 marker ``py.typed``, so type checkers read its
annotations.

``import isochor`` is cheap: it imports neither numpy nor Qt. The Python API
(:mod:`isochor.core.api`) is loaded on first use::

    import isochor
    result = isochor.deform(mesh, lattice=(5, 2, 2), moves={(0, 0, 0): (0, 1.5, 0)})
    result.mesh, result.report

- :func:`deform`: one deformation of a mesh in memory, returned as the same type
- :class:`Session`: repeated edits of one model (reusing its level pyramid), export, save
- :func:`load`: a session on a model or scenario file
- :class:`Scenario`, :class:`Move`: the scenario document; :class:`IsochorError`: what a
  user's mistake raises, one sentence
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__version__ = "0.2.0"

if TYPE_CHECKING:  # what a type checker reads; at run time __getattr__ imports them
    # (``name as name``: re-exported, as a user's ``mypy --strict`` requires)
    from .core.api import Deformed as Deformed
    from .core.api import Session as Session
    from .core.api import deform as deform
    from .core.api import load as load
    from .core.errors import IsochorError as IsochorError
    from .core.scenario.document import Move as Move
    from .core.scenario.document import Scenario as Scenario

_API = {
    "deform": "isochor.core.api",
    "Deformed": "isochor.core.api",
    "Session": "isochor.core.api",
    "load": "isochor.core.api",
    "Scenario": "isochor.core.scenario.document",
    "Move": "isochor.core.scenario.document",
    "IsochorError": "isochor.core.errors",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    """The API, imported when first asked for (so ``import isochor`` stays cheap)."""
    if name in _API:
        import importlib

        value = getattr(importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'isochor' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
