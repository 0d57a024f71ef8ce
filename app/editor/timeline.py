"""The timeline's data and rules that need no Qt (issue 13): the keys and settings a document
holds (:class:`TimelineState`), the solved frames (:class:`FrameCache`), what the view shows
at a frame and the words the window says about it.

What an artist sees (the window follows these rules; :mod:`isochor.app.window.timelinetools`):

* The document's working edit (moves, pins, axis pins, handles, target) is what every edit
  changes, as without a timeline. **Set Key** (I) keys it at the current frame, replacing a
  key there; **Remove Key** (Alt+I) removes the key at the current frame.
* Going to a **key frame** loads that key's edit as the working edit (one undo step, "Go to
  key N"; going from key to key merges into that one step), so the artist changes it and
  presses I to key it again. The view shows the working edit.
* Going to a frame **between keys** (or before the first, after the last) shows that frame's
  *solved* pose from the cache of solved frames, or, while it is not solved yet, the
  interpolated start (the keys' poses blended, the fixed nodes on their path), and says so.
  The working edit stays as it was: an edit made there starts from the working edit, not
  from the frame on screen, and the view then shows the working edit again.
* The frames are solved in the background after every change of the keys, the frame range,
  the interpolation or the goal (:func:`sequence_signature`), with
  :func:`isochor.core.scenario.sequence.solve_sequence`, which solves every key pose and then every
  frame in order, each from the frame before.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field, replace

import numpy as np

from ...core.errors import IsochorError
from ...core.goal.spec import Goal
from ...core.scenario.edits import Edit, Move
from ...core.scenario.poses import INTERPOLATIONS, MAX_FRAMES, Pose, Timeline
from ...core.scenario.problem import Problem

#: a new document's frame range: one second at 24 frames a second
DEFAULT_END = 24
DEFAULT_RATE = 24.0
RATE_RANGE = (0.1, 1000.0)
#: how many solved sequences are kept (undo and redo of a key find theirs again) ...
KEPT_SEQUENCES = 8
#: ... while they hold at most this many node positions (120 MB) besides the current one
KEPT_NODES = 5_000_000


@dataclass(frozen=True)
class TimelineState:
    """The keys (sorted by frame, each target ratio set) and the timeline's settings; a
    part of every document state, so key edits undo like any other edit."""

    keys: tuple[Pose, ...] = ()
    start: int = 0
    end: int = DEFAULT_END
    rate: float = DEFAULT_RATE
    interpolation: str = "linear"

    @classmethod
    def of(cls, scenario) -> TimelineState:
        """A scenario's poses and timeline; a pose without a target ratio gets the
        scenario's (what it means there), so a key never depends on the working edit."""
        tl = scenario.timeline
        if tl is None:
            return cls()
        ratio = scenario.goal.target_ratio
        keys = tuple(
            p if p.target_ratio is not None else replace(p, target_ratio=ratio) for p in tl.poses
        )
        return cls(keys, tl.start, tl.end, tl.rate, tl.interpolation)

    def core(self) -> Timeline | None:
        """The scenario's :class:`~isochor.core.scenario.poses.Timeline` (None without keys)."""
        if not self.keys:
            return None
        return Timeline(self.keys, self.start, self.end, self.rate, self.interpolation)

    @property
    def frames(self) -> range:
        return range(self.start, self.end + 1)

    @property
    def key_frames(self) -> tuple[int, ...]:
        return tuple(p.frame for p in self.keys)

    def key_at(self, frame: int) -> Pose | None:
        return next((p for p in self.keys if p.frame == frame), None)

    def with_key(self, pose: Pose) -> TimelineState:
        """A key at ``pose.frame``, replacing the one there."""
        keys = sorted([p for p in self.keys if p.frame != pose.frame] + [pose], key=_frame)
        return replace(self, keys=tuple(keys))

    def without_key(self, frame: int) -> TimelineState:
        return replace(self, keys=tuple(p for p in self.keys if p.frame != frame))

    def previous_key(self, frame: int) -> int | None:
        return max((f for f in self.key_frames if f < frame), default=None)

    def next_key(self, frame: int) -> int | None:
        return min((f for f in self.key_frames if f > frame), default=None)

    def clamp(self, frame: int) -> int:
        return int(min(max(int(frame), self.start), self.end))

    def changed(self, **changes) -> TimelineState:
        """With new ``start``, ``end``, ``rate`` or ``interpolation``, checked as the
        scenario file's fields are (:class:`IsochorError` naming the field)."""
        new = replace(self, **changes)
        for name in ("start", "end"):
            value = getattr(new, name)
            if not isinstance(value, int) or isinstance(value, bool) or abs(value) > MAX_FRAMES:
                raise IsochorError(f"timeline.{name}: must be a whole number of frames")
        if not 0 <= new.end - new.start < MAX_FRAMES:
            raise IsochorError(
                f"timeline: end ({new.end}) must be at or after start ({new.start}), at most "
                f"{MAX_FRAMES} frames"
            )
        if not RATE_RANGE[0] <= float(new.rate) <= RATE_RANGE[1]:
            raise IsochorError("timeline.rate: must be 0.1 to 1000 frames a second")
        if new.interpolation not in INTERPOLATIONS:
            raise IsochorError(f"timeline.interpolation: one of {', '.join(INTERPOLATIONS)}")
        return replace(new, rate=float(new.rate))


