"""The command line's output: its exit statuses and a standard output for its table and
summary."""

from __future__ import annotations

import contextlib
import os
from typing import TextIO

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NOT_CONVERGED = 0, 1, 2, 3
EXIT_INTERNAL = 70  # EX_SOFTWARE: a bug, not the user's doing


class PipeSafe:
    """Standard output that a reader gone away (``isochor solve ... | head -1``) silences
    instead of stopping the solve: the table is for reading, the files are the work."""

    def __init__(self, stream: TextIO) -> None:
        self.stream: TextIO | None = stream

    def write(self, text: str) -> None:
        self._do(lambda s: s.write(text))

    def flush(self) -> None:
        self._do(lambda s: s.flush())

    def _do(self, action) -> None:
        if self.stream is None:
            return
        try:
            action(self.stream)
        except BrokenPipeError:
            # what is still buffered goes nowhere, and the exit does not complain either
            with contextlib.suppress(OSError, ValueError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), self.stream.fileno())
            self.stream = None
