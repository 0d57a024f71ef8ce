"""The house's structure and packaging, checked headless.

- the import graph of ``core/`` and ``app/``, read with :mod:`ast` (nothing is imported):
  no cycles, arrows point down only (app -> core, and down :data:`CORE_LAYERS` and
  :data:`APP_LAYERS` inside each), core imports no GUI, VTK or plotting library, no module
  uses the old top-level ``core.``/``app.`` names, no package folder is too big to read at
  a glance, and every package's ``__init__`` docstring maps each of its modules;
- a fresh interpreter outside the repository: ``import isochor`` is cheap and has the version
  of ``isochor/__init__.py``, and importing all of ``isochor.core`` imports no Qt, VTK or pyvista;
- the command line out of process: ``isochor --version`` and ``python -m isochor --version``;
- the wheel built from the source files: one import name, the right files, the scripts.
"""

from __future__ import annotations

import ast
import configparser
import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
from collections import deque
from dataclasses import dataclass
from functools import cache
from itertools import pairwise
from pathlib import Path

import pytest

from tests.fresh import GUI_LIBRARIES

ROOT = Path(__file__).resolve().parents[1]

#: import name -> source folder (``[tool.setuptools] package-dir`` in pyproject.toml)
PACKAGE_DIRS = {
    "isochor": "isochor",
    "isochor.core": "core",
    "isochor.app": "app",
    "isochor.assets": "assets",
}
#: the folders whose import graph is checked, lowest layer first
LAYERS = ("core", "app")
#: top-level names of the old layout (absolute ``import core.x``), now ``isochor.core.x``
OLD_TOP_LEVEL = ("core", "app", "assets")
#: source folders that are not shipped: nothing shipped may import them
UNSHIPPED = ("benchmarks", "tests")
#: the layers inside each folder, lowest first: a module imports only from lower layers or
#: from its own subpackage. A layer is a set of siblings that do not import each other: a
#: subpackage (``io``) or a module at the folder's top (``lattice``). The tables are
#: import-linter's layers contracts in pyproject.toml (``make lint`` runs import-linter on
#: them too); they are read here so that they are written once.


def _contract_layers(container: str) -> tuple[set[str], ...]:
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))["tool"]
    for contract in contracts["importlinter"]["contracts"]:
        if contract.get("containers") == [container]:
            layers = [{n.strip() for n in layer.split("|")} for layer in contract["layers"]]
            return tuple(reversed(layers))
    raise AssertionError(f"pyproject.toml has no layers contract for {container}")


CORE_LAYERS = _contract_layers("isochor.core")
APP_LAYERS = _contract_layers("isochor.app")
#: "small enough to read at a glance": modules at the top of one package folder
MAX_PACKAGE_MODULES = 20

#: the child processes must find the installed package, not a PYTHONPATH into the source
CHILD_ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
CHILD_TIMEOUT = 120


# --- reading the sources --------------------------------------------------------------------


@dataclass(frozen=True)
class Import:
    """One import statement (or ``importlib.import_module("...")`` call) of a source file."""

    path: Path
    line: int
    target: str | None  # the absolute dotted name it reaches; None: beyond the top package
    written: str  # as written, for messages
    absolute: bool  # level 0 (no leading dots)

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


@cache
def _version() -> str:
    """``__version__`` of isochor/__init__.py, read without importing it."""
    tree = ast.parse((ROOT / "isochor" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__version__" for t in node.targets
        ):
            return ast.literal_eval(node.value)
    raise AssertionError("isochor/__init__.py assigns no __version__")


@cache
def _source_modules() -> dict[str, Path]:
    """Full module name (``isochor.core.lattice``) -> its file, for every installed package."""
    modules = {}
    for package, folder in PACKAGE_DIRS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join([package, *parts])] = path
    return modules


def _project_name(name: str) -> str | None:
    """An absolute dotted name -> the project's own name for it (``core.lattice``,
    ``app.cli.main``, ``isochor`` for the package root, ``benchmarks``, ``tests``), or None
    for a name outside the project."""
    top, _, rest = name.partition(".")
    if top == "isochor":
        if rest.partition(".")[0] in OLD_TOP_LEVEL:
            return rest
        return name
    if top in OLD_TOP_LEVEL:  # the old layout: names the same folder
        return name
    if top in UNSHIPPED:
        return top
    return None


