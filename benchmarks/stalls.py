"""What the GUI thread does during its long stalls: a sampling probe for the window's rows.

The window's stall meter (:class:`benchmarks.window.Meter`) knows *when* the GUI thread did
not answer; :class:`StallProbe` says *what* it did meanwhile. A thread of its own reads the
GUI thread's Python stack every :data:`SAMPLE_MS` (``sys._current_frames``) with the GUI
thread's CPU clock (``time.pthread_getcpuclockid``). VTK's render and most Qt calls release
the GIL, so the samples see the Python line that called them. For each gap the meter
reports over a threshold, :meth:`StallProbe.explain` sums the samples that fell in it by
the innermost line of Isochor's code (or of this benchmark) on the stack, and splits the
gap's wall time into the GUI thread's own CPU time and the rest (waiting for the GIL or
for a core, on a shared machine).

The probe takes the GIL for each sample (tens of microseconds), so it runs only when asked
for (``python -m benchmarks.window 3 --stalls``), never in the rows ``make bench`` writes.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field

#: the GUI thread's stack is read this often, ms
SAMPLE_MS = 2
#: the frames of these packages say where a sample is (the innermost one on the stack)
OWN = ("/isochor/", "/benchmarks/", "/app/", "/core/")
#: a stack whose innermost own frame is one of these waits in the event loop: idle
IDLE = ("run_until", "exec")


def thread_times() -> dict[int, tuple[float, float]]:
    """Every thread of this process: ``{native id: (seconds on a core, seconds waiting for
    one while runnable)}`` (Linux's ``schedstat``; empty elsewhere)."""
    out = {}
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tasks:
        try:
            with open(f"/proc/self/task/{tid}/schedstat") as f:
                run, wait, _ = f.read().split()
        except (OSError, ValueError):
            continue
        out[int(tid)] = (int(run) * 1e-9, int(wait) * 1e-9)
    return out


def thread_kind(tid: int, names: dict[int, str]) -> str:
    """What a thread is: the GUI thread, a Python thread by its name (the solver's, the
    rebuild's), or by its kernel name (llvmpipe's rasterisers, Qt's)."""
    if tid in names:
        return names[tid]
    try:
        with open(f"/proc/self/task/{tid}/comm") as f:
            comm = f.read().strip()
    except OSError:
        return "?"
    return "llvmpipe" if comm.startswith("llvmpipe") else comm


@dataclass(frozen=True)
class Gap:
    """One long gap between the meter's ticks: when, how long, the GUI thread's CPU time in
    it, the phase the meter counted it for, and per kind of thread the seconds on a core
    and waiting for one (runnable) in it."""

    start: float
    end: float
    cpu: float
    phase: str
    threads: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def wall(self) -> float:
        return self.end - self.start


class StallProbe:
    """Samples the GUI thread's stack from a thread of its own (see the module's text)."""

    def __init__(self, keep: int = 400_000) -> None:
        self.main = threading.main_thread().ident
        self._clock = time.pthread_getcpuclockid(self.main)
        self.samples: deque[tuple[float, float, tuple[str, ...]]] = deque(maxlen=keep)
        self.gaps: list[Gap] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stall-probe", daemon=True)
        self._names: dict[tuple[object, int], str] = {}

    def start(self) -> StallProbe:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(1.0)

    def cpu(self) -> float:
        """The GUI thread's CPU time so far, seconds."""
        return time.clock_gettime(self._clock)

    def _run(self) -> None:
        while not self._stop.wait(SAMPLE_MS / 1000):
            frame = sys._current_frames().get(self.main)
            now, cpu = time.perf_counter(), self.cpu()
            self.samples.append((now, cpu, self._stack(frame)))

    def _stack(self, frame) -> tuple[str, ...]:
        """The stack's own frames, innermost first, as ``file:line function``; the
        innermost frame of any package first of all when it is not our own (a library)."""
        out: list[str] = []
        lib = None
        while frame is not None and len(out) < 12:
            code = frame.f_code
            name = code.co_filename
            if any(p in name for p in OWN):
                key = (code, frame.f_lineno)
                label = self._names.get(key)
                if label is None:
                    short = name.rsplit("/", 2)
                    label = f"{'/'.join(short[-2:])}:{frame.f_lineno} {code.co_name}"
                    self._names[key] = label
                out.append(label)
            elif not out and lib is None:
                lib = f"[{name.rsplit('/', 1)[-1]}:{code.co_name}]"
            frame = frame.f_back
        return ((lib,) if lib else ()) + tuple(out)

    def tick(self) -> dict[int, tuple[float, float]]:
        """The threads' times now (the meter calls it at every tick)."""
        return thread_times()

    def gap(self, start: float, end: float, cpu: float, phase: str, before, after) -> None:
        """The meter saw a long gap (``before`` and ``after``: :meth:`tick` at its ends):
        remember it for :meth:`explain`."""
        names = {t.native_id: t.name for t in threading.enumerate() if t.native_id}
        names[threading.main_thread().native_id] = "GUI"
        kinds: dict[str, tuple[float, float]] = {}
        for tid, (run, wait) in after.items():
            run0, wait0 = before.get(tid, (run, wait))
            kind = thread_kind(tid, names).split("-")[0]
            r, w = kinds.get(kind, (0.0, 0.0))
            kinds[kind] = (r + run - run0, w + wait - wait0)
        busy = {k: v for k, v in kinds.items() if v[0] + v[1] > 0.002}
        self.gaps.append(Gap(start, end, cpu, phase, busy))

    def explain(self, gap: Gap, depth: int = 4, top: int = 4) -> str:
        """Where ``gap`` went: its wall and CPU time, and the most sampled stacks in it
        (``depth`` own frames each) with their share of its samples."""
        inside = [s for s in self.samples if gap.start <= s[0] <= gap.end]
        counts = Counter(" < ".join(s[2][:depth]) if s[2] else "(no Python frame)" for s in inside)
        threads = ", ".join(
            f"{k} {1e3 * r:.0f}+{1e3 * w:.0f}" for k, (r, w) in sorted(gap.threads.items())
        )
        lines = [
            f"gap {1e3 * gap.wall:.0f} ms ({gap.phase}): GUI thread CPU {1e3 * gap.cpu:.0f} ms, "
            f"{len(inside)} samples; threads, ms on a core + ms runnable waiting: {threads}"
        ]
        for stack, n in counts.most_common(top):
            lines.append(f"    {100 * n / max(len(inside), 1):3.0f}%  {stack}")
        return "\n".join(lines)

    def report(self, over: float, limit: int = 12) -> str:
        """The gaps over ``over`` seconds, longest first, explained."""
        long = sorted((g for g in self.gaps if g.wall > over), key=lambda g: -g.wall)
        if not long:
            return f"no gap over {1e3 * over:.0f} ms"
        return "\n".join(self.explain(g) for g in long[:limit])
