"""The ``isochor`` command: the editor, a headless solve, the examples.

::

    isochor                                   open the editor
    isochor edit FILE [--screenshot out.png]  open a scenario or a model in the editor
    isochor solve SCENARIO.json [--out deformed.ply] [--report report.json]
    isochor solve --example NAME [--out ...] [--report ...]
    isochor examples                          list the built-in examples
    isochor --version

Exit status:

- 0 success;
- 1 a user error: a bad or missing file, an open mesh, a number out of range, an output
  that would replace an input or cannot be written (one line ``isochor: <message>``);
- 2 a usage error (one line, pointing at ``--help``);
- 3 the solve ran but did not reach the volume tolerance (the outputs are written,
  ``converged`` is false in the report);
- 70 an internal error: a bug (one line ``isochor: internal error: ...``; the traceback
  only when ``ISOCHOR_DEBUG`` is set);
- 128 + the signal when interrupted: 130 Ctrl-C, 143 SIGTERM, 129 SIGHUP (one line).

The outputs of ``solve`` are a set (:mod:`isochor.core.io.atomic`): checked before the solve,
then written all or none; a failure or an interrupt leaves no new file, no temporary
file, and every existing file as it was. Python's warnings never reach standard error
(set ``ISOCHOR_DEBUG`` to see them); the program's own are ``isochor: warning: ...`` lines.

Only ``edit`` (and no command) imports the GUI; everything else runs without Qt.
"""

from __future__ import annotations

# Signals first: a Ctrl-C or SIGTERM while the rest is imported is remembered and answered
# by main() with one line, never a traceback.
from . import interrupts

interrupts.install()

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import TYPE_CHECKING, Any, NoReturn, TextIO  # noqa: E402

from ... import __version__  # noqa: E402
from ...core import blas  # noqa: E402  (standard library only)
from ...core.errors import IsochorError  # noqa: E402
from ...core.goal.spec import GOAL_FIELDS, Goal  # noqa: E402  (light: no numpy)
from .console import (  # noqa: E402
    EXIT_ERROR,
    EXIT_INTERNAL,
    EXIT_NOT_CONVERGED,
    EXIT_OK,
    EXIT_USAGE,
    PipeSafe,
    ProgressLine,
    leave_now,
)

# One BLAS thread unless the user says otherwise: the lattice products are small and the
# solver shares the cores with the window. (Nothing imported above imports numpy, so the
# setting still counts.)
blas.at_start()

if TYPE_CHECKING:
    from ...core.api import Session
    from ...core.solve.records import SolveResult

