"""Keyframed poses: squash and stretch over time (the paper's animation use case).

A scenario may hold ``poses``: each a key frame with the edit at that frame (moves, pins,
handles, a target volume ratio). :class:`Timeline` says what holds at any frame between
the keys; :mod:`isochor.core.scenario.sequence` solves every frame.

Between key A (frame ``fa``) and key B (frame ``fb``), at frame ``f``, with
``s = ease((f - fa) / (fb - fa))`` (``linear``, or ``smooth``: 3s^2 - 2s^3, which starts
and stops at rest):

* a node coordinate fixed in A or in B is fixed on the straight path between its place in
  A's solved pose and its place in B's (a node free in A starts where A's solve put it, so
  a node that is moved only from B on leaves A's pose without a jump);
* a handle of A or B goes from where its point is in A's solved pose (or A's own target)
  to B's likewise;
* the target volume ratio goes from A's to B's;
* before the first key the first key's edit holds, after the last the last's.

At a key frame itself this is exactly the key's edit (the other key's fixed coordinates
sit where the key's own solve put them), so every key frame shows its solved pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import IsochorError
from ..goal.spec import goal_field
from ..validate import as_list, check_keys, number, word
from .edits import Edit

INTERPOLATIONS = ("linear", "smooth")
#: frames a timeline may hold (a minute at 60 frames a second is 3600)
MAX_FRAMES = 10_000
#: a pose's own target ratio: the goal's field, under its scenario key
RATIO = goal_field("target_ratio")


@dataclass(frozen=True)
class Pose:
    """The edit at one key frame; ``target_ratio`` None keeps the scenario's."""

    frame: int
    edit: Edit = Edit()
    target_ratio: float | None = None


@dataclass(frozen=True)
class Timeline:
    """The key poses and the frames to solve (``start`` to ``end``, both included)."""

    poses: tuple[Pose, ...]
    start: int
    end: int
    rate: float = 24.0
    interpolation: str = "linear"

    @classmethod
    def from_json(cls, items: Any, settings: Any, shape, version: int) -> Timeline | None:
        """The ``poses`` list and ``timeline`` object of a scenario (None without poses)."""
        poses: list[Pose] = []
        for n, doc in enumerate(as_list(items, "poses")):
            where = f"poses[{n}]"
            check_keys(doc, where, {"frame", "moves", "pins", "handles", RATIO.key}, {"frame"})
            frame = doc["frame"]
            if not isinstance(frame, int) or isinstance(frame, bool) or abs(frame) > MAX_FRAMES:
                raise IsochorError(f"{where}.frame: must be a whole number of frames")
            if any(p.frame == frame for p in poses):
                raise IsochorError(f"{where}.frame: frame {frame} already has a key")
            ratio = doc.get(RATIO.key)
            if ratio is not None:
                ratio = RATIO.check(number(ratio, f"{where}.{RATIO.key}"), where)
            poses.append(Pose(frame, Edit.from_json(doc, shape, version, f"{where}."), ratio))
        settings = {} if settings is None else settings
        check_keys(settings, "timeline", {"start", "end", "rate", "interpolation"}, set())
        if not poses:
            if settings:
                raise IsochorError("timeline: there are no poses to play")
            return None
        poses.sort(key=lambda p: p.frame)
        start = settings.get("start", poses[0].frame)
        end = settings.get("end", poses[-1].frame)
        for name, value in (("start", start), ("end", end)):
            if not isinstance(value, int) or isinstance(value, bool) or abs(value) > MAX_FRAMES:
                raise IsochorError(f"timeline.{name}: must be a whole number of frames")
        if not 0 <= end - start < MAX_FRAMES:
            raise IsochorError(
                f"timeline: end ({end}) must be at or after start ({start}), at most "
                f"{MAX_FRAMES} frames"
            )
        rate = number(settings.get("rate", 24.0), "timeline.rate", (0.1, 1000.0))
        interp = word(
            settings.get("interpolation", "linear"), "timeline.interpolation", INTERPOLATIONS
        )
        return cls(tuple(poses), start, end, rate, interp)

    def to_json(self) -> tuple[list, dict]:
        poses = []
        for p in self.poses:
            doc: dict[str, Any] = {"frame": p.frame, **p.edit.to_json()}
            if p.target_ratio is not None:
                doc[RATIO.key] = p.target_ratio
            poses.append(doc)
        settings = {"start": self.start, "end": self.end, "rate": self.rate}
        return poses, {**settings, "interpolation": self.interpolation}

    @property
    def frames(self) -> range:
        return range(self.start, self.end + 1)

    def segment(self, frame: int) -> tuple[int, int, float]:
        """The keys (indices into ``poses``) around ``frame`` and the eased weight of the
        second."""
        frames = [p.frame for p in self.poses]
        b = int(np.searchsorted(frames, frame, side="right"))
        if b == 0:
            return 0, 0, 0.0
        if b == len(frames):
            return b - 1, b - 1, 0.0
        a = b - 1
        s = (frame - frames[a]) / (frames[b] - frames[a])
        if self.interpolation == "smooth":
            s = s * s * (3.0 - 2.0 * s)
        return a, b, float(s)
