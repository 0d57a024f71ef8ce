"""``python -m benchmarks``: BLAS on one thread, set before NumPy is imported; then the run.

``python -m benchmarks --help`` lists the options.
"""

import os
import sys

from benchmarks import BLAS_ENV  # the package's __init__ imports nothing else

#: NumPy was imported before this module (then threadpoolctl limits the threads, if it can)
NUMPY_FIRST = "numpy" in sys.modules
#: the BLAS variables the user had set before the benchmark started: left as they are
USER_BLAS = {v: os.environ[v] for v in BLAS_ENV if v in os.environ}
if not NUMPY_FIRST:
    for _name in BLAS_ENV:
        os.environ.setdefault(_name, "1")


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (``argv`` as on the command line, without the program name)."""
    from benchmarks.run import main as run_main  # NumPy is imported from here on

    return run_main(argv, numpy_first=NUMPY_FIRST, user_blas=USER_BLAS)


if __name__ == "__main__":
    raise SystemExit(main())
