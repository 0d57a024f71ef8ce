"""The public API as a user's type checker sees it: ``mypy --strict`` on a user's script.

``import isochor`` loads its API lazily (a module ``__getattr__``), which a type checker
reads as ``Any``; the ``TYPE_CHECKING`` imports in isochor/__init__.py give it the real
names. The package is found as an installed one (on the search path, with its ``py.typed``
marker), laid out by :mod:`tests.lint` as the wheel installs it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap

import pytest

from tests.lint import exceptions, lay_out

pytest.importorskip("mypy", reason="mypy is not installed (pip install -e '.[test]')")

#: API name -> what ``reveal_type`` must show (a fragment of it)
API = {
    "isochor.load": "def (path: str | pathlib.Path, **options: Any) -> isochor.core.api.Session",
    "isochor.deform": "def (mesh: Any, lattice:",
    "isochor.Session": "isochor.core.api.Session",
    "isochor.Deformed": "isochor.core.api.Deformed",
    "isochor.Scenario": "isochor.core.scenario.document.Scenario",
    "isochor.Move": "-> isochor.core.scenario.edits.Move",
    "isochor.IsochorError": "isochor.core.errors.IsochorError",
    # the result types a user gets back
    "isochor.deform(mesh)": "isochor.core.api.Deformed",
    "isochor.deform(mesh).result": "isochor.core.solve.records.SolveResult",
    "isochor.deform(mesh).report": "dict[str, Any]",
    "isochor.load('m.obj')": "isochor.core.api.Session",
    "isochor.load('m.obj').solve()": "isochor.core.solve.records.SolveResult",
    "isochor.load('m.obj').solve().nodes": "numpy.ndarray",
    "isochor.load('m.obj').scenario()": "isochor.core.scenario.document.Scenario",
}

#: a user's script that must pass ``mypy --strict`` as it is
USER_SCRIPT = """\
    import numpy as np
    import isochor

    def squash(path: str) -> float:
        session = isochor.load(path)
        session.move((0, 0, 0), (0.0, 0.5, 0.0))
        result = session.solve()
        nodes: np.ndarray = result.nodes
        return float(result.rel_volume_error) + float(nodes.sum())

    def once(mesh: object) -> bool:
        try:
            return isochor.deform(mesh, lattice=(3, 2, 2)).converged
        except isochor.IsochorError:
            return False
"""

#: a script every line of which is a type error, unless the API reaches mypy as Any
WRONG_SCRIPT = """\
    import isochor

    a: int = isochor.deform
    b: int = isochor.load
    c: int = isochor.Session
    d: int = isochor.load("m.obj").solve()
"""


def _mypy(script: str, tmp_path) -> subprocess.CompletedProcess:
    tree = lay_out(tmp_path / "site")
    (tmp_path / "user.py").write_text(textwrap.dedent(script), "utf-8")
    command = [sys.executable, "-m", "mypy", "--strict", "--no-error-summary", "user.py"]
    command += ["--cache-dir", str(tmp_path / "cache"), "--python-version", "3.11"]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    return subprocess.run(
        command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False
    )


@pytest.mark.slow
def test_the_api_names_reach_a_user_checker_typed(tmp_path):
    lines = ["import isochor", "mesh = object()"]
    lines += [f"reveal_type({expression})" for expression in API]
    out = _mypy("\n".join(lines) + "\n", tmp_path)
    revealed = re.findall(r'user\.py:(\d+): note: Revealed type is "(.*)"', out.stdout)
    assert len(revealed) == len(API), f"mypy revealed {len(revealed)} types:\n{out.stdout}"
    wrong = []
    for (_, shown), (expression, expected) in zip(revealed, API.items()):
        if shown == "Any" or expected not in shown:
            wrong.append(f"{expression}: {shown} (expected {expected}...)")
    assert not wrong, "API names a user's mypy sees wrongly:\n" + "\n".join(wrong)


@pytest.mark.slow
def test_a_user_script_passes_mypy_strict_and_a_wrong_one_fails(tmp_path):
    good = _mypy(USER_SCRIPT, tmp_path)
    assert good.returncode == 0, f"mypy --strict on a correct user script:\n{good.stdout}"
    bad = _mypy(WRONG_SCRIPT, tmp_path)
    errors = re.findall(r"user\.py:(\d+): error:", bad.stdout)
    assert [int(n) for n in errors] == [3, 4, 5, 6], (
        f"each wrong line must be an error (an Any passes silently):\n{bad.stdout}"
    )


def test_the_exceptions_list_holds_only_app_modules():
    """core has no exception: its errors are all fixed, and it stays so."""
    listed = exceptions()
    assert listed, "no exceptions list found in pyproject.toml (a [[tool.mypy.overrides]])"
    assert all(m.startswith("isochor.app.") for m in listed), listed
