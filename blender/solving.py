"""The add-on's solves on a :class:`~.scene.Target`: one solve on a background thread
(:class:`Solve`: Blender's data read before it starts and written after it ends, both on
Blender's main thread; the thread runs Isochor on arrays only), the live solver that
re-solves while pinned points move (coarse levels first), and the bake of a frame range.
Nothing is written to Blender's data until a solve has converged. Each takes the session
of its problem from :data:`.sessions.SESSIONS` (built once per mesh and lattice) and hands
it back when it ends."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import bpy
import numpy as np

from .rig import isochor_order
from .scene import BAKED, RigError, Target
from .sessions import SESSIONS, problem_key


@dataclass
class Settings:
    """What the panel sets: where the pins come from and the volume to keep."""

    pins: str = "SELECTED"  #: "SELECTED" points or a vertex "GROUP"
    group: str = ""
    ratio: float = 1.0  #: the target volume / the rest volume
    preserve: str = "total"  #: the meshes' volumes summed, or "per-body": each its own


def _failure(result) -> str | None:
    if result.converged:
        return None
    return f"Isochor: the solve did not converge ({result.message}); nothing was changed"


def check_pins(rig) -> None:
    if not rig.pinned.any():
        raise RigError("Isochor: pin some lattice points first (select them, or a vertex group)")
    if rig.pinned.all():
        raise RigError("Isochor: every lattice point is pinned; nothing is free to solve")


class _CancelledError(Exception):
    """Raised in the solving thread by its progress callback once Esc was pressed."""


class Solve:
    """One Preserve Volume solve on a background thread, so that Blender's interface never
    waits for it. Made on Blender's main thread, it reads the rig (bpy) and starts the
    thread, which builds the Isochor session and solves on arrays only (NumPy, or the
    compiled kernels, which release the GIL). The main thread asks :attr:`running`,
    :attr:`stage` and :attr:`fraction` (a timer, for the status bar), may :meth:`cancel`,
    and once the thread has ended calls :meth:`finish`, which writes the result: nothing
    is written before, so a cancelled or failed solve leaves the scene as it was."""

    def __init__(self, target: Target, settings: Settings) -> None:
        self.target, self.settings = target, settings
        self.rig = target.rig(settings.pins, settings.group)
        self.rig.preserve = settings.preserve
        check_pins(self.rig)
        self.key = problem_key(self.rig)
        self.free = self.rig.written()
        self.read = target.points()  #: the points as the solve read them
        self.stage, self.fraction = "load", 0.0
        self.result = None
        self.nodes: np.ndarray | None = None
        self.error: BaseException | None = None
        self._cancel = threading.Event()
        self._thread = threading.Thread(target=self._run, name="isochor-solve", daemon=True)
        self._thread.start()

    def _progress(self, stage: str, fraction: float) -> None:
        if self._cancel.is_set():
            raise _CancelledError
        self.stage, self.fraction = stage, fraction

    def _run(self) -> None:
        try:
            session = SESSIONS.take(self.key, self.rig, self.settings.ratio, self._progress)
            result = session.solve()
            if result.converged:
                self.nodes = self.rig.shown(session, result.nodes)
            self.result = result
            session.progress = None
            SESSIONS.keep(self.key, session)
        except _CancelledError:
            pass
        except Exception as exc:  # handed to the main thread: finish() raises it
            self.error = exc

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def cancel(self) -> None:
        """Stop at the next progress report (the thread ends soon after)."""
        self._cancel.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the thread; True once it has ended."""
        self._thread.join(timeout)
        return not self.running

    def finish(self) -> float:
        """On the main thread, once the thread has ended: write the solved points; returns
        the relative volume error Isochor measured. Raises the solve's error (one line),
        or :class:`RigError` when it was cancelled, did not converge, or the lattice
        changed while it ran; nothing is written then."""
        if self.running:
            raise RuntimeError("finish() before the solving thread ended")
        if self.error is not None:
            raise self.error
        if self.cancelled or self.result is None:
            raise RigError("Isochor: cancelled; nothing was changed")
        failure = _failure(self.result)
        if failure:
            raise RigError(failure)
        try:
            now = self.target.points()
        except ReferenceError:  # removed (or undone) while it solved
            raise RigError(
                "Isochor: the lattice was removed while it was solved; nothing was changed"
            ) from None
        if not np.array_equal(now, self.read):
            raise RigError(
                "Isochor: the lattice changed while it was solved; nothing was changed "
                "(press Preserve Volume again)"
            )
        self.target.write(self.nodes, self.free)
        return float(self.result.rel_volume_error)