@cache
def _project_modules() -> frozenset[str]:
    return frozenset(_project_name(m) for m in _source_modules())


def _is_module(name: str) -> bool:
    project = _project_name(name)
    return project is not None and project in _project_modules()


def _module_name(path: Path) -> tuple[str, bool]:
    """The full module name of a source file, and whether it is a package ``__init__``."""
    for name, p in _source_modules().items():
        if p == path:
            return name, path.name == "__init__.py"
    raise AssertionError(f"{path} is in no package of PACKAGE_DIRS")


@cache
def _imports(path: Path) -> tuple[Import, ...]:
    """Every import of a file, at any place in it (functions, ``if TYPE_CHECKING:``, ``try:``),
    resolved to absolute names; ``from X import y`` reaches ``X.y`` when that is a module of
    the project, else ``X``."""
    module, is_package = _module_name(path)
    package = module if is_package else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.append(Import(path, node.lineno, alias.name, f"import {alias.name}", True))
        elif isinstance(node, ast.ImportFrom):
            dots = "." * node.level
            names = ", ".join(a.name for a in node.names)
            written = f"from {dots}{node.module or ''} import {names}"
            if node.level == 0:
                base = node.module
            else:
                parts = package.split(".")
                if node.level - 1 >= len(parts):
                    found.append(Import(path, node.lineno, None, written, False))
                    continue
                parts = parts[: len(parts) - (node.level - 1)]
                base = ".".join(parts + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                target = sub if alias.name != "*" and _is_module(sub) else base
                found.append(Import(path, node.lineno, target, written, node.level == 0))
        elif (
            isinstance(node, ast.Call)
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
            and not node.args[0].value.startswith(".")
            and (
                (isinstance(node.func, ast.Name) and node.func.id == "__import__")
                or (isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
            )
        ):
            name = node.args[0].value
            found.append(Import(path, node.lineno, name, f"import_module({name!r})", True))
    return tuple(sorted(found, key=lambda i: i.line))


def _layer_files(layer: str) -> dict[str, Path]:
    """Project module name (``core``, ``core.lattice``) -> file, for one folder."""
    package = f"isochor.{layer}"
    return {
        _project_name(name): path
        for name, path in _source_modules().items()
        if name == package or name.startswith(package + ".")
    }


def _all_files() -> list[Path]:
    return [path for layer in LAYERS for path in _layer_files(layer).values()]


# --- the import graph ------------------------------------------------------------------------


def _graph(layer: str) -> dict[str, dict[str, Import]]:
    """module -> {module of the same layer it imports -> the first such import}."""
    files = _layer_files(layer)
    graph: dict[str, dict[str, Import]] = {m: {} for m in files}
    for module, path in files.items():
        for imp in _imports(path):
            target = _project_name(imp.target) if imp.target else None
            if target in files and target != module:
                graph[module].setdefault(target, imp)
    return graph


def _strongly_connected(graph: dict[str, dict[str, Import]]) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def _describe_cycle(graph: dict[str, dict[str, Import]], component: list[str]) -> str:
    """The shortest cycle through the first module of a component, with each arrow's line."""
    start, members = component[0], set(component)
    previous: dict[str, str] = {}
    queue = deque([start])
    while queue:
        v = queue.popleft()
        for w in sorted(graph[v]):
            if w not in members:
                continue
            if w == start:
                path = [v]
                while path[-1] != start:
                    path.append(previous[path[-1]])
                path.reverse()
                path.append(start)
                arrows = [
                    f"    {a} -> {b}  ({graph[a][b].where}: {graph[a][b].written})"
                    for a, b in pairwise(path)
                ]
                return " -> ".join(path) + "\n" + "\n".join(arrows)
            if w not in previous:
                previous[w] = v
                queue.append(w)
    raise AssertionError(f"no cycle through {start} in {component}")


@pytest.mark.parametrize("layer", LAYERS)
def test_no_import_cycles(layer):
    files = _layer_files(layer)
    assert len(files) > 1, f"no modules found in {layer}/"
    graph = _graph(layer)
    cycles = [_describe_cycle(graph, c) for c in _strongly_connected(graph)]
    assert not cycles, f"import cycles in {layer}/:\n" + "\n".join(cycles)


def test_arrows_point_down_only():
    """core never imports app, the package root, benchmarks or tests; app never imports the
    unshipped benchmarks or tests."""
    bad = []
    for path in _layer_files("core").values():
        for imp in _imports(path):
            target = _project_name(imp.target) if imp.target else None
            if target is None:
                continue
            if target.partition(".")[0] in ("app", *UNSHIPPED) or target.startswith("isochor"):
                bad.append(f"{imp.where}: {imp.written}  (-> {target})")
    for path in _layer_files("app").values():
        for imp in _imports(path):
            target = _project_name(imp.target) if imp.target else None
            if target in UNSHIPPED:
                bad.append(f"{imp.where}: {imp.written}  (-> {target}, not shipped)")
    assert not bad, "imports against the layering (app -> core only):\n" + "\n".join(bad)


def test_core_imports_no_gui_vtk_or_plotting():
    bad = [
        f"{imp.where}: {imp.written}"
        for path in _layer_files("core").values()
        for imp in _imports(path)
        if imp.absolute and imp.target and imp.target.partition(".")[0] in GUI_LIBRARIES
    ]
    assert not bad, "core/ imports a GUI, VTK or plotting library:\n" + "\n".join(bad)


def test_no_old_layout_absolute_imports():
    """``import core.x`` / ``from app.y import z`` worked only with the repository on sys.path;
    the installed names are relative imports or ``isochor.core``/``isochor.app``."""
    bad = [
        f"{imp.where}: {imp.written}"
        for path in _all_files()
        for imp in _imports(path)
        if imp.absolute and imp.target and imp.target.partition(".")[0] in OLD_TOP_LEVEL
    ]
    assert not bad, "absolute imports of the old layout (use relative or isochor.*):\n" + (
        "\n".join(bad)
    )


def test_project_imports_name_existing_modules():
    """Every relative or ``isochor.*`` import names a package or module that exists (a
    renamed or deleted module leaves no stale import behind)."""
    bad = []
    for path in _all_files():
        for imp in _imports(path):
            if imp.target is None:
                bad.append(f"{imp.where}: {imp.written}  (beyond the top-level package)")
            elif (imp.target.partition(".")[0] == "isochor" or not imp.absolute) and not (
                _is_module(imp.target)
            ):
                bad.append(f"{imp.where}: {imp.written}  (no module {imp.target})")
    assert not bad, "imports of modules that do not exist:\n" + "\n".join(bad)


@pytest.mark.parametrize(("layer", "order"), [("core", CORE_LAYERS), ("app", APP_LAYERS)])
def test_layers_inside_each_folder_point_down(layer, order):
    rank = {name: i for i, names in enumerate(order) for name in names}
    files = _layer_files(layer)
    tops = {m.split(".")[1] for m in files if "." in m}
    assert tops == set(rank), f"{layer}/: modules and subpackages not in the layer table: " + (
        f"{sorted(tops ^ set(rank))}"
    )
    bad = []
    for module, path in files.items():
        if "." not in module:
            continue
        here = module.split(".")[1]
        for imp in _imports(path):
            target = _project_name(imp.target) if imp.target else None
            if not target or target not in files or "." not in target:
                continue
            there = target.split(".")[1]
            if there != here and rank[there] >= rank[here]:
                bad.append(f"{imp.where}: {imp.written}  ({here} -> {there})")
    assert not bad, f"imports against {layer}/'s layers:\n" + "\n".join(bad)


def _packages() -> dict[str, Path]:
    return {
        name: path.parent for name, path in _source_modules().items() if path.name == "__init__.py"
    }


def test_package_folders_are_small_enough_to_read_at_a_glance():
    over = {}
    for name, folder in _packages().items():
        modules = [p for p in folder.glob("*.py") if p.name not in ("__init__.py", "__main__.py")]
        if len(modules) > MAX_PACKAGE_MODULES:
            over[name] = len(modules)
    assert not over, f"package folders over {MAX_PACKAGE_MODULES} modules: {over}"


def test_every_package_docstring_maps_its_modules():
    """Each package's ``__init__`` docstring is its map: it names every module and
    subpackage beside it (as ``.name``, ``name/`` or ``name.py``)."""
    missing = []
    for name, folder in _packages().items():
        doc = ast.get_docstring(ast.parse((folder / "__init__.py").read_text("utf-8"))) or ""
        if name in ("isochor", "isochor.assets"):
            continue
        parts = [p.stem for p in folder.glob("*.py") if p.stem not in ("__init__", "__main__")]
        parts += [p.name for p in folder.iterdir() if (p / "__init__.py").exists()]
        for part in parts:
            if not any(f"{part}{end}" in doc for end in ("`", "/", ".py", " ")):
                missing.append(f"{name}: {part}")
    assert not missing, "package maps that leave out a module:\n" + "\n".join(missing)


# --- a fresh interpreter, outside the repository ---------------------------------------------


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        args,
        cwd=cwd,
        env=CHILD_ENV,
        capture_output=True,
        text=True,
        timeout=CHILD_TIMEOUT,
        check=False,
    )


def _python(code: str, cwd: Path) -> str:
    out = _run([sys.executable, "-c", code], cwd)
    assert out.returncode == 0, f"child python failed:\n{out.stdout}\n{out.stderr}"
    return out.stdout


def test_import_isochor_is_cheap_and_has_the_version(tmp_path):
    code = (
        "import sys\n"
        "import isochor\n"
        "print(isochor.__version__)\n"
        "print(isochor.__file__)\n"
        "print(','.join(sorted(n for n in sys.modules"
        " if n.partition('.')[0] in ('numpy', 'PySide6'))))\n"
    )
    version, where, heavy = (_python(code, tmp_path).splitlines() + ["", "", ""])[:3]
    assert version == _version(), f"isochor imported from {where} has version {version!r}"
    assert heavy == "", f"import isochor imported: {heavy}"


def test_importing_all_of_core_imports_no_gui_or_vtk(tmp_path):
    modules = sorted(m for m in _source_modules() if m.partition(".")[2].startswith("core"))
    expected = {"lattice", "volume", "springs", "solve.solver", "solve.multilevel"}
    assert {f"isochor.core.{m}" for m in expected} <= set(modules)
    code = (
        "import importlib, sys\n"
        f"for m in {modules!r}: importlib.import_module(m)\n"
        f"bad = sorted(n for n in sys.modules if n.partition('.')[0] in {set(GUI_LIBRARIES)!r})\n"
        "print(','.join(bad))\n"
    )
    bad = _python(code, tmp_path).strip()
    assert bad == "", f"importing isochor.core.* imported: {bad}"


# --- the command line ------------------------------------------------------------------------


def test_console_script_version(tmp_path):
    bindir = Path(sys.executable).parent
    script = bindir / ("isochor.exe" if os.name == "nt" else "isochor")
    if not script.exists():
        pytest.skip(f"no isochor script in {bindir}: the package is not installed in this venv")
    out = _run([str(script), "--version"], tmp_path)
    assert (out.returncode, out.stdout.strip()) == (0, f"isochor {_version()}"), out.stderr


def test_python_m_isochor_version(tmp_path):
    out = _run([sys.executable, "-m", "isochor", "--version"], tmp_path)
    assert (out.returncode, out.stdout.strip()) == (0, f"isochor {_version()}"), out.stderr


# --- the wheel -------------------------------------------------------------------------------

_IGNORED = ("build", "dist", "__pycache__", "*.egg-info", ".venv", "venv", ".git", ".*_cache")
_OFFLINE = (
    "Failed to establish a new connection",
    "Temporary failure in name resolution",
    "Network is unreachable",
    "No matching distribution found",
    "Could not find a version that satisfies",
    "ProxyError",
    "ConnectTimeout",
    "Read timed out",
)


def _copy_sources(dest: Path) -> None:
    """The files git would commit (tracked, or new and not ignored); without git, the tree
    minus the virtual environment, build products and caches."""
    try:
        out = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            cwd=ROOT,
            capture_output=True,
            check=True,
            timeout=60,
        )
        files = [f for f in out.stdout.decode().split("\0") if f]
    except (OSError, subprocess.SubprocessError):
        files = []
    if not files:
        shutil.copytree(ROOT, dest, ignore=shutil.ignore_patterns(*_IGNORED), dirs_exist_ok=True)
        return
    for name in files:
        source = ROOT / name
        if source.is_file():  # skips files deleted in the work tree, not yet in the index
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)


