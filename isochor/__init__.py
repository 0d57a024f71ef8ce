"""Isochor: volume-preserving free-form deformation (Hirota, Maheshwari, Lin 1999).

One distribution, one import name. The source folders of the repository install under it:

- :mod:`isochor.core`   the numerical library: numpy, scipy, trimesh, fast-simplification;
  never imports Qt, VTK or pyvista
- :mod:`isochor.app`    the desktop editor and the ``isochor`` command line (PySide6 +
  pyvistaqt; imported only when the editor starts)
- :mod:`isochor.assets` the sample models, example scenarios and the icon the program ships

``import isochor`` is cheap: it imports neither numpy nor Qt.
"""

from __future__ import annotations

__version__ = "0.2.0"

__all__ = ["__version__"]
