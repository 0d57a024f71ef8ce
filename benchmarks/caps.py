"""The Open models section: what capping an open model's holes costs (issue 30).

An open model (the Stanford bunny with the five holes in its base, the Utah teapot's four
open pieces) is closed virtually when it is loaded (:mod:`isochor.core.io.caps`). The solid
the solver then works on is exactly the capped one, so the cost of capping is measured
against the same solid given closed: both are written as binary PLY (the model's own
triangles; the capped solid's, caps included), and each is opened, its pyramid built and a
first solve run, in one process, alternating, the repeats' medians compared. A drag's frames
(:func:`benchmarks.drag_cases.drag`) are timed on both the same way.

``python -m benchmarks --only caps`` runs it alone and replaces the section in
``docs/BENCHMARKS.md``.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from benchmarks.drag_cases import drag, dragged, model_problem
from benchmarks.timing import Timing
from isochor.core.io.caps import summary
from isochor.core.io.meshio import load_mesh, mesh_bytes
from isochor.core.solve.generators import run_to_end

HEADING = "## Open models: what capping costs"
#: capping may add at most this fraction to a first solve (open, pyramid, solve)
FIRST_TARGET = 0.10
#: and nothing to a drag frame: the same solid, so the same frames, within this or twice
#: the noise measured between two runs of the closed solid's frames
DRAG_NOISE = 0.05
#: live frames per drag
DRAG_FRAMES = 20
MODELS = ("stanford_bunny.obj", "teapot.obj")


@dataclass
class CapsRow:
    case: str
    holes: int
    cap_faces: int
    first_open: Timing
    first_closed: Timing
    frame_open: Timing
    frame_closed: Timing
    frame_again: Timing  #: the closed solid's frames again: the noise of the measurement

    @property
    def first_ratio(self) -> float:
        return self.first_open.median / self.first_closed.median

    @property
    def frame_ratio(self) -> float:
        return self.frame_open.median / self.frame_closed.median

    @property
    def noise(self) -> float:
        """How far two measurements of the same closed solid's frames differ."""
        return abs(self.frame_again.median / self.frame_closed.median - 1)

    def first_verdict(self) -> str:
        added = self.first_ratio - 1
        word = "MET" if added < FIRST_TARGET else "MISSED"
        return f"{word}: capping adds {100 * added:+.1f}% (target under {100 * FIRST_TARGET:g}%)"

    def frame_verdict(self) -> str:
        added = self.frame_ratio - 1
        allowed = max(DRAG_NOISE, 2 * self.noise)
        word = "MET" if added < allowed else "MISSED"
        return (
            f"{word}: {100 * added:+.1f}% (target: nothing, within the noise: the closed "
            f"solid measured twice differs by {100 * self.noise:.1f}%; allowed "
            f"{100 * allowed:.0f}%)"
        )


def _first_solve(path: Path) -> float:
    """Seconds to open ``path``, build its pyramid and solve a first edit."""
    t0 = time.perf_counter()
    problem = model_problem(path)
    x, fixed, _ = dragged(problem)
    run_to_end(problem.solve(x, fixed))
    return time.perf_counter() - t0


def run_caps(models: Path, repeats: int) -> tuple[list[CapsRow], list[str]]:
    rows, notes = [], []
    for name in MODELS:
        source = models / name
        if not source.is_file():
            notes.append(f"{name}: not found in {models}; its row is left out")
            continue
        full = load_mesh(source).mesh
        caps = summary(full)
        with tempfile.TemporaryDirectory() as tmp:
            open_path, closed_path = Path(tmp) / "open.ply", Path(tmp) / "closed.ply"
            open_path.write_bytes(mesh_bytes(full.own, ".ply"))
            closed_path.write_bytes(mesh_bytes(full.moved(full.vertices), ".ply"))
            for path in (open_path, closed_path):  # untimed: the kernels, the caches
                _first_solve(path)
            first = {open_path: [], closed_path: []}
            for _ in range(repeats):
                for path in first:
                    first[path].append(_first_solve(path))
            # the drags alternate too; a second closed copy measures the noise between two
            # runs of the same thing (the open and closed frames solve the same solid)
            problems = [model_problem(p) for p in (open_path, closed_path, closed_path)]
            levels = {p.surface.levels[-1].n_faces for p in problems}
            assert len(levels) == 1, "the open and closed solids differ"
            frames: list[list[float]] = [[], [], []]
            for _ in range(repeats):
                for times, problem in zip(frames, problems):
                    times += drag(problem, 1, frames=DRAG_FRAMES).frames.values
        row = CapsRow(
            f"{name} ({full.own_faces} triangles)",
            caps.holes,
            caps.boundary_edges,
            Timing(tuple(first[open_path])),
            Timing(tuple(first[closed_path])),
            Timing(tuple(frames[0])),
            Timing(tuple(frames[1])),
            Timing(tuple(frames[2])),
        )
        rows.append(row)
        print(
            f"  {row.case}: first solve {row.first_open.ms(0)} ms open vs "
            f"{row.first_closed.ms(0)} ms closed; {row.first_verdict()}"
        )
        print(
            f"  {'':{len(row.case)}}  drag frame {row.frame_open.ms(1)} ms vs "
            f"{row.frame_closed.ms(1)} ms; {row.frame_verdict()}"
        )
    return rows, notes


def section(rows: list[CapsRow], notes: list[str], command: str, repeats: int) -> list[str]:
    lines = [
        HEADING,
        "",
        f"`{command}`; medians of {repeats} repeats (min-max), open and closed alternating",
        "in one process. *open*: the model's own triangles as binary PLY, capped when it is",
        "opened; *closed*: the capped solid itself as binary PLY (the same solid, nothing to",
        "cap). *first solve*: open the file, build the pyramid, solve one edit (a corner",
        "moved by a tenth of the lattice). *drag frame*: a live frame of a drag (20 frames a",
        "drag, the drags alternating open / closed / closed again; *again*: the closed solid's",
        "frames measured a second time, the noise the open frames are judged against).",
        "",
        "| model | holes | cap triangles | first solve open ms | closed ms | open / closed "
        "| target | drag frame open ms | closed ms | again ms | target |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.case} | {r.holes} | {r.cap_faces} | {r.first_open.ms()} "
            f"| {r.first_closed.ms()} | {r.first_ratio:.3f} | {r.first_verdict()} "
            f"| {r.frame_open.ms(1)} | {r.frame_closed.ms(1)} | {r.frame_again.ms(1)} "
            f"| {r.frame_verdict()} |"
        )
    lines += ["", *[f"- {n}" for n in notes]] if notes else []
    return lines