def _frame(pose: Pose) -> int:
    return pose.frame


# -- the working edit as a key, and a key as the working edit ------------------------------------
def state_edit(st) -> Edit:
    """A document state's edit as the scenario writes it: moved nodes as ``to`` moves, pins on
    all axes, pins on some axes, handles."""
    lat = st.lattice
    moves = tuple(
        Move(lat.ijk(r), to=tuple(float(x) for x in st.nodes[r])) for r in np.flatnonzero(st.moved)
    )
    full = st.pin_axes.all(axis=1)
    pins = tuple(lat.ijk(r) for r in np.flatnonzero(full & ~st.moved))
    axis_pins = tuple(
        (lat.ijk(r), "".join(a for a, on in zip("xyz", st.pin_axes[r]) if on))
        for r in np.flatnonzero(st.axis_pinned)
    )
    return Edit(moves, pins, axis_pins, tuple(st.handles))


def pose_of(st, frame: int) -> Pose:
    """The working edit of document state ``st`` as the key at ``frame``."""
    return Pose(int(frame), state_edit(st), float(st.goal.target_ratio))


def same_pose(a: Pose, b: Pose, lattice) -> bool:
    """Both keys hold the same edit: the same nodes fixed at the same places (moved ones
    moved), the same handles and target (a ``by`` move equals the ``to`` move it makes)."""
    if a.target_ratio != b.target_ratio or a.edit.handles != b.edit.handles:
        return False
    if {m.node for m in a.edit.moves} != {m.node for m in b.edit.moves}:
        return False
    na, fa = a.edit.apply(lattice)
    nb, fb = b.edit.apply(lattice)
    return bool(np.array_equal(fa, fb) and np.array_equal(na[fa], nb[fb]))


