"""The package laid out as it installs, for the tools that read files: mypy and import-linter.

setuptools installs the top-level ``core/``, ``app/`` and ``assets/`` folders as
``isochor.core``, ``isochor.app`` and ``isochor.assets`` (``package-dir`` in
pyproject.toml). An editable install reaches them through an import hook, which neither
mypy nor import-linter's graph builder follows, so both run on a copy of the sources in
that layout, ``build/lint/isochor/``, refreshed file by file (a file keeps its time stamp, so
mypy's cache stays valid). Their messages name the source files (``core/lattice.py``), not
the copy.

``python -m tests.lint`` runs both and exits non-zero when either fails:

- mypy with ``[tool.mypy]`` of pyproject.toml: no error anywhere but in the modules of the
  exceptions list (the override with ``ignore_errors``), which holds only app modules, only
  ones of :data:`EXCEPTIONS_AT_START` and only modules that still have errors (a module that
  becomes clean leaves the list);
- import-linter with ``[tool.importlinter]`` of pyproject.toml (the layers).

``python -m tests.lint mypy`` or ``... imports`` runs one of them.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREE = ROOT / "build" / "lint"
#: installed name -> source folder, as ``[tool.setuptools] package-dir``
PACKAGE_DIRS = {"isochor": "isochor", "isochor.core": "core", "isochor.app": "app"}
PACKAGE_DIRS["isochor.assets"] = "assets"

#: the modules the exceptions list held when it was made: it may only lose members
EXCEPTIONS_AT_START = frozenset(
    {
        "isochor.app.cli.interrupts",
        "isochor.app.cli.launch",
        "isochor.app.cli.main",
        "isochor.app.editor.recovery",
        "isochor.app.editor.state",
        "isochor.app.editor.timeline",
        "isochor.app.session.controller",
        "isochor.app.session.framesolver",
        "isochor.app.session.worker",
        "isochor.app.view.camera",
        "isochor.app.view.composer",
        "isochor.app.view.meshprep",
        "isochor.app.view.modelview",
        "isochor.app.view.overlays",
        "isochor.app.view.picking",
        "isochor.app.view.scene",
        "isochor.app.view.viewport",
        "isochor.app.window.files",
        "isochor.app.window.handletools",
        "isochor.app.window.loading",
        "isochor.app.window.mainwindow",
        "isochor.app.window.panel",
    }
)

_MESSAGE = re.compile(r"^(isochor/[^:]+\.py)(:\d+)")


def _sources() -> dict[Path, Path]:
    """Path in the tree -> source file, for every file the wheel would hold that a tool
    reads (the modules and the PEP 561 marker)."""
    files = {}
    for package, folder in PACKAGE_DIRS.items():
        base = Path(*package.split("."))
        source = ROOT / folder
        names = ["py.typed"] if package == "isochor" else []
        for path in source.rglob("*.py"):
            relative = path.relative_to(source)
            # the package root's own files only: its subpackages come from their folders
            if "__pycache__" in relative.parts or (package == "isochor" and relative.parent.parts):
                continue
            files[base / relative] = path
        for name in names:
            files[base / name] = source / name
    return files


def lay_out(tree: Path = TREE) -> Path:
    """Copy the sources into ``tree`` in the installed layout (only what changed; files no
    longer in the sources are removed). Returns ``tree``."""
    wanted = _sources()
    for relative, source in wanted.items():
        target = tree / relative
        stat = source.stat()
        if target.exists():
            seen = target.stat()
            if (seen.st_mtime_ns, seen.st_size) == (stat.st_mtime_ns, stat.st_size):
                continue
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, target)
    if (tree / "isochor").exists():
        for path in sorted((tree / "isochor").rglob("*"), reverse=True):
            if path.is_file() and path.relative_to(tree) not in wanted:
                path.unlink()
            elif path.is_dir() and not any(path.iterdir()):
                path.rmdir()
    return tree


def source_name(line: str) -> str:
    """A tool's message about a file of the tree, naming the source file instead."""
    match = _MESSAGE.match(line)
    if not match:
        return line
    parts = Path(match.group(1)).parts
    for package, folder in sorted(PACKAGE_DIRS.items(), key=lambda p: -len(p[0])):
        depth = package.count(".") + 1
        if tuple(parts[:depth]) == tuple(package.split(".")) and len(parts) > depth:
            return str(Path(folder, *parts[depth:])) + line[len(match.group(1)) :]
    return line


