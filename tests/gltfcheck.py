"""The Khronos glTF validator (npm ``gltf-validator``, run by node from ``tests/js``) as a
test helper: :func:`validate` gives each file's errors. Where node or the npm package is
missing the calling test skips saying why, except in CI (``CI`` set), where it fails:
``make venv`` installs the package (``npm ci`` in tests/js)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

JS = Path(__file__).parent / "js"


def _validator() -> list[str]:
    node = shutil.which("node")
    missing = (
        "node is not installed"
        if node is None
        else "the npm package gltf-validator is not installed (make venv: npm ci in tests/js)"
        if not (JS / "node_modules" / "gltf-validator").is_dir()
        else None
    )
    if missing:
        if os.environ.get("CI"):
            pytest.fail(f"the glTF validator is needed in CI: {missing}")
        pytest.skip(missing)
    return [node, str(JS / "validate.js")]


def validate(*paths: Path) -> dict[str, list[str]]:
    """``{file name: [error messages]}`` of the Khronos validator for each file (an empty
    list: 0 errors)."""
    return {name: line["messages"] for name, line in _reports(paths).items()}


def external(*paths: Path) -> dict[str, list[str]]:
    """``{file name: [uri]}``: the buffers and images each file keeps as separate files, as
    the validator's resource list gives them (an empty list: the file carries them all)."""
    return {
        name: [r.get("uri") for r in line.get("resources", []) if r.get("storage") == "external"]
        for name, line in _reports(paths).items()
    }


def _reports(paths: tuple[Path, ...]) -> dict[str, dict]:
    run = subprocess.run(
        [*_validator(), *map(str, paths)], capture_output=True, text=True, timeout=120
    )
    lines = [json.loads(line) for line in run.stdout.splitlines() if line.startswith("{")]
    assert len(lines) == len(paths), (run.returncode, run.stdout, run.stderr)
    out = {}
    for line in lines:
        assert line["errors"] == len(line["messages"]) or line["errors"] > 50, line
        out[Path(line["path"]).name] = line
    return out


def assert_valid(*paths: Path) -> None:
    """Every file validates with 0 errors."""
    problems = {name: m for name, m in validate(*paths).items() if m}
    assert not problems, problems