def pose_flags(pose: Pose, lattice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A key's nodes (rest with its moves), (n, 3) pinned coordinates and (n,) moved rows:
    what a document state holds for it."""
    nodes, _ = pose.edit.apply(lattice)
    n = lattice.n_nodes
    moved = np.zeros(n, dtype=bool)
    pins = np.zeros((n, 3), dtype=bool)
    for mv in pose.edit.moves:
        moved[lattice.index(*mv.node)] = True
    for p in pose.edit.pins:
        pins[lattice.index(*p)] = True
    for p, axes in pose.edit.axis_pins:
        pins[lattice.index(*p), ["xyz".index(a) for a in axes]] = True
    return nodes, pins, moved


# -- solving the frames ---------------------------------------------------------------------------
def sequence_goal(st) -> Goal:
    """The goal the frames of document state ``st`` are solved with: the state's, with the
    scenario's target (every key holds its own target; the working edit's is not theirs)."""
    return replace(st.goal, target_ratio=st.problem.scenario.goal.target_ratio)


def sequence_signature(st) -> tuple | None:
    """What the solved frames of document state ``st`` depend on: the problem, the keys, the
    frame range, the interpolation and the goal's settings (:func:`sequence_goal`; not the
    rate, not the working edit). None without keys."""
    tl = st.timeline
    if not tl.keys:
        return None
    return (id(st.problem), tl.keys, tl.start, tl.end, tl.interpolation, sequence_goal(st))


def sequence_problem(st) -> Problem:
    """The problem :func:`~isochor.core.scenario.sequence.solve_sequence` solves for state
    ``st``: its scenario with the timeline and the goal's settings, the first key started
    from the rest lattice (so the frames do not depend on the working edit)."""
    problem = st.problem
    sc = problem.scenario.with_(timeline=st.timeline.core(), goal=sequence_goal(st))
    lattice = problem.surface.lattice
    fixed = np.zeros((lattice.n_nodes, 3), dtype=bool)
    return replace(problem, scenario=sc, nodes=lattice.rest_nodes, fixed=fixed)


@dataclass
class FrameCache:
    """The solved frames of one signature: frame -> (n, 3) nodes, the keys' own solves, and
    how far the background solve has come."""

    signature: tuple | None = None
    problem: object = None  #: kept so that the id in the signature is not reused
    n_keys: int = 0
    total: int = 0  #: frames in the range
    frames: dict[int, np.ndarray] = field(default_factory=dict)
    errors: dict[int, float] = field(default_factory=dict)  #: frame -> |dV|/V0
    unconverged: set[int] = field(default_factory=set)
    keys: dict[int, object] = field(default_factory=dict)  #: key frame -> its SolveResult
    done: bool = False
    failed: str = ""

    @classmethod
    def for_state(cls, st) -> FrameCache:
        tl = st.timeline
        return cls(sequence_signature(st), st.problem, len(tl.keys), len(tl.frames))

    def add(self, frame) -> None:
        """A :class:`~isochor.core.scenario.sequence.Frame` the solve yielded."""
        result = frame.result
        if frame.key:
            self.keys[frame.frame] = result
            return
        self.frames[frame.frame] = np.array(result.nodes)
        self.errors[frame.frame] = float(result.rel_volume_error)
        if result.converged:
            self.unconverged.discard(frame.frame)
        else:
            self.unconverged.add(frame.frame)

    def finish(self) -> None:
        """The background solve ended: every frame it could solve is here."""
        self.done = True

    def fail(self, message: str) -> None:
        """The background solve stopped: ``message`` says why."""
        self.failed = message

    @property
    def complete(self) -> bool:
        return self.done or len(self.frames) >= self.total

    def progress(self) -> str:
        """``"Solving frames 7/25"``, ``"25 frames solved"``."""
        if self.failed:
            return f"Frames not solved: {self.failed}"
        if self.complete:
            bad = len(self.unconverged)
            note = f", {bad} not converged" if bad else ""
            return f"{len(self.frames)} frames solved{note}"
        if len(self.keys) < self.n_keys and not self.frames:
            return f"Solving keys {len(self.keys)}/{self.n_keys}"
        return f"Solving frames {len(self.frames)}/{self.total}"


class FrameCaches:
    """The few newest :class:`FrameCache` objects by signature (undo and redo of a key edit
    come back to frames solved before)."""

    def __init__(self, kept: int = KEPT_SEQUENCES, nodes: int = KEPT_NODES) -> None:
        self.kept = kept
        self.nodes = nodes
        self._caches: OrderedDict[tuple, FrameCache] = OrderedDict()

    def get(self, st) -> FrameCache | None:
        """The cache of ``st``'s frames (a new empty one when none is kept); None without
        keys."""
        sig = sequence_signature(st)
        if sig is None:
            return None
        cache = self._caches.get(sig)
        if cache is None:
            cache = self._caches[sig] = FrameCache.for_state(st)
        self._caches.move_to_end(sig)
        n = st.lattice.n_nodes
        while len(self._caches) > 1 and (
            len(self._caches) > self.kept
            or sum(len(c.frames) * n for c in self._caches.values()) > self.nodes
        ):
            self._caches.popitem(last=False)  # the oldest, never the one returned
        return cache

    def clear(self) -> None:
        self._caches.clear()


# -- what a frame shows ---------------------------------------------------------------------------
def key_place(pose: Pose, lattice, cache: FrameCache | None) -> np.ndarray:
    """A key's solved nodes when its solve is known, else its edit on the rest lattice."""
    if cache is not None and pose.frame in cache.keys:
        return np.array(cache.keys[pose.frame].nodes)
    return pose.edit.apply(lattice)[0]