def _module(path: str) -> str:
    """``isochor/app/view/scene.py`` -> ``isochor.app.view.scene``."""
    name = path.removesuffix(".py").replace("/", ".")
    return name.removesuffix(".__init__")


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))


def exceptions(config: dict | None = None) -> list[str]:
    """The modules whose mypy errors are let pass (the override with ``ignore_errors``)."""
    mypy = (config or _pyproject())["tool"]["mypy"]
    listed = [o for o in mypy.get("overrides", ()) if o.get("ignore_errors")]
    return [m for o in listed for m in _modules(o)]


def _modules(override: dict) -> list[str]:
    """The ``module`` of a mypy override: one name or a list."""
    modules = override["module"]
    return [modules] if isinstance(modules, str) else list(modules)


def _ini_value(value: object) -> str:
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, list):
        return ", ".join(str(v) for v in value)
    return str(value)


def _config_without_exceptions(path: Path) -> Path:
    """pyproject's mypy configuration as a mypy.ini, minus the exceptions list (so that mypy
    reports every module, and the list is applied here)."""
    mypy = dict(_pyproject()["tool"]["mypy"])
    overrides = [o for o in mypy.pop("overrides", ()) if not o.get("ignore_errors")]
    lines = ["[mypy]", *(f"{k} = {_ini_value(v)}" for k, v in mypy.items())]
    for override in overrides:
        lines.append(f"[mypy-{','.join(_modules(override))}]")
        lines += [f"{k} = {_ini_value(v)}" for k, v in override.items() if k != "module"]
    path.write_text("\n".join(lines) + "\n", "utf-8")
    return path


def mypy() -> int:
    """mypy over the laid-out package; 0 when it passes with the exceptions list applied."""
    tree = lay_out()
    config = _config_without_exceptions(TREE / "mypy.ini")
    command = [sys.executable, "-m", "mypy", "--config-file", str(config), "-p", "isochor"]
    command += ["--cache-dir", str(ROOT / ".mypy_cache"), "--no-error-summary"]
    out = subprocess.run(command, cwd=tree, capture_output=True, text=True, check=False)
    if out.returncode not in (0, 1):  # 2: mypy itself failed
        print(out.stdout + out.stderr, end="")
        return out.returncode
    listed = exceptions()
    failed = False
    errors: dict[str, int] = {}
    shown = []
    for line in out.stdout.splitlines():
        match = _MESSAGE.match(line)
        module = _module(match.group(1)) if match else None
        if module and ": error:" in line:
            errors[module] = errors.get(module, 0) + 1
        if module not in listed:
            shown.append(source_name(line))
    unlisted = {m: n for m, n in errors.items() if m not in listed}
    if unlisted:
        failed = True
        print("\n".join(shown))
    problems = []
    for module in listed:
        if not module.startswith("isochor.app."):
            problems.append(f"{module}: only app modules may be in the exceptions list")
        elif module not in EXCEPTIONS_AT_START:
            problems.append(f"{module}: new in the exceptions list (it may only shrink)")
        elif module not in errors:
            problems.append(f"{module}: has no mypy error: remove it from the exceptions list")
    if problems:
        failed = True
        print("pyproject.toml [[tool.mypy.overrides]] ignore_errors:\n  " + "\n  ".join(problems))
    total = sum(errors.values())
    passed = total - sum(unlisted.values())
    print(
        f"mypy: {sum(unlisted.values())} errors outside the exceptions list, "
        f"{passed} in its {len(listed)} modules; {'FAILED' if failed else 'passed'}"
    )
    return 1 if failed else 0


def imports() -> int:
    """import-linter's contracts over the laid-out package; 0 when all are kept."""
    tree = lay_out()
    env = {**os.environ, "PYTHONPATH": str(tree)}
    command = [str(Path(sys.executable).with_name("lint-imports"))]
    command += [str(ROOT / "pyproject.toml"), "--no-cache"]
    out = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True, check=False)
    report = out.stdout + out.stderr
    start = report.find("Contracts\n")
    print(report[start:].strip() if start >= 0 and out.returncode == 0 else report.strip())
    return out.returncode


def main(argv: list[str]) -> int:
    tools = {"mypy": mypy, "imports": imports}
    chosen = argv or list(tools)
    unknown = [t for t in chosen if t not in tools]
    if unknown:
        print(f"unknown tool {unknown[0]!r}: choose from {', '.join(tools)}")
        return 2
    return max(tools[t]() for t in chosen)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