def solve_once(target: Target, settings: Settings) -> float:
    """Solve the free points so the meshes under the modifier have ``ratio`` times their
    rest volume, waiting for the thread; write them. Returns the relative volume error
    Isochor measured."""
    job = Solve(target, settings)
    job.wait()
    return job.finish()


class LiveSolver:
    """Re-solves while the pinned points move: :meth:`tick` (called by a timer) restarts
    the solve when a pin moved or the pins changed, and runs it for a time budget, writing
    each level's nodes as it comes (the coarse ones first)."""

    def __init__(self, target: Target, settings: Settings) -> None:
        self.target, self.settings = target, settings
        self.rig = target.rig(settings.pins, settings.group)
        self.rig.preserve = settings.preserve
        self.key = problem_key(self.rig)
        self.session = SESSIONS.take(self.key, self.rig, settings.ratio)
        self.steps = None
        self.seen: tuple[bytes, bytes] | None = None
        self.solves = 0  #: solves finished
        self.last = None  #: the last finished result

    def _pins(self) -> tuple[np.ndarray, np.ndarray]:
        points = self.target.points()
        return self.target.pinned(self.settings.pins, self.settings.group), points

    def tick(self, budget: float = 0.03) -> bool:
        """One timer tick; True while a solve is running."""
        pinned, points = self._pins()
        key = (pinned.tobytes(), points[pinned].tobytes())
        if key != self.seen and pinned.any() and not pinned.all():
            self.seen = key
            if self.steps is not None:
                self.steps.close()
            shape = self.rig.shape
            self.rig.nodes = isochor_order(points, shape)
            self.rig.pinned = isochor_order(pinned, shape)
            self.rig.load(self.session)
            self.steps = self.session.steps()
        if self.steps is None:
            return False
        t0, record = time.perf_counter(), None
        free = self.rig.written()
        try:
            while record is None or time.perf_counter() - t0 < budget:  # a step at least
                record = next(self.steps)
        except StopIteration as done:
            self.steps, self.last = None, done.value
            self.solves += 1
            if done.value.converged:
                self.target.write(self.rig.shown(self.session, done.value.nodes), free)
            return False
        if record is not None:
            self.target.write(self.rig.shown(self.session, record.nodes), free)
        return True

    def stop(self) -> None:
        """Stop solving (a running solve keeps the nodes it last wrote); the session goes
        back to the cache."""
        if self.steps is not None:
            self.steps.close()
            self.steps = None
        SESSIONS.keep(self.key, self.session)


def bake(target: Target, settings: Settings, start: int, end: int) -> list[float]:
    """Solve every frame ``start..end`` of the keyframed lattice points (pins: the keyed
    points and the panel's), each from the frame before, then key the free points' solved
    positions on every frame. Returns each frame's relative volume error. Nothing is keyed
    when a frame fails."""
    scene = bpy.context.scene
    if end < start:
        raise RigError(f"Isochor: the bake range {start}..{end} is empty")
    keyed = target.keyed()
    if not keyed.any():
        raise RigError("Isochor: no lattice point has keyframes; key the moves to bake first")
    here, solved, errors = scene.frame_current, [], []
    session, key, previous = None, b"", None
    try:
        for frame in range(start, end + 1):
            scene.frame_set(frame)
            rig = target.rig(settings.pins, settings.group, extra_pins=keyed)
            rig.preserve = settings.preserve
            if rig.pinned.all():
                raise RigError("Isochor: every lattice point is pinned; nothing is free to solve")
            if session is None:
                key = problem_key(rig)
                session = SESSIONS.take(key, rig, settings.ratio)
            else:
                rig.load(session)
            if previous is not None:  # warm start: the free points where the frame before left them
                free = ~rig.pinned
                session.nodes[free] = previous[free]
            result = session.solve()
            failure = _failure(result)
            if failure:
                raise RigError(f"{failure} (frame {frame})")
            previous = np.array(result.nodes)
            solved.append((frame, rig.shown(session, previous), rig))
            errors.append(float(result.rel_volume_error))
        if session is not None:
            SESSIONS.keep(key, session)
    finally:
        scene.frame_set(here)
    points = target.lattice.data.points
    for frame, nodes, rig in solved:
        free = rig.written()
        target.write(nodes, free)
        for i in np.flatnonzero(free):
            points[int(i)].keyframe_insert("co_deform", frame=frame, group="Isochor")
    free_all = np.flatnonzero(solved[0][2].written())
    target.lattice[BAKED] = sorted(set(target.lattice.get(BAKED, [])) | set(map(int, free_all)))
    scene.frame_set(here)
    return errors
