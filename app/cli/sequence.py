"""``isochor solve SCENARIO --sequence PATTERN``: solve a scenario's keyframed poses
(:mod:`isochor.core.scenario.sequence`) and write one model file per frame (``frame_####.obj``,
through the round-trip export) or one animated GLB (``anim.glb``: the model's own mesh,
UVs, materials and skin, a morph target per frame and the animation of their weights). The
outputs and the report are checked before any work and written all or none, as for
``--out``."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from ...core.errors import IsochorError
from ...core.export import export_sequence
from ...core.io.atomic import check_outputs, write_outputs
from ...core.io.formats import GLTF_FORMATS, WRITE_FORMATS, listing
from ...core.report import sequence_report
from ...core.scenario.sequence import frame_path, solve_sequence
from ...core.solve.generators import run_to_end
from . import interrupts
from .console import EXIT_NOT_CONVERGED, EXIT_OK, PipeSafe
from .opening import open_session


def run_sequence(args, scenario, inputs: list, source: str) -> int:
    timeline = scenario.timeline
    if timeline is None:
        raise IsochorError(
            f'{source}: the scenario has no "poses", so there is no sequence to solve'
        )
    if args.out is not None or args.morph_target:
        raise IsochorError("--sequence writes the frames: give it without --out")
    pattern = str(args.sequence)
    suffix = Path(pattern).suffix.lower()
    one_glb = "#" not in Path(pattern).name and suffix in GLTF_FORMATS
    if suffix not in WRITE_FORMATS:
        raise IsochorError(f"{pattern}: --sequence must end in {listing(WRITE_FORMATS)}")
    if one_glb:
        if suffix != ".glb":
            raise IsochorError(f"{pattern}: one animated file is written as .glb")
        targets = [(Path(pattern), "--sequence")]
    else:
        if "#" in str(Path(pattern).parent):
            raise IsochorError(f"{pattern}: the #### of --sequence goes in the file name")
        targets = [(Path(frame_path(pattern, f)), "--sequence") for f in timeline.frames]
    report = [(args.report, "--report")] if args.report is not None else []
    outputs = check_outputs(targets + report, inputs)
    interrupts.check()
    t0 = time.perf_counter()
    session = open_session(scenario)  # loaded as for one solve; its problem holds the poses
    interrupts.check()
    problem = session.problem
    for w in session.warnings:
        print(f"isochor: warning: {w}", file=sys.stderr)
    console = PipeSafe(sys.stdout)
    if not args.quiet:
        print(f"{'frame':>6} {'key':>4} {'ms':>8} {'|dV|/V0':>9}", file=console, flush=True)

    def row(f) -> None:
        interrupts.check()  # a safe point at every frame
        if not args.quiet:
            err = abs(f.result.rel_volume_error)
            mark = "key" if f.key else ""
            line = f"{f.frame:>6} {mark:>4} {1000 * f.result.elapsed:>8.1f} {err:>9.2e}"
            print(line, file=console, flush=True)

    seq = run_to_end(solve_sequence(problem), row)

    if one_glb:
        nodes = [f.result.nodes for f in seq.frames]
        exported = export_sequence(problem, nodes, targets[0][0], timeline.rate)
        data, notes = [exported.data], list(exported.notes)
    else:
        exported = [
            session.export_bytes(p, nodes=f.result.nodes) for f, (p, _) in zip(seq.frames, targets)
        ]
        data = [e.data for e in exported]
        notes = list(dict.fromkeys(n for e in exported for n in e.notes))
    doc = sequence_report(problem, seq, source, time.perf_counter() - t0)
    doc["export_notes"] = notes
    files = list(zip(outputs, data))
    if report:
        files.append((outputs[-1], (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode()))
    interrupts.check()
    write_outputs(files, on_commit=interrupts.commit)  # a signal received so far stops it
    if (late := interrupts.finish()) is not None:
        return interrupts.answer_late(late, [o.path for o in outputs])
    for note in notes:
        shown = note if note.startswith("warning: ") else f"note: {note}"
        print(f"isochor: {shown}", file=sys.stderr)
    if not args.quiet:
        worst = max(abs(f.result.rel_volume_error) for f in seq.frames)
        print(
            f"{len(seq.frames)} frames ({len(seq.keys)} keys) in {seq.elapsed:.2f} s; "
            f"volume error at most {worst:.2e}; wrote {len(targets)} file(s)",
            file=console,
        )
        console.flush()
    if not seq.converged:
        print(f"isochor: the sequence did not converge: {doc['message']}", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    return EXIT_OK