#: set (to anything but "" or "0") for Python's warnings and the traceback of an internal error
DEBUG_VARIABLE = "ISOCHOR_DEBUG"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (the console script exits with it).

    Whatever happens, standard error gets one line per problem, each starting
    ``isochor:``, and no temporary file is left behind.
    """
    from ...core.io.atomic import discard_pending

    debug = os.environ.get(DEBUG_VARIABLE, "") not in ("", "0")
    try:
        interrupts.arm()
        with warnings.catch_warnings():
            if not debug:  # numpy's overflow warnings and the like: never on the user's screen
                warnings.simplefilter("ignore")
            args = _parser().parse_args(list(sys.argv[1:] if argv is None else argv))
            interrupts.check()
            status = args.run(args)
            interrupts.commit()  # a run that wrote nothing: a signal it received is answered
            return status
    except BaseException as exc:
        interrupts.hold()  # from here on a signal is only recorded: the way out says one thing
        return _status(exc, debug)
    finally:
        interrupts.hold()
        discard_pending()


def entry() -> NoReturn:
    """The ``isochor`` console script and ``python -m isochor``: :func:`main`, then exit
    deaf to signals. The run is over and its status decided; a signal now must neither
    change the status nor kill the interpreter while it shuts down (Python gives the
    signals back to their default, deadly, action then).

    While the compiled kernels are still loading in their background thread (numba and
    LLVM initialising; a short run, or one interrupted early) the process ends at once
    with its status, its output flushed: an interpreter shutting down under a thread
    inside a C extension's initialisation can crash (a SIGTERM once ended with a
    segmentation fault, exit -11)."""
    import threading

    status = main()
    interrupts.ignore()
    if threading.active_count() > 1:
        leave_now(status if isinstance(status, int) else EXIT_ERROR)
    sys.exit(status)


def _status(exc: BaseException, debug: bool) -> int:
    """The one line and the exit status for what ended the run."""
    if isinstance(exc, interrupts.Interrupted):
        return _fail(f"interrupted ({exc.name}); nothing was written", exc.status)
    # a signal's exception that came out as another, or a signal received before an error
    # ended the run: the run was interrupted (a signal is never lost)
    received = interrupts.state.raised or (
        None if interrupts.state.done else interrupts.state.pending
    )
    if received is not None and not isinstance(exc, SystemExit):
        signal = interrupts.Interrupted(received)
        return _fail(f"interrupted ({signal.name}); nothing was written", signal.status)
    if isinstance(exc, IsochorError):
        return _fail(exc)
    if isinstance(exc, KeyboardInterrupt):
        return _fail("interrupted (SIGINT); nothing was written", 128 + 2)
    if isinstance(exc, SystemExit):  # --help, --version, a usage error: argparse has spoken
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    if isinstance(exc, MemoryError):
        return _fail("out of memory: the model is too large for this computer")
    if isinstance(exc, OSError):  # a file that vanished or failed while being read
        where = f"{exc.filename}: " if exc.filename else ""
        return _fail(f"{where}{exc.strerror or exc}")
    if debug:
        traceback.print_exception(exc)
    hint = "" if debug else f" (set {DEBUG_VARIABLE}=1 for the details)"
    return _fail(f"internal error: {type(exc).__name__}: {exc}{hint}", EXIT_INTERNAL)


def _fail(message: Any, status: int = EXIT_ERROR) -> int:
    text = " ".join(str(message).replace("\0", " ").split())  # always one line
    print(f"isochor: {text}", file=sys.stderr)
    return status


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (exit 2), like every other message; an unknown
    option or command is named, with the nearest known one (``--ot``: did you mean
    ``--out``?), before argparse would take the option's value for a file name."""

    def error(self, message: str):
        choice = re.match(r"argument \S+: invalid choice: '(.*?)' \(choose from (.*)\)$", message)
        if choice:  # a mistyped command
            near = _nearest(choice[1], re.findall(r"'([^']*)'", choice[2]))
            message = f"unknown command {choice[1]!r}" + (
                f"; did you mean {near!r}?" if near else ""
            )
        _fail(f"{message} (see '{self.prog} --help')")
        raise SystemExit(EXIT_USAGE)

    def parse_known_args(self, args=None, namespace=None):
        # (called by argparse for each command's own parser too, with the words after it)
        words = list(sys.argv[1:] if args is None else args)
        self._check_options(words)
        return super().parse_known_args(words, namespace)

    def _check_options(self, words: list[str]) -> None:
        """An error for the first word that looks like an option and is none of this
        parser's (nor the start of one, as argparse accepts), up to its command's name."""
        options = [o for action in self._actions for o in action.option_strings]
        commands = {
            name
            for action in self._actions
            if action.nargs == argparse.PARSER  # the commands' action
            for name in action.choices
        }
        for word in words:
            if word == "--" or word in commands:
                return  # the rest is a command's (its parser checks its own)
            if not (word.startswith("--") or re.match(r"-[A-Za-z]", word)):
                continue
            name = word.split("=", 1)[0]
            if name in options or (len(name) > 2 and any(o.startswith(name) for o in options)):
                continue
            # compared without the dashes, which every option shares
            longs = {o[2:]: o for o in options if o.startswith("--")}
            near = longs.get(_nearest(name.lstrip("-"), list(longs)))
            self.error(f"unknown option {name}" + (f"; did you mean {near}?" if near else ""))


