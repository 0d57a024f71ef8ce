"""Issue 28's campaign, run by hand: the hardening families of tests/mutate.py (files a
model reads named as outputs, glTF URIs out of the model's folder, duplicate keys, nodes
pinned and moved, models far from the origin, folds between the samples, float32 outputs,
signals at random moments) against ``python -m isochor solve``, each run checked.

    .venv/bin/python -m tests.campaign --cases 1500 --seed 2801 [--workers 2]

It counts, per family, what the issue asks to be zero: files destroyed (an existing file
changed by a run that was refused or interrupted, or by any run other than its outputs),
silent wrong results (exit 0 with a volume off the closed form beyond the tolerance, a
reported written volume that is not the file's, det J <= 0 inside a result called
converged), tracebacks and crashes (a traceback, exit 70, death by a signal), lost signals
(a signal sent before the outputs existed, and exit 0), and any other break of the
command line's contract (tests/test_contract.py). A small seeded subset runs in the suite
(tests/test_fuzz.py).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from tests.mutate import HardCase, hard_case
from tests.test_contract import ENV, Run, _catching, contract_problems, snapshot, temp_files

TIMEOUT = 180
TOLERANCE = 0.0005  # the scenarios' default volume tolerance


def materialise(case: HardCase, folder: Path) -> list[str]:
    """Write the case's files and links into ``folder``; its arguments, made absolute where
    they say ``@ABS@``."""
    for name, data in case.files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    (folder / "outside.bin").parent.mkdir(exist_ok=True)
    for kind, name, target in case.links:
        if kind == "folder":
            (folder / name).mkdir(exist_ok=True)
        elif kind == "symlink":
            os.symlink(target if target.startswith("/") else folder / target, folder / name)
        elif kind == "hardlink":
            os.link(folder / target, folder / name)
    return [a.replace("@ABS@", str(folder)) for a in case.args]


def _default_signals() -> None:
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def forked(args: list[str], folder: Path) -> Run:
    """``isochor ARGS`` in a child forked from this (single-threaded) process, where
    Isochor and its libraries are imported already: the command line's ``main`` as the
    console script runs it, its standard output and error in files beside the folder.
    (A fresh interpreter per case costs seconds of imports on a loaded machine; the signal
    family keeps fresh interpreters, whose start-up it must cover.)"""
    out_path = folder.parent / f"{folder.name}.stdout"
    err_path = folder.parent / f"{folder.name}.stderr"
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the child
        status = 70
        try:
            os.chdir(folder)
            for fd, path in ((1, out_path), (2, err_path)):
                os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
            from isochor.app.cli.main import main as cli_main

            status = cli_main(args)
        finally:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            os._exit(status if isinstance(status, int) else 70)
    deadline = t0 + TIMEOUT
    code = None
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        time.sleep(0.02)
    else:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    text = [p.read_text("utf-8", "replace") if p.exists() else "" for p in (out_path, err_path)]
    return Run(args, code, text[0], text[1], time.monotonic() - t0)


def run(case: HardCase, folder: Path, fork: bool = False) -> tuple[Run, bool]:
    """Run the case; with a signal, send it at its moment. Returns the run and whether
    the signal was sent while no output existed yet (so it had to stop the run)."""
    args = ["solve", *materialise(case, folder)]
    # a file outside the model's folder that a crafted URI might read
    (folder.parent / f"{folder.name}-outside.bin").write_bytes(b"secret")
    if fork and case.signal is None:
        return forked(args, folder), False
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [sys.executable, "-m", "isochor", *args],
        cwd=folder,
        env=ENV,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        # as from a terminal: the signals at their default (a campaign started with nohup
        # would hand SIGHUP down ignored, and an ignored signal stays ignored)
        preexec_fn=_default_signals,
    )
    early = False
    if case.signal is not None:
        # the moment counts from when the program catches signals (Isochor's first line):
        # before that the interpreter starts and no Python program can answer one
        sig, delay = case.signal
        ready = _catching(proc, 60)
        time.sleep(max(0.0, ready + delay - time.monotonic()))
        if proc.poll() is None:
            early = not any((folder / o).exists() for o in case.outputs)
            proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=TIMEOUT)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        code = None
    return (
        Run(
            args,
            code,
            out.decode("utf-8", "replace"),
            err.decode("utf-8", "replace"),
            time.monotonic() - t0,
        ),
        early,
    )


def check(
    case: HardCase, index: int, root: Path, fork: bool = False
) -> tuple[HardCase, int, Run, dict[str, list[str]]]:
    folder = root / f"case{index:05d}"
    folder.mkdir()
    problems: dict[str, list[str]] = {}
    # the files exist before the run: write them, take the snapshot, then run
    materialise(case, folder)
    before = snapshot(folder)
    shutil.rmtree(folder)
    folder.mkdir()
    result, early = run(case, folder, fork)
    after = snapshot(folder)

    def add(kind: str, text: str) -> None:
        problems.setdefault(kind, []).append(text)

    code = result.returncode
    if code is None:
        add("hang", f"no end within {TIMEOUT} s")
        return case, index, result, problems
    if "Traceback" in result.stderr or code == 70 or code < 0:
        add("traceback", f"exit {code}: {result.stderr[-400:]!r}")
    destroyed = [k for k in before if after.get(k) != before[k]]
    if destroyed:
        add("destroyed", f"files changed or removed: {destroyed}")
    if temp_files(after):
        add("contract", f"temporary files left: {temp_files(after)}")
    if case.expect == "refused":
        if code != 1 or case.words not in result.stderr:
            add("contract", f"expected a refusal naming {case.words!r}, got exit {code}")
        for p in contract_problems(result, before, after, []):
            add("contract", p)
    elif case.expect == "signal":
        _judge_signal(case, result, early, before, after, add)
    else:
        for p in contract_problems(result, before, after, case.outputs, folder=folder):
            add("contract", p)
        if code == 1 and case.words and case.words in result.stderr:
            pass  # refused honestly (too far for its size)
        elif code in (0, 3):
            report = json.loads((folder / "r.json").read_text())
            for text in _truth_problems(case, folder, report, result):
                add("wrong" if code == 0 else "contract", text)
        elif code != 1:
            add("contract", f"exit {code}")
    return case, index, result, problems


def _judge_signal(case, result, early, before, after, add) -> None:
    sig, _ = case.signal
    code = result.returncode
    lines = result.stderr.splitlines()
    if code == 128 + sig:
        if len(lines) != 1 or not lines[0].startswith("isochor: interrupted"):
            add("contract", f"interrupted with {len(lines)} lines: {lines[:3]!r}")
        written = "all of them were written" in result.stderr
        present = [o for o in case.outputs if o in after]
        if not written and present:
            add("destroyed", f"interrupted but outputs written: {present}")
        if written and len(present) != len(case.outputs):
            add("contract", "said all were written, but some are missing")
    elif code == 0:
        if early:
            add("lost", "a signal sent before any output existed, and exit 0")
        missing = [o for o in case.outputs if o not in after]
        if missing:
            add("contract", f"exit 0 without {missing}")
    else:
        add("contract", f"exit {code} for a signal {sig}: {result.stderr[-300:]!r}")


def _truth_problems(case: HardCase, folder: Path, report: dict, result: Run) -> list[str]:
    from isochor.core.volume import signed_volume

    out = []
    if case.family == "far":
        v0 = case.truth["volume"]
        if abs(report["volume_original"] / v0 - 1) > TOLERANCE:
            out.append(f"volume_original {report['volume_original']!r}, closed form {v0!r}")
        if report["converged"]:
            written = report.get("written") or {}
            if abs(written.get("volume", np.nan) / report["volume_target"] - 1) > TOLERANCE and (
                "warning" not in result.stderr
            ):
                out.append(f"written volume {written.get('volume')!r} off the target, no warning")
    elif case.family == "float32":
        import trimesh

        name = case.truth["out"]
        loaded = trimesh.load(str(folder / name), process=False, force="mesh")
        actual = signed_volume(np.asarray(loaded.vertices, float), np.asarray(loaded.faces))
        written = report["written"]["volume"]
        if abs(actual - written) > 1e-6 * abs(report["volume_original"]):
            out.append(f"the report's written volume {written!r} is not the file's {actual!r}")
        off = abs(actual - report["volume_target"]) / abs(report["volume_original"])
        if off > TOLERANCE and "warning" not in result.stderr:
            out.append(f"{name} holds {off:.2e} off the target, and no warning")
    elif case.family == "fold" and report["converged"]:
        from isochor.core.goal.folds import jacobian_determinants
        from isochor.core.scenario.document import Scenario
        from isochor.core.scenario.problem import build

        problem = build(Scenario.from_dict(case.truth["scenario"]))
        lattice = problem.surface.lattice
        nodes = np.asarray(report["nodes"], float)
        rng = np.random.default_rng(len(case.description))
        points = rng.uniform(-1, 1, (60_000, 3))
        points = points[np.linalg.norm(points, axis=1) < 0.9]  # inside the icosphere
        det = jacobian_determinants(lattice, points, nodes)
        if (det <= 0).any():
            out.append(f"converged, but det J <= 0 at {(det <= 0).mean():.2e} of points inside")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=1500)
    parser.add_argument("--seed", type=int, default=2801)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--keep", action="store_true", help="keep the case folders")
    parser.add_argument("--only", default="", help="comma-separated case indices")
    parser.add_argument(
        "--part", default="1/1", help="K/N: this process runs every N-th case from K-1"
    )
    parser.add_argument(
        "--fork",
        action="store_true",
        help="run the cases without a signal in children forked from this process (one "
        "case at a time per process: run several --part processes in parallel)",
    )
    args = parser.parse_args(argv)
    indices = [int(i) for i in args.only.split(",") if i] or list(range(args.cases))
    k, n = (int(x) for x in args.part.split("/"))
    indices = indices[k - 1 :: n]
    if args.fork:
        args.workers = 1  # fork from one thread only
        import scipy.ndimage  # noqa: F401  (imported once, before the children)
        import trimesh  # noqa: F401

        import isochor.app.cli.main
        import isochor.core.api  # noqa: F401
    root = Path(tempfile.mkdtemp(prefix="isochor-campaign-"))
    t0 = time.monotonic()
    counts: Counter = Counter()
    families: Counter = Counter()
    exits: Counter = Counter()
    failures = []
    with ThreadPoolExecutor(max_workers=args.workers) as pool:
        jobs = [pool.submit(check, hard_case(args.seed, i), i, root, args.fork) for i in indices]
        for n, job in enumerate(jobs, 1):
            case, index, result, problems = job.result()
            families[case.family] += 1
            exits[(case.family, result.returncode)] += 1
            for kind, texts in problems.items():
                counts[kind] += 1
                failures.append(
                    f"case {index} [{case.family}: {case.description}] {kind}: {texts[0]}"
                )
                print(failures[-1], flush=True)
            if n % 50 == 0:
                print(f"... {n} cases, {time.monotonic() - t0:.0f} s, {dict(counts)}", flush=True)
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)
    summary = {
        "command": f"python -m tests.campaign --cases {args.cases} --seed {args.seed} "
        f"--part {args.part}{' --fork' if args.fork else ''}",
        "cases": len(indices),
        "seconds": round(time.monotonic() - t0),
        "families": dict(families),
        "exits": {f"{f} {c}": n for (f, c), n in sorted(exits.items(), key=str)},
        "problems": {
            k: counts.get(k, 0)
            for k in ("destroyed", "wrong", "traceback", "lost", "hang", "contract")
        },
    }
    print(json.dumps(summary, indent=1))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
