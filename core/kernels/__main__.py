"""``python -m isochor.core.kernels --compile [MARKER]``: compile every kernel into numba's
cache, in a child of its own (:mod:`isochor.core.kernels.cache`)."""

import sys

from .cache import compile_and_mark
from .signatures import compile_all

if sys.argv[1:2] == ["--compile"]:
    compile_and_mark(compile_all, sys.argv[2] if len(sys.argv) > 2 else None)