def frame_nodes(
    tl: TimelineState, lattice, cache: FrameCache | None, frame: int
) -> tuple[np.ndarray, bool]:
    """The nodes to show at ``frame`` and whether they are solved: the cached solve, or the
    interpolated start (the two keys' poses blended with the timeline's easing, so the fixed
    nodes are on the path the solve gives them)."""
    if cache is not None and frame in cache.frames:
        return np.array(cache.frames[frame]), True
    a, b, s = tl.core().segment(frame)
    na, nb = key_place(tl.keys[a], lattice, cache), key_place(tl.keys[b], lattice, cache)
    return (1.0 - s) * na + s * nb, False


def frame_target(tl: TimelineState, frame: int) -> float:
    """The target volume ratio at ``frame`` (the keys' eased between them)."""
    a, b, s = tl.core().segment(frame)
    ra, rb = (tl.keys[i].target_ratio for i in (a, b))
    return (1.0 - s) * ra + s * rb


def frame_fixed(tl: TimelineState, lattice, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """The (n, 3) fixed coordinates and (n,) moved rows of ``frame`` (either key's), to mark
    the nodes of a frame on screen."""
    a, b, _ = tl.core().segment(frame)
    _, pa, ma = pose_flags(tl.keys[a], lattice)
    _, pb, mb = pose_flags(tl.keys[b], lattice)
    return pa | pb, ma | mb


def where_words(tl: TimelineState, frame: int) -> str:
    """``"between keys 0 and 12"``, ``"key 12"``, ``"after the last key (24), its pose
    held"``."""
    frames = tl.key_frames
    if frame in frames:
        return f"key {frame}"
    if frame < frames[0]:
        return f"before the first key ({frames[0]}), its pose held"
    if frame > frames[-1]:
        return f"after the last key ({frames[-1]}), its pose held"
    return f"between keys {tl.previous_key(frame)} and {tl.next_key(frame)}"


def describe(tl: TimelineState, frame: int, showing: bool, solved: bool, keyed=True) -> str:
    """What the view shows at ``frame``: the status line of the timeline.

    ``showing``: the view shows the timeline's frame (between keys), not the working edit;
    ``solved``: that frame is solved; ``keyed``: at a key frame, the working edit is that
    key's."""
    head = f"Frame {frame} of {tl.start}–{tl.end}"
    if not tl.keys:
        return f"{head} — no keys yet: press I to key the working pose at this frame."
    where = where_words(tl, frame)
    if showing:
        how = "solved" if solved else "not solved yet: the keys' poses blended are shown"
        return (
            f"{head} — {where}, {how}. An edit here starts from the working pose, "
            "not from this frame."
        )
    if frame in tl.key_frames and keyed:
        return f"{head} — key {frame}: this is its edit; change it and press I to key it again."
    if frame in tl.key_frames:
        return (
            f"{head} — key {frame}, but the working pose shown is not its edit: press I to "
            "key it here, or click the frame to load the key."
        )
    return (
        f"{head} ({where}) — showing the working pose, not keyed: press I to key it at "
        f"frame {frame}."
    )