def _nearest(word: str, known: list[str]) -> str | None:
    """The known word nearest to ``word``, if any is near (difflib's ratio, 0.6)."""
    import difflib

    near = difflib.get_close_matches(word, known, n=1)
    return near[0] if near else None


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="isochor",
        description="Volume-preserving free-form deformation (Hirota, Maheshwari, Lin 1999). "
        "Without a command, opens the editor.",
    )
    parser.add_argument("--version", action="version", version=f"isochor {__version__}")
    parser.set_defaults(run=_edit, file=None, screenshot=None, timeout=None)
    sub = parser.add_subparsers(title="commands", metavar="COMMAND")

    edit = sub.add_parser("edit", help="open a scenario (.json) or a model in the editor")
    edit.add_argument("file", type=Path, help="scenario .json, or an OBJ/PLY/STL/OFF model")
    edit.add_argument(
        "--screenshot",
        type=Path,
        metavar="PNG",
        help="solve, render the window to this image and exit",
    )
    edit.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="SECONDS",
        help="with --screenshot: take the picture after this long even if the "
        "solve has not ended (default 300)",
    )
    edit.set_defaults(run=_edit)

    solve = sub.add_parser(
        "solve",
        help="solve a scenario without a window",
        description="Load, solve with the multi-level optimizer, print one "
        "row per level, write the deformed full-resolution mesh and a "
        "JSON report. Exit status 3: finished without reaching the "
        "volume tolerance (outputs written).",
    )
    what = solve.add_mutually_exclusive_group(required=True)
    what.add_argument("scenario", nargs="?", type=Path, help="the scenario .json")
    what.add_argument("--example", metavar="NAME", help="a built-in example (isochor examples)")
    solve.add_argument(
        "--out",
        type=Path,
        metavar="MESH",
        help="the deformed model: .obj, .ply, .stl, .off, .glb or .gltf; in the model's own "
        "format it keeps everything but the positions (UVs, polygons, normals transformed)",
    )
    solve.add_argument(
        "--morph-target",
        action="store_true",
        help="glTF model to glTF: keep the original mesh and add the deformation as a "
        "morph target (weight 1)",
    )
    solve.add_argument("--report", type=Path, metavar="JSON", help="the report (JSON)")
    solve.add_argument("--quiet", "-q", action="store_true", help="no per-level table")
    solve.add_argument(
        "--force",
        action="store_true",
        help="solve even when the estimate says it takes longer than the time limit "
        "(a solve whose memory does not fit is always refused)",
    )
    solve.add_argument(
        "--sequence",
        metavar="PATTERN",
        help="solve the scenario's poses: one file per frame (frame_####.obj) or one animated .glb",
    )
    solve.add_argument(
        "--basis",
        metavar="NAME",
        help="the lattice's basis, overriding the scenario's: bernstein (the paper's), or "
        "Blender's bspline, catmull-rom, cardinal, linear; one name or three comma-separated "
        "(one per axis)",
    )
    solve.add_argument(
        "--outside",
        action="store_true",
        help="Blender's lattice option 'Outside' (a local basis only): the inner nodes follow "
        "the outer ones, as Blender keeps them",
    )
    goal = solve.add_argument_group("what the solve holds (each overrides the scenario's)")
    for f in GOAL_FIELDS:  # one option per field of the goal, as it declares it
        if f.kind is bool:
            how: dict[str, Any] = {"action": argparse.BooleanOptionalAction, "default": None}
        elif f.choices:
            how = {"choices": f.choices}
        else:
            how = {"type": f.kind, "metavar": f.metavar}
        goal.add_argument(f.option, dest=f.name, help=f.help, **how)
    solve.set_defaults(run=_solve)

    examples = sub.add_parser("examples", help="list the built-in examples")
    examples.set_defaults(run=_examples)
    return parser


# -- edit ---------------------------------------------------------------------------------
def _edit(args: argparse.Namespace) -> int:
    interrupts.release()  # the editor keeps the default handling of signals
    try:
        from .launch import run_editor  # Qt is imported only for the editor
    except ImportError as exc:
        return _fail(f"the editor cannot start: {exc}")
    file = str(args.file) if args.file is not None else None
    shot = str(args.screenshot) if args.screenshot is not None else None
    return int(run_editor(file, shot, timeout=args.timeout) or 0)


# -- examples -----------------------------------------------------------------------------
def _examples(args: argparse.Namespace) -> int:
    from ...core.scenario.examples import EXAMPLES

    width = max(len(n) for n in EXAMPLES)
    for name, text in EXAMPLES.items():
        print(f"{name:<{width}}  {text}")
    return EXIT_OK


