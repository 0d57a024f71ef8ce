"""The Constraints section as console lines and Markdown, and the section replaced in place
in an existing report (``python -m benchmarks --only constraints``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from benchmarks.constraints import (
    DRAG,
    HEADING,
    SHRINK,
    SQUASH,
    ConstraintRow,
    converged_text,
    measured,
)
from benchmarks.targets import Target, constraint_targets

#: a line of the generated report that follows the last section
PEAK_LINE = "Peak RSS of the benchmark process"


def section(
    rows: Sequence[ConstraintRow],
    notes: Sequence[str],
    command: str,
    env: Mapping[str, str],
    repeats: int,
    targets: Sequence[Target] | None = None,
) -> list[str]:
    """The section's Markdown lines: the table, its targets (computed from ``rows`` unless
    given) and the skipped cases."""
    lines = [HEADING, ""]
    lines.append(
        "Every case solved with and without one constraint on the same surface in the same "
        "run: each variant once untimed (it sets the levels and the constraint's own parts "
        "up; *first with* is that solve with the constraint), then the repeats alternate "
        "with / without; times are medians (min-max), *ratio* is with over without. "
        "Measured on the full mesh at the end: anchor: the largest move of the lattice layer "
        "farthest from the dragged corner over the drag, and the best-fit rigid motion "
        "(Kabsch) of the model's vertices; fold guard: the folded share of the samples "
        "(vertices and interior points, det J <= 0) and the smallest det J; per body: each "
        "body's (V - V_target) / V_target; centroid: the centre of mass's shift over the "
        "size; axis pins: how far the bottom layer's nodes slid sideways, and the spring "
        f"energy. Cases: anchor: a corner of the default lattice dragged outward by {DRAG:g} "
        "of the lattice size, nothing pinned; per body and axis pins: the top layer pushed "
        f"down by {SQUASH:g} of the lattice height, the bottom layer pinned; the cow shrink: "
        f"target volume ratio {SHRINK:g}, nothing pinned, default lattice.\n"
    )
    lines.append(
        f"Command: `{command}`; {env.get('date', '')}, {env.get('cpu', '')}; {repeats} repeats.\n"
    )
    lines.append(
        "| constraint | case | N_tri | with / without | T with ms | T without ms | ratio "
        "| first with ms | steps | measured with | measured without | converged |"
    )
    lines.append("|---|---|---:|---|---:|---:|---:|---:|---:|---|---|---|")
    for r in rows:
        on, off = r.labels
        lines.append(
            f"| {r.constraint} | {r.case} | {r.triangles} | {on} / {off} | {r.t_with.ms()} | "
            f"{r.t_without.ms()} | {r.ratio:.2f} | {1e3 * r.first_with:.0f} | "
            f"{r.with_.steps} / {r.without.steps} | {measured(r, r.with_)} | "
            f"{measured(r, r.without)} | {converged_text(r.with_)} / {converged_text(r.without)} |"
        )
    failed = [(r, lab, o) for r in rows for lab, o in zip(r.labels, (r.with_, r.without))]
    failed = [(r, lab, o) for r, lab, o in failed if not o.converged]
    if failed:
        lines.append("\nNot converged:\n")
        for r, lab, o in failed:
            lines.append(f"- {r.key}, {r.constraint} {lab}: {o.message}")
    ts = list(constraint_targets(rows) if targets is None else targets)
    lines.append("\n| target | measured | reason | |")
    lines.append("|---|---|---|---|")
    for t in ts:
        mark = {"MET": "MET", "MISSED": "**MISSED**"}.get(t.status, t.status)
        lines.append(f"| {t.name} | {t.measured} | {t.reason} | {mark} |")
    missed = [t for t in ts if t.met is False and t.why]
    if missed:
        lines.append("\nWhy missed, and what was tried:\n")
        for t in missed:
            lines.append(f"- *{t.name}*: {t.why}")
    for n in notes:
        lines.append(f"\n> {n}")
    lines.append("")
    return lines


def splice(text: str, block: str, markers: Sequence[str], heading: str = HEADING) -> str:
    """``text`` (a report) with its section ``heading`` replaced by ``block``; without one,
    ``block`` goes before the peak-memory line, else before the hand-written marker (the
    first of ``markers`` found), else at the end. The rest of the report is kept as it is."""
    block = block.rstrip("\n") + "\n\n"
    end_of_generated = len(text)
    for marker in markers:
        if marker in text:
            end_of_generated = text.index(marker)
            break
    head, tail = text[:end_of_generated], text[end_of_generated:]
    start = head.find(heading + "\n")
    if start < 0:
        at = head.find(PEAK_LINE)
        at = at if at >= 0 else len(head)
        if at and not head[:at].endswith("\n\n"):
            block = ("\n" if head[:at].endswith("\n") else "\n\n") + block
        return head[:at] + block + head[at:] + tail
    stop = len(head)
    for follower in ("\n## ", "\n" + PEAK_LINE):
        i = head.find(follower, start + len(heading))
        if 0 <= i < stop:
            stop = i + 1
    return head[:start] + block + head[stop:] + tail


def write_section(
    out: Path, lines: Sequence[str], markers: Sequence[str], heading: str = HEADING
) -> None:
    """Replace (or add) the section ``heading`` of the report at ``out``, keeping the rest;
    a new file gets the section and the hand-written marker (the first of ``markers``:
    :data:`benchmarks.report.KEEP_MARKER`, then the ones earlier versions wrote)."""
    from isochor.core.io.atomic import atomic_write_text

    try:
        text = out.read_text(encoding="utf-8")
    except OSError:
        text = f"# Benchmarks\n\n{markers[0]}\n"
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, splice(text, "\n".join(lines), markers, heading))