def _can_build_offline() -> bool:
    code = (
        "import setuptools, wheel\n"
        "v = tuple(int(p) for p in setuptools.__version__.split('.')[:2])\n"
        "raise SystemExit(0 if v >= (77, 0) else 1)\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, check=False)
    return result.returncode == 0


def _build_wheel(src: Path, out: Path) -> Path:
    pip = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--disable-pip-version-check"]
    pip += ["-q", "-w", str(out)]
    if _can_build_offline():
        result = _run([*pip, "--no-build-isolation", str(src)], out)
    else:  # fetches setuptools>=77 and wheel into an isolated build environment
        try:
            result = _run([*pip, "--retries", "0", "--timeout", "15", str(src)], out)
        except subprocess.TimeoutExpired:
            pytest.skip("building the wheel with build isolation timed out (slow network?)")
        if result.returncode != 0 and any(s in result.stderr for s in _OFFLINE):
            pytest.skip(
                "setuptools>=77/wheel are not in the venv and build isolation cannot fetch "
                f"them (no network): {result.stderr.strip().splitlines()[-1]}"
            )
    assert result.returncode == 0, f"pip wheel failed:\n{result.stdout}\n{result.stderr}"
    wheels = sorted(out.glob("*.whl"))
    assert len(wheels) == 1, f"expected one wheel, got {wheels}"
    return wheels[0]


def _functions(source: str) -> set[str]:
    """The names of a module's top-level functions."""
    return {n.name for n in ast.parse(source).body if isinstance(n, ast.FunctionDef)}


@pytest.mark.slow
def test_wheel_ships_one_import_name(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    _copy_sources(src)
    wheel = _build_wheel(src, out)

    version = _version()
    dist_info = f"isochor-{version}.dist-info/"
    assert wheel.name.startswith(f"isochor-{version}-"), wheel.name
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        entry_points = archive.read(dist_info + "entry_points.txt").decode()
        metadata = archive.read(dist_info + "METADATA").decode()
        modules = {n: archive.read(n).decode() for n in names if n.endswith(".py")}
        typed = archive.read("isochor/py.typed") if "isochor/py.typed" in names else None

    stray = [n for n in names if not n.startswith(("isochor/", dist_info))]
    assert not stray, f"wheel entries outside isochor/ and {dist_info}: {stray}"
    unshipped = [n for n in names if {"tests", "benchmarks", "docs"} & set(n.split("/")[:-1])]
    assert not unshipped, f"the wheel ships tests, benchmarks or docs: {unshipped}"
    required = {
        "isochor/__init__.py",
        "isochor/core/solve/multilevel.py",
        "isochor/app/cli/main.py",
        "isochor/assets/__init__.py",
        "isochor/py.typed",  # PEP 561: users' type checkers read the annotations
    }
    assert required <= set(names), f"missing from the wheel: {sorted(required - set(names))}"
    assert typed == b"", "py.typed is an empty marker"
    assert f"\nVersion: {version}\n" in metadata

    scripts = configparser.ConfigParser(delimiters=("=",))
    scripts.optionxform = str  # keep the scripts' names as written
    scripts.read_string(entry_points)
    assert scripts.has_section("console_scripts"), entry_points
    assert dict(scripts["console_scripts"]).get("isochor") == "isochor.app.cli.main:entry", (
        entry_points
    )
    assert scripts.has_section("gui_scripts") and dict(scripts["gui_scripts"]), (
        f"no gui_scripts for the editor in entry_points.txt:\n{entry_points}"
    )
    for section in ("console_scripts", "gui_scripts"):
        for script, target in scripts[section].items():
            module, _, function = target.partition(":")
            stem = module.replace(".", "/")
            file = next((f for f in (f"{stem}.py", f"{stem}/__init__.py") if f in modules), None)
            assert file, f"{section} {script} = {target}: the wheel has no {stem}.py"
            assert function in _functions(modules[file]), (
                f"{section} {script} = {target}: {file} defines no {function}()"
            )


def test_the_import_contract_forbids_every_gui_library():
    """import-linter's "core imports no GUI" contract names the same libraries as the
    fresh-interpreter tests (:data:`tests.fresh.GUI_LIBRARIES`)."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))["tool"]
    forbidden = [c for c in contracts["importlinter"]["contracts"] if c.get("type") == "forbidden"]
    assert forbidden and forbidden[0]["source_modules"] == ["isochor.core"], forbidden
    assert set(forbidden[0]["forbidden_modules"]) == set(GUI_LIBRARIES)
