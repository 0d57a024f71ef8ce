"""The command line's output: its exit statuses, a standard output for its table and
summary, and the progress line on a terminal."""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from typing import NoReturn, TextIO

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NOT_CONVERGED = 0, 1, 2, 3
EXIT_INTERNAL = 70  # EX_SOFTWARE: a bug, not the user's doing


def leave_now(status: int) -> NoReturn:
    """End the process at once with ``status``, without Python's finalisation: logging (if
    used) shut down and the standard streams flushed (closed or detached ones skipped),
    then ``os._exit``. For a process whose work is done and written while other threads
    may still run (the kernels' loader, a lattice rebuild) or whose finalisation is slow
    (the editor's VTK objects and arrays)."""
    from os import _exit  # (os's documented exit without interpreter shutdown)

    if (logging := sys.modules.get("logging")) is not None:
        logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError, AttributeError):
            stream.flush()
    _exit(status)


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


#: seconds a load or a solve runs before the progress line shows (the environment variable
#: overrides it: ``ISOCHOR_PROGRESS_AFTER=0`` shows it at once)
PROGRESS_AFTER = 1.0
PROGRESS_ENV = "ISOCHOR_PROGRESS_AFTER"
#: what the line says for each stage
STAGE_WORDS = {"load": "loading the model", "solve": "solving"}


class ProgressLine:
    """One updating line on a terminal while a load or a solve takes long.

    Called as ``line(stage, fraction)`` (the API's progress callback); drawn on ``stream``
    (standard error) only when it is a terminal, as ``\\r``-rewritten text, from
    :data:`PROGRESS_AFTER` seconds into a stage on, and redrawn a few times a second by a
    ticker thread with the seconds spent (a single long step, such as reading a big file,
    still shows that work goes on). Nothing at all is written to a pipe or a file.
    :meth:`clear` wipes the line (before other output, and when a stage ends); :meth:`close`
    stops the ticker and wipes it.
    """

    def __init__(self, stream: TextIO, after: float | None = None, tick: float = 0.25) -> None:
        self.stream = stream
        try:
            self.on = bool(stream.isatty())
        except (AttributeError, ValueError, OSError):
            self.on = False
        if after is None:
            try:
                after = float(os.environ.get(PROGRESS_ENV, PROGRESS_AFTER))
            except ValueError:
                after = PROGRESS_AFTER
        self.after, self.tick = after, tick
        self._lock = threading.Lock()
        self._stage: str | None = None
        self._fraction = 0.0
        self._since = 0.0
        self._width = 0
        self._drawn = -float("inf")  # when the line was last drawn (time.monotonic)
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None

    def __call__(self, stage: str, fraction: float) -> None:
        if not self.on:
            return
        with self._lock:
            if fraction >= 1.0:  # the stage is over: its line goes
                self._stage = None
                self._wipe()
                return
            if stage != self._stage:
                self._stage, self._since = stage, time.monotonic()
            self._fraction = max(0.0, float(fraction))
        if self._ticker is None:
            self._ticker = threading.Thread(target=self._run, name="isochor-progress", daemon=True)
            self._ticker.start()
        if time.monotonic() - self._drawn >= self.tick:
            self._draw()

    def _run(self) -> None:
        while not self._stop.wait(self.tick):
            self._draw()

    def _draw(self) -> None:
        with self._lock:
            if self._stage is None:
                return
            spent = time.monotonic() - self._since
            if spent < self.after:
                return
            word = STAGE_WORDS.get(self._stage, self._stage)
            text = f"isochor: {word} {100 * self._fraction:3.0f}% ({spent:.0f} s)"
            self._write("\r" + text.ljust(self._width))
            self._width, self._drawn = len(text), time.monotonic()

    def clear(self) -> None:
        """Wipe the line (before other output to the same terminal)."""
        with self._lock:
            self._wipe()

    def close(self) -> None:
        """Stop redrawing and wipe the line."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        self.clear()

    def _wipe(self) -> None:
        if self._width:
            self._write("\r" + " " * self._width + "\r")
            self._width = 0

    def _write(self, text: str) -> None:
        with contextlib.suppress(OSError, ValueError):
            self.stream.write(text)
            self.stream.flush()
