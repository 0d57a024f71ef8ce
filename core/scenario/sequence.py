"""Solve a timeline: every key pose, then every frame between them, each warm-started from
the one before so that the motion is continuous and cheap (:mod:`isochor.core.scenario.poses` says
what holds at each frame).

:func:`solve_sequence` is a generator like :func:`isochor.core.solve.multilevel.solve`: it yields
a :class:`Frame` as each frame is solved (keys first, flagged ``key``) and returns the
:class:`Sequence` of all frames in order. Closing it stops the work.
"""

from __future__ import annotations

import time
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np

from ..errors import IsochorError
from ..goal.handles import Handle
from ..solve.generators import run_to_end
from ..solve.records import SolveResult
from .poses import Timeline
from .problem import Problem


@dataclass(frozen=True)
class Frame:
    frame: int
    result: SolveResult
    key: bool = False  #: a key pose's own solve (yielded before the frames)


@dataclass(frozen=True)
class Sequence:
    frames: tuple[Frame, ...]  #: every frame from start to end, in order
    keys: tuple[Frame, ...]  #: the key poses' own solves
    elapsed: float

    @property
    def converged(self) -> bool:
        return all(f.result.converged for f in self.frames)


@dataclass(frozen=True)
class _Key:
    place: np.ndarray  #: (n, 3) the key's solved nodes
    fixed: np.ndarray  #: (n, 3) bool
    ratio: float
    handles: dict  #: at -> to


def _timeline(problem: Problem) -> Timeline:
    timeline = problem.scenario.timeline
    if timeline is None:
        raise IsochorError('the scenario has no poses: add "poses" to solve a sequence')
    return timeline


def solve_sequence(problem: Problem) -> Generator[Frame, None, Sequence]:
    """Solve the scenario's timeline; see the module notes."""
    t0 = time.perf_counter()
    timeline = _timeline(problem)
    lattice = problem.surface.lattice
    goal = problem.scenario.goal
    keys: list[_Key] = []
    key_frames: list[Frame] = []
    x = lattice.rest_nodes  # the keys' free nodes start at rest, not at the working edit
    for n, pose in enumerate(timeline.poses):
        nodes, fixed = pose.edit.apply(lattice, f"poses[{n}].")
        start = np.where(fixed, nodes, x)
        ratio = goal.target_ratio if pose.target_ratio is None else pose.target_ratio
        run = problem.solve(
            start, fixed, goal=goal.with_(target_ratio=ratio), handles=pose.edit.handles
        )
        result = run_to_end(run)
        x = np.array(result.nodes)
        keys.append(_Key(x, fixed, ratio, {h.at: h.to for h in pose.edit.handles}))
        key_frames.append(Frame(pose.frame, result, key=True))
        yield key_frames[-1]
    frames: list[Frame] = []
    x = keys[0].place
    for f in timeline.frames:
        a, b, s = timeline.segment(f)
        ka, kb = keys[a], keys[b]
        fixed = ka.fixed | kb.fixed
        place = (1.0 - s) * ka.place + s * kb.place
        start = np.where(fixed, place, x)
        ratio = (1.0 - s) * ka.ratio + s * kb.ratio
        handles = []
        for at in dict.fromkeys([*ka.handles, *kb.handles]):
            ends = [
                np.asarray(k.handles[at])
                if at in k.handles
                else lattice.deform(np.array([at]), k.place)[0]
                for k in (ka, kb)
            ]
            handles.append(Handle(at, (1.0 - s) * ends[0] + s * ends[1]))
        run = problem.solve(
            start, fixed, goal=goal.with_(target_ratio=ratio), handles=handles, near=True
        )
        result = run_to_end(run)
        x = np.array(result.nodes)
        frames.append(Frame(f, result))
        yield frames[-1]
    return Sequence(tuple(frames), tuple(key_frames), time.perf_counter() - t0)


def frame_path(pattern: str, frame: int) -> str:
    """``pattern`` with its run of ``#`` replaced by the frame number, zero-padded to the
    run's length (``out/f_####.obj`` -> ``out/f_0012.obj``)."""
    start = pattern.rfind("#")
    if start < 0:
        raise IsochorError(f"{pattern}: a sequence of files needs #### where the frame goes")
    first = start
    while first > 0 and pattern[first - 1] == "#":
        first -= 1
    width = start - first + 1
    sign = "-" if frame < 0 else ""
    return f"{pattern[:first]}{sign}{abs(frame):0{width}d}{pattern[start + 1 :]}"
