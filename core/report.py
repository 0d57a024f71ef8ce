"""The report of a solve: one JSON-ready dict, the same for the command line's
``--report`` and the Python API."""

from __future__ import annotations

from typing import Any

import numpy as np

from .io.caps import summary
from .io.repair import count_bodies
from .scenario.problem import Problem
from .solve.records import SolveResult


def make_report(
    problem: Problem, result: SolveResult, source: str, time_s: float | None = None
) -> dict[str, Any]:
    """The JSON report of a solve (volumes on the full-resolution mesh), as the command
    line writes it and the Python API returns it.

    Parameters
    ----------
    problem : what was solved
    result : how it ended
    source : where the scenario came from, in words ("example torus-compression", a path)
    time_s : the whole run's seconds (load and solve); the solve's own by default
    """
    sc = problem.scenario
    lattice = problem.surface.lattice
    return {
        "scenario": source,
        "model": dict(sc.model),
        "model_path": str(sc.model_path()) if "path" in sc.model else None,
        "lattice": list(problem.surface.lattice.shape),
        "lattice_basis": list(problem.surface.lattice.basis),
        "lattice_outside": bool(problem.surface.lattice.outside),
        "triangles": problem.surface.full.own_faces,
        "bodies": _bodies(problem),
        "caps": _caps(problem),
        "volume_original": result.volume_original,
        "volume_target": result.volume_target,
        "volume_final": result.volume_final,
        "relative_volume_error": result.rel_volume_error,
        "target_error": result.target_error,
        **sc.goal.to_json(),  # each field under its scenario key
        "asymmetry": result.asymmetry,
        "handles": [
            {"at": list(h.at), "to": list(h.to), "reached": list(h.reached), "miss": h.miss}
            for h in result.handles
        ],
        "handles_met": result.handles_met,
        "held": {
            "face": result.held_face or None,
            "nodes": [list(lattice.ijk(r)) for r in result.held],
        },
        "folded": _folds(result.folds),
        "body_volumes": [
            {"original": b.original, "target": b.target, "final": b.final, "error": b.error}
            for b in result.bodies
        ],
        "centroid_shift": result.centroid_shift,
        "converged": bool(result.converged),
        "message": result.message,
        "terminal_level": result.terminal_level,
        "levels": [
            {
                "level": s.level,
                "triangles": s.triangles,
                "steps": s.steps,
                "time_s": s.time_s,
                "max_node_change": s.max_node_change,
                "relative_volume_error": s.rel_volume_error,
            }
            for s in result.levels
        ],
        "pyramid": [m.n_faces for m in problem.surface.levels],
        "nodes": [[float(x) for x in row] for row in result.nodes],
        "free_nodes": result.free_nodes,
        "energy": result.energy,
        "solve_time_s": result.elapsed,
        "time_s": result.elapsed if time_s is None else time_s,
        "warnings": list(problem.warnings),
    }


def sequence_report(problem: Problem, seq, source: str, time_s: float) -> dict[str, Any]:
    """The JSON report of a solved sequence (:func:`isochor.core.scenario.sequence.solve_sequence`):
    one row per frame and per key, and the top-level fields of :func:`make_report` for the
    whole sequence at its worst (``converged`` only if every frame did, the largest
    ``target_error``, the most folded frame, the first failing frame's message); ``nodes``
    are the last frame's."""
    frames = seq.frames
    worst = max(frames, key=lambda f: abs(f.result.target_error))
    folded = max(frames, key=lambda f: f.result.folds.fraction if f.result.folds else 0.0)
    failed = [f for f in frames if not f.result.converged]
    out = make_report(problem, frames[-1].result, source, time_s)
    timeline = problem.scenario.timeline
    assert timeline is not None  # a sequence is solved from its timeline
    out.update(
        converged=seq.converged,
        target_error=worst.result.target_error,
        relative_volume_error=worst.result.rel_volume_error,
        folded=_folds(folded.result.folds),
        message=f"frame {failed[0].frame}: {failed[0].result.message}" if failed else "",
        solve_time_s=seq.elapsed,
        sequence={
            "frames": len(frames),
            "start": timeline.start,
            "end": timeline.end,
            "rate": timeline.rate,
            "interpolation": timeline.interpolation,
        },
        frames=[_frame(f) for f in frames],
        keys=[_frame(f) for f in seq.keys],
    )
    return out


def _frame(f) -> dict[str, Any]:
    r = f.result
    return {
        "frame": f.frame,
        "converged": bool(r.converged),
        "relative_volume_error": r.rel_volume_error,
        "target_error": r.target_error,
        "volume_final": r.volume_final,
        "steps": sum(s.steps for s in r.levels),
        "time_s": r.elapsed,
        "handles_met": r.handles_met,
        "message": r.message,
    }


def _folds(folds: Any) -> dict[str, Any] | None:
    """The folded fractions (0 when nothing is turned inside out)."""
    if folds is None:
        return None
    low = folds.min_det if np.isfinite(folds.min_det) else None
    return {
        "fraction": folds.fraction,
        "vertex_fraction": folds.vertex_fraction,
        "interior_fraction": folds.interior_fraction,
        "min_det_j": low,
        # det J > 0 proven over the whole solid (true), a pocket found or not proven
        # (false), or not certified (null: folded samples, or a lattice of local bases)
        "proven_fold_free": folds.proven,
        "pocket": None
        if folds.witness is None
        else {"at": list(folds.witness), "det_j": folds.witness_det},
    }


def _caps(problem: Problem) -> dict[str, Any]:
    """The caps over the model's holes (the volumes are those of the capped solid)."""
    caps = summary(problem.surface.full)
    return {
        "holes": caps.holes,
        "boundary_edges": caps.boundary_edges,
        "area_ratio": caps.ratio,  # the caps' area over the model's own surface area
    }


def _bodies(problem: Problem) -> int:
    """The full mesh's bodies: as loading counted them, else counted now (labelling the
    faces of a big model again took 250 MB of the 1.38M armadillo's command at its end)."""
    known = problem.model.bodies
    return int(known) if known is not None else count_bodies(problem.surface.full)
