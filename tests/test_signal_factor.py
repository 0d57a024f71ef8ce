"""A signal during the sparse factorisation of a big lattice is answered at once (issue
39: SIGTERM during a 64^3 solve went unanswered for 60 s inside SciPy's sparse LU).

Out of process: ``isochor solve`` on a 32x32x32 B-spline lattice (its curvature is factored
by SuperLU on the nodes, a single C call). The child is the real command, with the
factorisation wrapped to leave a marker file when it starts and to run several times in a
row, so that the signal surely arrives inside it. The answer must come within
:data:`ANSWER_BOUND`: the main thread looks for a signal every
:data:`isochor.app.cli.interrupts.POLL` seconds; the bound leaves room for the interpreter
under load, not for a factorisation (which takes longer than the bound here)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from isochor.app.cli import interrupts

ROOT = Path(__file__).resolve().parents[1]
#: seconds from the signal to the process's end: 200 polls, far below the wrapped
#: factorisation's time and far above a poll
ANSWER_BOUND = 200 * interrupts.POLL
#: the wrapped factorisation runs SuperLU this many times in a row
REPEAT = 20

CHILD = f"""
import sys
from isochor.app.cli import main
import isochor.core.solve.precondition as pc

mark, argv = sys.argv[1], sys.argv[2:]
factor = pc.Curvature._lu

def slow(self, a):
    open(mark, "w").close()
    for _ in range({REPEAT}):
        factor(self, a)
    open(mark + ".done", "w").close()

pc.Curvature._lu = slow
sys.argv = ["isochor", *argv]
main.entry()
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_during_the_sparse_factorisation_is_answered_at_once(tmp_path, sig):
    scene = tmp_path / "s.json"
    scene.write_text(
        json.dumps(
            {
                "model": {"builtin": "torus"},
                "lattice": {"nodes": [32, 32, 32], "basis": "bspline"},
                "moves": [{"node": [31, 16, 16], "by": [0.05, 0, 0]}],
                "pins": [{"node": [0, 16, 16], "axes": "xyz"}],
            }
        )
    )
    mark = tmp_path / "factor-started"
    out, report = tmp_path / "o.ply", tmp_path / "r.json"
    args = ["solve", str(scene), "--out", str(out), "--report", str(report), "-q"]
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(mark), *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 600
        while not mark.exists():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the factorisation never started"
            time.sleep(0.02)
        sent = time.monotonic()
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=ANSWER_BOUND)
        answered = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    print(f"{sig.name}: answered {answered:.2f} s after the signal, inside the factorisation")
    assert not Path(str(mark) + ".done").exists(), "the factorisation ended before the answer"
    assert proc.returncode == 128 + sig, stderr
    line = stderr.decode()
    assert line == f"isochor: interrupted ({sig.name}); nothing was written\n"
    assert not out.exists() and not report.exists()
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == ["factor-started", "s.json"], left  # no temporary file either