# -- solve --------------------------------------------------------------------------------
def _solve(args: argparse.Namespace) -> int:
    """``isochor solve``: a :class:`isochor.core.api.Session` on the scenario (load, solve,
    report, export), its outputs checked before any work and written as one set."""
    from ...core.io.atomic import check_outputs, write_outputs
    from ...core.io.formats import GLTF_FORMATS, WRITE_FORMATS, listing
    from ...core.scenario.document import Scenario
    from .opening import one_shot, open_session

    one_shot()  # before any model is made: building a shape evaluates volumes too
    if args.example is not None:
        from ...core.scenario.examples import example_scenario

        scenario, source = example_scenario(args.example), f"example {args.example}"
    else:
        scenario, source = Scenario.read(args.scenario), str(args.scenario)
    scenario = scenario.with_(goal=_goal(scenario.goal, args))
    if args.basis is not None:
        scenario = _basis(scenario, args.basis)
    if args.outside:
        scenario = _outside(scenario)
    # the scenario, the model and every file the model reads (mtllib, textures, buffers)
    inputs = scenario.inputs()
    interrupts.check()
    if args.sequence is not None:
        from .sequence import run_sequence

        return run_sequence(args, scenario, inputs, source)
    # every output is checked against the inputs and the others before any work
    wanted = [(p, role) for p, role in ((args.out, "--out"), (args.report, "--report")) if p]
    outputs = check_outputs(wanted, inputs)
    if args.out is not None and args.out.suffix.lower() not in WRITE_FORMATS:
        raise IsochorError(f"{args.out}: --out must end in {listing(WRITE_FORMATS)}")
    if args.morph_target and (
        args.out is None
        or args.out.suffix.lower() not in GLTF_FORMATS
        or "path" not in scenario.model
        or scenario.model_path().suffix.lower() not in GLTF_FORMATS
    ):
        raise IsochorError("--morph-target needs a glTF model and --out ending in .glb or .gltf")
    interrupts.check()
    t0 = time.perf_counter()
    line = ProgressLine(sys.stderr)  # on a terminal only, for a load or solve that takes long
    try:
        session = open_session(scenario, progress=line if line.on else None, force=args.force)
        line.clear()
        interrupts.check()
        for w in session.warnings:
            print(f"isochor: warning: {w}", file=sys.stderr)
        _screen(session, args.force)
        console = PipeSafe(sys.stdout)
        result = run_solve(session, None if args.quiet else console, line)
    finally:
        line.close()
    interrupts.check()
    total = time.perf_counter() - t0
    exported = None
    if args.out is not None:
        exported = session.export_bytes(args.out, morph_target=args.morph_target)
    interrupts.check()
    report = session.report_for(source, total)
    report["export_notes"] = list(exported.notes) if exported is not None else []
    if exported is not None and exported.volume is not None:
        # the volume the written file holds (its coordinates rounded as stored)
        report["written"] = {
            "file": str(args.out),
            "volume": exported.volume,
            "float32": exported.single,
            "volume_error": (exported.volume - result.volume_target) / abs(result.volume_original),
        }
    # everything is computed before anything is written: an error or a signal up to here
    # leaves no file; then the outputs are written as a set, all or none
    files = []
    for o in outputs:
        if o.role == "--out":
            files.append((o, exported.data))
        else:
            files.append((o, (json.dumps(report, indent=2, allow_nan=False) + "\n").encode()))
    # a signal received until the first output is renamed into place stops the run
    # (interrupts.commit); from then on the renames complete, and a signal received during
    # them is answered when they are done, saying so
    write_outputs(files, on_commit=interrupts.commit)
    if (late := interrupts.finish()) is not None:
        return interrupts.answer_late(late, [o.path for o in outputs])
    for note in exported.notes if exported is not None else ():
        print(f"isochor: {_note(note)}", file=sys.stderr)
    _summary(result, args, console, caps_words(session.problem.surface.full))
    if result.converged and not result.handles_met:  # the best fit, said as a warning
        print(f"isochor: warning: {result.message}", file=sys.stderr)
    if not result.converged:
        folded = result.folds is not None and result.folds.folded
        what = "" if folded else "the solve did not converge: "  # the message says "folded"
        print(f"isochor: {what}{result.message}", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    return EXIT_OK


def _screen(session: Session, force: bool) -> None:
    """Refuse a solve beyond this machine (:func:`isochor.core.estimate.screen`) in one
    line: its memory always, its time unless ``--force`` (then a warning, and the solve
    goes on with its progress)."""
    from ...core.estimate import screen

    estimate = screen(session)
    if estimate is None or estimate.fits():
        return
    if not estimate.memory_fits():
        raise IsochorError(estimate.message())
    if not force:
        raise IsochorError(f"{estimate.message()} (--force solves it anyway)")
    print(f"isochor: warning: {estimate.message()}; solving anyway (--force)", file=sys.stderr)


def _basis(scenario, text: str):
    """``scenario`` with the lattice basis of ``--basis`` (one name or three, comma-separated),
    checked as the scenario's ``lattice.basis`` is."""
    names = [n.strip() for n in text.split(",")] if "," in text else text.strip()
    try:
        return scenario.checked({"lattice_basis": names})
    except IsochorError as exc:
        message = str(exc).removeprefix("lattice.basis: ")
        raise IsochorError(f"--basis {text}: {message}") from None


def _outside(scenario):
    """``scenario`` with Blender's "Outside" option on, checked as ``lattice.outside`` is."""
    try:
        return scenario.checked({"lattice_outside": True})
    except IsochorError as exc:
        message = str(exc).removeprefix("lattice.outside: ")
        raise IsochorError(f"--outside: {message}") from None


def _goal(goal: Goal, args: argparse.Namespace) -> Goal:
    """``goal`` with the command line's goal options, each checked and named by its option
    (``--target 30``: the range, and ``--target``)."""
    changes = {
        f.name: f.check(getattr(args, f.name), f.option)
        for f in GOAL_FIELDS
        if getattr(args, f.name) is not None
    }
    return goal.with_(**changes) if changes else goal


def run_solve(
    session: Session, out: TextIO | None = None, line: ProgressLine | None = None
) -> SolveResult:
    """Drive the session's solve (:meth:`isochor.core.api.Session.steps`) to its end,
    printing one row per level (the progress ``line`` wiped before each).

    A signal (Ctrl-C, SIGTERM, SIGHUP) is answered within
    :data:`~isochor.app.cli.interrupts.POLL` seconds, even inside a long C call: the solve
    runs on a worker thread (:func:`isochor.app.cli.interrupts.run_answering`), which
    stops (the generator closed) at its next step, and the interrupt is raised here.

    Returns
    -------
    isochor.core.solve.records.SolveResult
    """
    from ...core.solve.generators import run_to_end

    run = session.steps()
    if out is not None:
        if line is not None:
            line.clear()
        print(
            f"{'level':>5} {'triangles':>10} {'max dX %':>9} {'steps':>6} {'ms':>8} {'|dV|/V0':>9}",
            file=out,
            flush=True,
        )
    last = [0.0]

    def row(p) -> None:
        interrupts.check()  # a safe point at every step: a signal stops the solve here
        if p.level_done and out is not None:
            if line is not None:
                line.clear()
            change = 100 * p.max_node_change if p.max_node_change is not None else 0.0
            print(
                f"{p.level:>5} {p.triangles:>10} {change:>9.3f} {p.step:>6} "
                f"{1000 * (p.elapsed - last[0]):>8.1f} {abs(p.rel_volume_error):>9.2e}",
                file=out,
                flush=True,
            )
        if p.level_done:
            last[0] = p.elapsed

    # on a worker thread: the main thread answers a signal even while one step runs long
    # inside a C call (a big lattice's sparse factorisation)
    return interrupts.run_answering(lambda: run_to_end(run, row))


def caps_words(mesh) -> str:
    """'' for a closed model; for an open one, how many holes were capped and how large."""
    from ...core.io.caps import summary  # (numpy: after the solve, imported already)

    caps = summary(mesh)
    if not caps.holes:
        return ""
    return f" (capped: {caps.holes} hole(s), {100 * caps.ratio:.2g}% of the surface's area)"


def _note(note: str) -> str:
    """An export's note as its line: ``warning: ...`` ones stay warnings."""
    return note if note.startswith("warning: ") else f"note: {note}"


def _summary(result: SolveResult, args: argparse.Namespace, out: PipeSafe, caps: str) -> None:
    if args.quiet:
        return
    print(
        f"volume{caps} {result.volume_original:.6g} -> {result.volume_final:.6g} "
        f"(target {result.volume_target:.6g}, error {result.rel_volume_error:+.2e}); "
        f"{result.free_nodes} free nodes; {result.elapsed:.2f} s",
        file=out,
    )
    for path in (args.out, args.report):
        if path is not None:
            print(f"wrote {path}", file=out)
    out.flush()


if __name__ == "__main__":
    sys.exit(main())
