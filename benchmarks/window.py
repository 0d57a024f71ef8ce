"""The window's rows of the Display rate section (issue 9), measured in the real window.

:func:`run_window` opens the 346k-triangle armadillo in the editor window in this process
(it needs a display: ``xvfb-run``, software OpenGL there), turns live solving on and drags a
lattice node with mouse events sent by a timer at 60 Hz for :data:`DRAG_SECONDS`, then
releases it and waits until the solve of the release has ended and its result is drawn.
Each repeat undoes the drag first, so every repeat drags the same node the same way.

What it measures, each a median of the repeats:

* redraws per second while dragging: the frames the window drew (a redraw is one call of
  its frame handler: the model deformed, shaded and rendered at new node positions) over
  the drag's duration; shown as milliseconds per redraw, the target 15 a second;
* the longest GUI-thread stall: a precise timer ticks every :data:`TICK_MS` ms on the GUI
  thread and the largest gap between two ticks is the longest time the GUI thread did not
  answer, from the press to the release solve's result (drawn or not);
* the longest stall while the result is drawn at full resolution (after the release
  solve's end, but for gaps that hold a paint of the proxy: the pause, the full mesh
  deformed and shaded in steps and drawn in passes, :mod:`isochor.app.view.composer`,
  and the paint that shows it), reported on its own so that it is never hidden in the
  row before: the most the next press could wait, against one proxy frame (the drag's
  median time a redraw);
* from the release to its result drawn at the proxy (the first frame after the release
  solve's result was accepted);
* the drags alternate with and without back-face culling of the (closed) model, so that
  its gain is a ratio in one run;
* closing the window while it solves: the armadillo opened in a new window each repeat, a
  node dragged (live solving off), and once the release's solve has handed over its first
  record, the time ``close()`` takes (it stops the solver, waiting at most 0.1 s
  for its thread, and releases VTK).

The event loop is a real one (``QEventLoop.exec``) the whole time: nothing here sleeps on
the GUI thread, so a gap is the window's own work or the solver thread's hold on the GIL.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from benchmarks.display import Row
from benchmarks.opening import run_opening, unmeasured
from benchmarks.scale import ARMADILLO
from benchmarks.timing import Timing

#: the stall probe explains the gaps longer than this, seconds
PROBE_OVER = 0.035
#: how long each drag lasts, seconds
DRAG_SECONDS = 2.0
#: the mouse moves this often while dragging, ms
MOVE_MS = 16
#: the stall meter ticks this often, ms
TICK_MS = 4
RATE_TARGET = 20.0  #: redraws a second while dragging, at least
STALL_TARGET = 0.050  #: seconds, at most
RESULT_TARGET = 0.150  #: seconds from the release to its result drawn (at the proxy), at most
CLOSE_TARGET = 1.0  #: seconds ``close()`` takes while a solve runs, at most
#: windows opened for the closing row (each opens the armadillo anew)
CLOSE_REPEATS = 3

WHAT_RATE = "window: redraws while dragging the 346k armadillo (ms a redraw)"
WHAT_STALL = "window: longest GUI stall, drag and release solve, 346k armadillo"
WHAT_FINAL = "window: longest GUI stall drawing the released result at full resolution"
WHAT_RESULT = "window: from the release to its result drawn (at the proxy), 346k armadillo"
WHAT_CLOSE = "window: closing it while it solves the 346k armadillo"


def _unmeasured(why: str) -> list[Row]:
    return [
        Row(WHAT_RATE, None, f">= {RATE_TARGET:g} a second", None, why),
        Row(WHAT_STALL, None, f"<= {1e3 * STALL_TARGET:g} ms", None, why),
        Row(WHAT_RESULT, None, f"<= {1e3 * RESULT_TARGET:g} ms", None, why),
        Row(WHAT_FINAL, None, "<= one proxy frame", None, why),
        Row(WHAT_CLOSE, None, f"<= {1e3 * CLOSE_TARGET:g} ms", None, why),
        *unmeasured(why),
    ]


def run_window(models: Path, repeats: int) -> list[Row]:
    """The window's rows: redraws a second while dragging the 346k armadillo and the
    longest GUI-thread stalls; rows with ``met=None`` when there is no display or model."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        return _unmeasured("needs a display: run under xvfb-run")
    path = Path(models) / ARMADILLO
    if not path.is_file():
        return _unmeasured(f"needs {path}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    try:
        from isochor.app.view.modeldraw import IDLE_MS

        runs = _measure(path, max(1, repeats))
        closes = [one_close(path) for _ in range(min(max(1, repeats), CLOSE_REPEATS))]
        opening = run_opening(path, repeats)
    except ImportError as exc:  # the window needs PySide6 and pyvistaqt
        return _unmeasured(f"the window's libraries are missing: {exc}")
    bare = [r for r in runs if not r["cull"]]  # the same drags without back-face culling
    runs = [r for r in runs if r["cull"]] or bare  # (a view that cannot cull: all bare)
    bare = bare if runs is not bare else []
    rate = Timing(tuple(1.0 / max(r["rate"], 1e-9) for r in runs))
    stall = Timing(tuple(r["stall"] for r in runs))
    final = Timing(tuple(r["final"] for r in runs))
    result = Timing(tuple(r["result"] for r in runs))
    rates = ", ".join(f"{r['rate']:.1f}" for r in runs)
    proxies = {r["proxy"] for r in runs}
    converged = all(r["converged"] for r in runs)
    note = (
        f"{1 / rate.median:.1f} redraws/s (runs: {rates}); drawn: {', '.join(proxies)}; "
        f"load average {load:.1f} on {os.cpu_count()} CPUs at the start"
    )
    frame = rate.median  # one proxy frame: the drag's median time a redraw
    culling = ""
    if bare:
        b_rate = float(np.median([r["rate"] for r in bare]))
        b_final = float(np.median([r["final"] for r in bare]))
        culling = (
            f"; without back-face culling (interleaved, same run): {b_rate:.1f} redraws/s, "
            f"full-resolution stall {1e3 * b_final:.1f} ms; culling gives "
            f"x{1 / rate.median / max(b_rate, 1e-9):.2f} the redraws and a "
            f"x{b_final / max(final.median, 1e-9):.2f} shorter stall"
        )
    rows = [
        Row(
            WHAT_RATE,
            rate,
            f">= {RATE_TARGET:g} a second",
            1 / rate.median >= RATE_TARGET,
            note + culling,
        ),
        Row(
            WHAT_STALL,
            stall,
            f"<= {1e3 * STALL_TARGET:g} ms",
            stall.median <= STALL_TARGET and converged,
            ("" if converged else "a release solve did not converge; ") + _culprit(runs),
        ),
        Row(
            WHAT_RESULT,
            result,
            f"<= {1e3 * RESULT_TARGET:g} ms",
            result.median <= RESULT_TARGET and converged,
            "the release solve, then its result drawn at the proxy at once (the full mesh "
            "waits for a pause)",
        ),
        Row(
            WHAT_FINAL,
            final,
            f"<= one proxy frame ({1e3 * frame:.1f} ms)",
            final.median <= frame,
            _final_reason(runs, IDLE_MS, final.median, frame),
        ),
        _close_row(closes),
        *opening,
    ]
    for r in rows:
        print("  " + r.line())
    return rows


def _close_row(closes: list[tuple[float, bool]]) -> Row:
    """The closing row from :func:`one_close`'s runs: met when every window was still
    solving as it closed and the median is within :data:`CLOSE_TARGET`."""
    took = Timing(tuple(t for t, _ in closes))
    solving = sum(s for _, s in closes)
    met = took.median <= CLOSE_TARGET and solving == len(closes)
    why = f"{solving} of {len(closes)} windows still solving as they closed"
    if took.median > CLOSE_TARGET:
        why += "; the solver's thread is waited for at most 0.1 s, the rest is releasing VTK"
    return Row(WHAT_CLOSE, took, f"<= {1e3 * CLOSE_TARGET:g} ms", met, why)


def _final_reason(runs, idle_ms: int, final: float, frame: float) -> str:
    """What the full-resolution stall holds: the passes the full mesh is drawn in (their
    count, the longest, the paint that shows them), or the one render of older code."""
    over = "" if final <= frame else f"; it is {final / frame:.1f} proxy frames"
    passes = [r for r in runs if r.get("passes")]
    if not passes:
        return (
            f"the most a press could wait: drawn after a {idle_ms} ms pause, the one render "
            "of the full mesh (back faces culled on this closed model) cannot be split" + over
        )
    longest = float(np.median([r["longest_pass"] for r in passes]))
    result_gap = float(np.median([r["result_gap"] for r in passes]))
    show = float(np.median([r["show"] for r in passes]))
    count = int(np.median([r["passes"] for r in passes]))
    return (
        f"the most a press could wait: drawn after a {idle_ms} ms pause in {count} passes, one "
        f"an event-loop turn (the background and lattice, then a piece of 65536 triangles "
        f"each; the longest {1e3 * longest:.1f} ms, medians over the runs), then shown by a "
        f"paint of {1e3 * show:.1f} ms that draws only the overlays; a gap that holds a paint "
        f"of the proxy (the result drawn at it) counts for the result row instead (the "
        f"longest: {1e3 * result_gap:.1f} ms)" + over
    )


def _culprit(runs) -> str:
    worst = max(runs, key=lambda r: r["stall"])
    return (
        f"the longest gap came {worst['stall_phase']}: a gap holds one render of the proxy "
        "(12 ms on an idle machine, 25-35 ms beside the solver in software OpenGL), Qt "
        "composing the view, and the GUI thread's waits for the GIL while a solver step "
        "runs Python"
    )


# -- the measurement --------------------------------------------------------------------------
class Meter:
    """The largest gap between the ticks of a precise GUI-thread timer, per phase; with a
    :class:`~benchmarks.stalls.StallProbe` in :attr:`probe`, every gap over
    :data:`PROBE_OVER` is handed to it with the GUI thread's CPU time in the gap."""

    probe = None  #: a running :class:`~benchmarks.stalls.StallProbe`, or None

    def __init__(self) -> None:
        from PySide6.QtCore import Qt, QTimer

        self.timer = QTimer()
        self.timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.timer.setInterval(TICK_MS)
        self.timer.timeout.connect(self._tick)
        self.phase = ""
        self.worst: dict[str, float] = {}
        #: per phase, the GUI thread's own CPU time in its busiest gap (the rest of a gap is
        #: waiting: for the GIL, or for a core on a shared machine)
        self.busiest: dict[str, float] = {}
        self._last = time.perf_counter()
        self._cpu = time.thread_time()
        self._times = self.probe.tick() if self.probe is not None else {}
        self.aside = None  #: () -> a phase the gap just ended counts for instead, or None

    def start(self, phase: str) -> None:
        self.phase = phase
        self.worst.setdefault(phase, 0.0)
        self._last, self._cpu = time.perf_counter(), time.thread_time()
        if not self.timer.isActive():
            self.timer.start()

    def switch(self, phase: str) -> None:
        """Later gaps count for ``phase`` (a gap spanning the switch counts for the new)."""
        self.phase = phase
        self.worst.setdefault(phase, 0.0)

    def _tick(self) -> None:
        now, cpu = time.perf_counter(), time.thread_time()
        gap, last, used = now - self._last, self._last, cpu - self._cpu
        self._last, self._cpu = now, cpu
        phase = (self.aside() if self.aside is not None else None) or self.phase
        if self.probe is not None:
            times, self._times = self._times, self.probe.tick()
            if gap > PROBE_OVER:
                self.probe.gap(last, now, used, phase, times, self._times)
        if gap > self.worst.get(phase, 0.0):
            self.worst[phase] = gap
        if used > self.busiest.get(phase, 0.0):
            self.busiest[phase] = used

    def stop(self) -> None:
        self._tick()
        self.timer.stop()


def run_until(pred, timeout: float, poll_ms: int = 5) -> bool:
    """Run the Qt event loop until ``pred()`` is true (checked every ``poll_ms``) or
    ``timeout`` seconds passed; True when ``pred()`` came true."""
    from PySide6.QtCore import QEventLoop, QTimer

    if pred():
        return True
    loop = QEventLoop()
    check = QTimer()
    check.setInterval(poll_ms)

    def poll() -> None:
        if pred():
            loop.quit()

    check.timeout.connect(poll)
    check.start()
    QTimer.singleShot(int(timeout * 1000), loop.quit)
    loop.exec()
    check.stop()
    return bool(pred())


def settled(win) -> bool:
    """Nothing runs, no frame is pending and the full-resolution model is drawn."""
    vp = win.viewport
    full = vp.model_frames.showing_full()
    return not win.is_solving() and not win.session.frame_pending and full


def drag_node(win) -> int:
    """A free lattice node drawn well inside the view, clear of the others."""
    vp = win.viewport
    xy, _, visible = vp.camera_control.projection().project(vp.nodes)
    free = ~np.asarray(win.state.fixed, bool).reshape(len(xy), -1).all(axis=1)
    best, score = -1, -1.0
    for r in np.flatnonzero(visible & free):
        margin = min(xy[r, 0], xy[r, 1], vp.width() - xy[r, 0], vp.height() - xy[r, 1])
        if margin < 120:
            continue
        others = np.delete(xy, r, axis=0)
        clear = float(np.hypot(*(others - xy[r]).T).min())
        if clear > 12 and clear + 0.1 * margin > score:
            best, score = int(r), clear + 0.1 * margin
    if best < 0:
        raise RuntimeError("no lattice node can be picked cleanly in the view")
    return best


def drag_path(start: np.ndarray, seconds: float = DRAG_SECONDS) -> list[np.ndarray]:
    """Mouse positions every :data:`MOVE_MS`: out and sideways, about 120 pixels."""
    steps = int(seconds * 1000 / MOVE_MS)
    t = np.linspace(0, 1, steps + 1)[1:]
    return [start + np.array([-110 * s, -50 * np.sin(np.pi * s)]) for s in t]


def one_drag(app, win, row: int, meter: Meter) -> dict:
    """Press on ``row``, move along :func:`drag_path` by a timer, release, wait for the
    drawn result. Returns the rate, the stalls and what was drawn."""
    from PySide6.QtCore import QPoint, Qt, QTimer
    from PySide6.QtTest import QTest

    vp = win.viewport
    start = vp.camera_control.projection().project(vp.nodes)[0][row]
    path = drag_path(start)
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier

    def at(xy) -> QPoint:
        return QPoint(int(round(xy[0])), int(round(xy[1])))

    QTest.mousePress(vp, left, none, at(start))
    moves = iter(path)
    done = {"moves": False}
    drawn: set[str] = set()

    def move() -> None:  # each mouse event in its own turn of the event loop, as a user's
        xy = next(moves, None)
        if xy is None:
            done["moves"] = True
            return
        QTest.mouseMove(vp, at(xy))

    def frame(*_args) -> None:
        drawn.add(vp.model_frames.drawn_model())

    mover = QTimer()
    mover.setTimerType(Qt.TimerType.PreciseTimer)
    mover.setInterval(MOVE_MS)
    mover.timeout.connect(move)
    win.session.frameReady.connect(frame)
    meter.start("drag")
    redraws0, t0 = win.frames.redraws, time.perf_counter()
    mover.start()
    run_until(lambda: done["moves"], DRAG_SECONDS + 30)
    mover.stop()
    elapsed = time.perf_counter() - t0
    redraws = win.frames.redraws - redraws0
    win.session.frameReady.disconnect(frame)
    release = {"gen": None, "at": 0.0, "result": None, "solved": False}
    seen = {"paints": vp.paints}

    def proxy_painted() -> str | None:
        """A gap that holds a paint of the proxy (the result drawn at the proxy, or drawn
        again) counts for the result, not for the full-resolution drawing."""
        painted, seen["paints"] = vp.paints != seen["paints"], vp.paints
        proxy = vp.model_frames.drawn_model().startswith("proxy")
        return "result" if meter.phase == "final" and painted and proxy else None

    def solved(gen: int, _ok: bool) -> None:
        if gen == release["gen"]:  # the result is accepted: what follows draws it
            release["solved"] = True
            meter.switch("final")
            meter.aside = proxy_painted

    def shown(*_args) -> None:  # (after the frame is drawn: connected after the window)
        if release["solved"] and release["result"] is None:
            release["result"] = time.perf_counter() - release["at"]

    def up() -> None:
        release["at"] = time.perf_counter()
        QTest.mouseRelease(vp, left, none, at(path[-1]))
        meter.switch("release")
        release["gen"] = win.worker.generation

    win.solveDone.connect(solved)
    win.session.frameReady.connect(shown)
    QTimer.singleShot(MOVE_MS, up)
    run_until(lambda: release["gen"] is not None, 5)
    gen = release["gen"]
    ended = run_until(lambda: not win.is_solving(), 120)
    run_until(lambda: settled(win), 30)
    meter.stop()
    win.solveDone.disconnect(solved)
    win.session.frameReady.disconnect(shown)
    phase = max(("drag", "release"), key=lambda p: meter.worst.get(p, 0.0))
    composer = getattr(vp.scene.model, "composer", None)  # (the benchmark runs older code too)
    passes = list(getattr(composer, "pass_seconds", []))
    return {
        "passes": len(passes),
        "longest_pass": max(passes, default=0.0),
        "show": vp.paint_seconds,  # (the last paint: the one that showed the passes)
        "rate": redraws / elapsed,
        "stall": max(meter.worst.get("drag", 0.0), meter.worst.get("release", 0.0)),
        "stall_cpu": max(meter.busiest.get("drag", 0.0), meter.busiest.get("release", 0.0)),
        "stall_phase": "while dragging" if phase == "drag" else "during the release solve",
        "final": meter.worst.get("final", 0.0),
        "result_gap": meter.worst.get("result", 0.0),
        "converged": bool(ended and win.state.solved and win.state.converged),
        "proxy": " and ".join(sorted(drawn)) or "nothing",
        "generation": gen,
        "result": release["result"] if release["result"] is not None else float("inf"),
        "cull": getattr(win.viewport.scene.model, "cull", False),
    }


def open_window(path: Path, prepared: bool = True):
    """The editor window on the model at ``path``, shown (a QApplication made if needed);
    ``prepared``: the levels set up first, as opening a file does in the background."""
    from PySide6.QtWidgets import QApplication

    from isochor.app.editor.document import Document
    from isochor.app.view import style
    from isochor.app.window.mainwindow import MainWindow

    app = QApplication.instance() or QApplication([])
    style.apply_dark_theme(app)
    doc = Document.open(path)
    prepare = getattr(doc.surface, "prepare", None)
    if prepared and prepare is not None:
        prepare(doc.state.problem.options)
    win = MainWindow(doc)
    win.set_headless_errors()
    win.resize(1360, 860)
    win.show()
    return app, win


def one_close(path: Path) -> tuple[float, bool]:
    """Open the model in a new window, drag a node (live solving off) and, once the solve
    of the release runs, close the window: the seconds ``close()`` took, and whether the
    solve was still running as it closed.

    The levels are not set up beforehand, so the release's solve is a model's first one
    (the levels' set-up included) and lasts long enough to be closed on."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    _, win = open_window(path, prepared=False)
    try:
        run_until(lambda: win.viewport.paints > 0 and settled(win), 120)
        row = drag_node(win)
        vp = win.viewport
        start = vp.camera_control.projection().project(vp.nodes)[0][row]
        moves = drag_path(start, 0.15)
        left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier

        def at(xy) -> QPoint:
            return QPoint(int(round(xy[0])), int(round(xy[1])))

        QTest.mousePress(vp, left, none, at(start))
        for xy in moves:
            QTest.mouseMove(vp, at(xy))
            run_until(lambda: False, MOVE_MS / 1000)
        QTest.mouseRelease(vp, left, none, at(moves[-1]))
        # closed as soon as the release's solve runs: a first solve of the 346k model
        # now ends within about 60 ms, often before its first record is shown
        run_until(win.is_solving, 30)
        solving = win.is_solving()
        win.undo_stack.setClean()  # no question about unsaved edits
        t = time.perf_counter()
        win.close()
        return time.perf_counter() - t, solving
    finally:
        win.undo_stack.setClean()
        win.close()
        win.shutdown()


def _measure(path: Path, repeats: int) -> list[dict]:
    app, win = open_window(path)
    try:
        run_until(lambda: win.viewport.paints > 0 and settled(win), 120)
        win.action_set.live.setChecked(True)
        row = drag_node(win)
        runs = []
        # the first is a warm-up; then with and without back-face culling, interleaved
        for i in range(2 * repeats + 1):
            model = win.viewport.scene.model
            if hasattr(model, "set_culling"):  # (the benchmark also runs older code)
                model.set_culling(i % 2 == 1 or i == 0)
            meter = Meter()
            run = one_drag(app, win, row, meter)
            if i:
                runs.append(run)
            win.undo_stack.undo()
            run_until(lambda: settled(win), 60)
        return runs
    finally:
        win.undo_stack.setClean()
        win.close()
        win.shutdown()


def main(argv: list[str] | None = None) -> None:
    """``xvfb-run python -m benchmarks.window [repeats]``: the drags alone (no closing or
    opening rows, nothing written), each run's figures and the full-resolution row."""
    import sys

    from benchmarks.run import DEFAULT_MODELS
    from isochor.app.view.modeldraw import IDLE_MS

    args = sys.argv[1:] if argv is None else argv
    flags = {a for a in args if a.startswith("--")}
    args = [a for a in args if not a.startswith("--")]
    repeats = int(args[0]) if args else 3
    models = Path(os.environ.get("ISOCHOR_MODELS", DEFAULT_MODELS))
    if "--stalls" in flags:  # what the GUI thread does in the long gaps
        from benchmarks.stalls import StallProbe

        Meter.probe = StallProbe().start()
    if "--rebuild" in flags:  # the opening and rebuilding rows' gaps instead of the drags
        from benchmarks.opening import open_and_rebuild

        for _ in range(repeats):
            r = open_and_rebuild(models / ARMADILLO)
            print(", ".join(f"{k} {1e3 * v:.0f} ms" for k, v in r.items()))
        _probe_report()
        os._exit(0)
    runs = _measure(models / ARMADILLO, repeats)
    for r in runs:
        print(
            f"{'culled' if r['cull'] else 'unculled'}: {r['rate']:.1f} redraws/s, "
            f"full resolution {1e3 * r['final']:.1f} ms (passes {r['passes']}, the longest "
            f"{1e3 * r['longest_pass']:.1f} ms), the result's frame {1e3 * r['result_gap']:.1f} "
            f"ms, stall {1e3 * r['stall']:.1f} ms (GUI thread CPU in the busiest gap "
            f"{1e3 * r['stall_cpu']:.1f} ms)"
        )
    _probe_report()
    culled = [r for r in runs if r["cull"]] or runs
    final = float(np.median([r["final"] for r in culled]))
    frame = 1 / float(np.median([r["rate"] for r in culled]))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{WHAT_FINAL}: {1e3 * final:.1f} ms against one proxy frame {1e3 * frame:.1f} ms")
    print(_final_reason(culled, IDLE_MS, final, frame) + f" (load {load:.1f})")
    os._exit(0)  # (as the editor: no finalisation of the window's VTK objects)


def _probe_report() -> None:
    if Meter.probe is not None:
        Meter.probe.stop()
        print(Meter.probe.report(STALL_TARGET))


if __name__ == "__main__":
    main()
