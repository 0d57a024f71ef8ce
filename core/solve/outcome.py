"""What a solve ends with: the result measured on the full-resolution mesh.

The volume, each body's volume, the centroid's shift and the folds (det J <= 0 at the
model's vertices and at points inside it) are measured on the full mesh, whatever level the
solve stopped at. A result is a success only when the solver converged and the full mesh
meets every constraint within the tolerance, nothing is folded and the volume kept its
sign: the command line's exit 0, the window's "Converged".
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import IsochorError
from ..goal.handles import handles_sentence
from .plan import Ending, Plan
from .records import BodyVolume, SolveResult, frozen_copy
from .solver import worst


def outcome(plan: Plan, end: Ending) -> SolveResult:
    """The result measured on the full mesh: volumes, bodies, centroid, folds, where each
    handle's point ended (the plan's handle system) and the asymmetry (its mirror); a
    result that misses a constraint, folds the model or turns its volume's sign is no
    success. Handles that cannot all be met are fitted by least squares and said so in the
    message: that is the best the lattice can do, not a failure."""
    surface, goal, opts, system, mirror = (
        plan.surface,
        plan.goal,
        plan.options,
        plan.system,
        plan.mirror,
    )
    x, converged = end.nodes, end.converged
    full = surface.level(-1)
    size = surface.size
    surface.survey(x)  # the volume and det J at the vertices in one pass, where it can
    v_final = full.volume(x)
    v0 = full.rest_volume
    target = goal.target_ratio * v0
    energy = surface.springs.energy(x) / size**2
    if not (np.all(np.isfinite(x)) and np.isfinite(v_final) and np.isfinite(energy)):
        # never a result made of overflowed numbers, whatever the caller does with it
        raise IsochorError(
            "The solve broke down: its numbers overflowed. The moves or the target "
            "volume are too extreme for this lattice."
        )
    cons = surface.constraints(-1, goal, system)
    c = cons.values(x)
    folds = surface.fold_check.measure(x)
    bodies: tuple[BodyVolume, ...] = ()
    if goal.preserve == "per-body" or surface.body_count > 1:
        rest = surface.bodies.volumes
        final = surface.bodies.measure(surface.deform(x), surface.full.faces)
        bodies = tuple(
            BodyVolume(float(r), float(goal.target_ratio * r), float(f))
            for r, f in zip(rest, final)
        )
    shift = None
    if goal.keep_centroid:
        m, _ = full.moment_and_gradient(x)
        shift = float(np.linalg.norm(m / v_final - full.rest_centroid)) / size
    problems = []
    if v_final * v0 <= 0:
        problems.append("the final volume has turned inside out (its sign changed)")
    if folds.folded and folds.fraction > 0:
        problems.append(
            f"the result is folded: {100 * folds.fraction:.3g}% of the model is turned "
            "inside out (det J <= 0)"
        )
    elif folds.witness is not None:  # folded between the samples
        where = ", ".join(f"{c:.6g}" for c in folds.witness)
        problems.append(
            f"the result is folded: a pocket inside the model between the fold check's "
            f"samples is turned inside out (det J = {folds.witness_det:.3g} at {where})"
        )
    unproven = (
        "no fold was found, but det J could not be proven positive everywhere inside the "
        "model (it comes within rounding of 0)"
        if folds.unproven
        else ""
    )
    if converged and np.max(np.abs(c)) > opts.tol_volume:
        problems.append(
            f"a constraint misses its tolerance on the full mesh ({worst(c):.2e} of it)"
            if goal.keep_centroid or len(c) > 1
            else f"volume error {worst(c) * cons.scales[0] / abs(v0):.2e} on the full mesh "
            "exceeds the tolerance"
        )
    ok = converged and not problems
    handles = ()
    if system is not None:  # the user's handles: the first half under symmetry
        handles = system.results(x, len(system.handles) // (2 if mirror else 1))
    fitted = handles_sentence(handles)
    notes = [n for n in (fitted, unproven) if n]
    message = "; ".join(([end.message] if end.message else []) + problems + notes)
    return SolveResult(
        frozen_copy(x),
        end.stats,
        end.terminal,
        v0,
        target,
        v_final,
        (v_final - target) / abs(v0),
        energy,
        plan.n_free,
        time.perf_counter() - plan.t0,
        ok,
        message,
        float(np.atleast_1d(end.lam)[0]),
        end.sigma,
        target_error=(v_final - target) / abs(target),
        constraint_error=worst(c),
        held=tuple(int(r) for r in np.flatnonzero(plan.held)),
        held_face=plan.face,
        folds=folds,
        bodies=bodies,
        centroid_shift=shift,
        handles=handles,
        asymmetry=None if mirror is None else mirror.asymmetry(x),
    )


def preview(plan: Plan, end: Ending) -> SolveResult:
    """A live drag's frame, measured on the level it was solved on (``end.terminal``) and
    never on the full mesh: the volume is that level's, scaled by the full mesh's rest
    volume over the level's; folds, bodies, the centroid and the handles are not measured.
    It is for showing, not for keeping: the solve when the drag ends measures the real
    result."""
    surface, goal, x, terminal = plan.surface, plan.goal, end.nodes, end.terminal
    level = surface.level(terminal)
    v0 = surface.rest_volume
    v_final = level.volume(x) * v0 / level.rest_volume
    target = goal.target_ratio * v0
    c = plan.constraints(terminal).values(x)
    if not (np.all(np.isfinite(x)) and np.isfinite(v_final)):
        raise IsochorError("The solve broke down: its numbers overflowed.")
    return SolveResult(
        frozen_copy(x),
        end.stats,
        terminal,
        v0,
        target,
        v_final,
        (v_final - target) / abs(v0),
        surface.springs.energy(x) / surface.size**2,
        plan.n_free,
        time.perf_counter() - plan.t0,
        end.converged and np.max(np.abs(c)) <= plan.options.tol_volume,
        "; ".join(filter(None, [end.message, f"preview on level {terminal}"])),
        float(np.atleast_1d(end.lam)[0]),
        end.sigma,
        target_error=(v_final - target) / abs(target),
        constraint_error=worst(c),
        held=tuple(int(r) for r in np.flatnonzero(plan.held)),
        held_face=plan.face,
        preview=True,
    )
