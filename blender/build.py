"""Build the Isochor extension for Blender (``make addon``): one zip per platform,
``dist/isochor-VERSION-PLATFORM.zip`` (the manifest's ``platforms`` says which).

The add-on's modules, manifest and licences (the add-on's GPL-3.0-or-later ``LICENSE``, and
the repository's MIT ``LICENSE`` as ``LICENSE-isochor`` when there is one) are staged with
the wheels Blender lacks: isochor itself (built from this tree), what its core needs beyond
the numpy Blender ships (scipy, trimesh, fast-simplification, threadpoolctl, at the versions
installed here), and numba with llvmlite for the compiled kernels (Blender has no numba; the
versions of :data:`COMPILED`), for Python 3.11 (Blender 4.2 to 5.0) on each platform
(``--platform``: ``all`` or ``current``). Blender's own extension tool then builds one zip
per platform (``blender_ext.py build --split-platforms``, from the ``bpy`` package, or
``blender --command extension ...``), each holding its platform's wheels, and validates it.
The manifest's version must be the package's (``isochor/__init__.py``); its ``website`` is
written from ``pyproject.toml``'s ``Homepage``.

    python blender/build.py [--platform all|current] [--out dist]
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import json
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import tomllib
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: what isochor's core imports beyond numpy (Blender ships numpy; PySide6/pyvista are the
#: editor's, not the add-on's)
NEEDS = ("scipy", "trimesh", "fast-simplification", "threadpoolctl")
#: the compiled kernels' compiler: numba 0.68.1 supports NumPy 1.22 to 2.5 (its wheel's
#: requirement), so Blender's NumPy 1.24 and 1.26 (4.2 to 5.0) alike
COMPILED = {"numba": "0.68.1", "llvmlite": "0.50.0"}
#: Blender 4.2 to 5.0 run Python 3.11
PYTHON = "3.11"
#: Blender's platform names and the wheel platform each stands for
PLATFORMS = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_12_0_arm64",
    "macos-x64": "macosx_10_15_x86_64",
}


def _tool() -> list[str]:
    """How to run Blender's extension command (build, validate)."""
    spec = importlib.util.find_spec("bpy")
    if spec is not None and spec.submodule_search_locations:
        found = sorted(
            Path(spec.submodule_search_locations[0]).glob(
                "*/scripts/addons_core/bl_pkg/cli/blender_ext.py"
            )
        )
        if found:
            return [sys.executable, str(found[-1])]
    blender = shutil.which("blender")
    if blender:
        return [blender, "--background", "--factory-startup", "--command", "extension"]
    raise SystemExit(
        "build: Blender's extension tool was not found: install the bpy package "
        "(make venv) or put blender on the PATH"
    )


def _platforms(which: str) -> list[str]:
    """Blender's names of the platforms to build for."""
    if which == "all":
        return list(PLATFORMS)
    tag = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    if tag.startswith("linux"):
        return ["linux-x64"]
    if tag.startswith("win"):
        return ["windows-x64"]
    return ["macos-arm64" if tag.endswith("arm64") else "macos-x64"]


def version() -> str:
    """The package's version (``isochor/__init__.py``)."""
    text = (ROOT / "isochor" / "__init__.py").read_text()
    return re.search(r'^__version__ = "(.+)"$', text, re.M).group(1)


def manifest_version() -> str:
    """The version the source manifest says."""
    text = (HERE / "blender_manifest.toml").read_text()
    return re.search(r'^version = "(.+)"$', text, re.M).group(1)


def homepage() -> str:
    """The project's Homepage (``pyproject.toml``'s ``[project.urls]``)."""
    with (ROOT / "pyproject.toml").open("rb") as f:
        return str(tomllib.load(f)["project"]["urls"]["Homepage"])


def manifest_website() -> str:
    """The website the source manifest says."""
    with (HERE / "blender_manifest.toml").open("rb") as f:
        return str(tomllib.load(f)["website"])


def _pip(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", *args], check=True)


def stage(folder: Path, platforms: list[str]) -> list[str]:
    """The add-on's files, licences and wheels in ``folder``; returns the wheels'
    manifest paths."""
    for path in HERE.iterdir():
        if (
            path.suffix == ".py"
            and path.name != "build.py"
            or path.name
            in (
                "blender_manifest.toml",
                "LICENSE",
            )
        ):
            shutil.copy2(path, folder / path.name)
    if (ROOT / "LICENSE").is_file():
        shutil.copy2(ROOT / "LICENSE", folder / "LICENSE-isochor")
    wheels = folder / "wheels"
    wheels.mkdir()
    _pip("wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels), str(ROOT))
    pins = [f"{name}=={importlib.metadata.version(name)}" for name in NEEDS]
    pins += [f"{name}=={v}" for name, v in COMPILED.items()]
    for platform in platforms:
        _pip(
            "download", "--no-deps", "--only-binary=:all:", "-q", "--dest", str(wheels),
            "--python-version", PYTHON, "--platform", PLATFORMS[platform], *pins,
        )  # fmt: skip
    return sorted(f"./wheels/{w.name}" for w in wheels.glob("*.whl"))


def build(out: Path, which: str = "all") -> list[Path]:
    """The zips, one per platform (``which``: ``all`` or ``current``)."""
    if manifest_version() != version():
        raise SystemExit(
            f"build: blender_manifest.toml says version {manifest_version()}, the package "
            f"{version()}; make them equal"
        )
    tool = _tool()
    out.mkdir(parents=True, exist_ok=True)
    platforms = _platforms(which)
    with tempfile.TemporaryDirectory(prefix="isochor-addon-") as tmp:
        folder = Path(tmp) / "isochor"
        folder.mkdir()
        listed = stage(folder, platforms)
        manifest = folder / "blender_manifest.toml"
        text = manifest.read_text()
        lines = ",\n".join(f'  "{w}"' for w in listed)
        text = re.sub(r"^wheels = \[\]$", f"wheels = [\n{lines},\n]", text, flags=re.M)
        names = ", ".join(f'"{p}"' for p in platforms)
        text = re.sub(r"^website = .*$", f"website = {json.dumps(homepage())}", text, flags=re.M)
        text = re.sub(r"^platforms = \[\]$", f"platforms = [{names}]", text, flags=re.M)
        manifest.write_text(text)
        made = out / f"isochor-{tmp.rsplit('-', 1)[-1]}"
        made.mkdir()
        subprocess.run(
            [*tool, "build", "--source-dir", str(folder), "--output-dir", str(made),
             "--split-platforms"],
            check=True,
        )  # fmt: skip
        targets = []
        for zipped in sorted(made.glob("*.zip")):
            subprocess.run([*tool, "validate", str(zipped)], check=True)
            targets.append(zipped.replace(out / zipped.name))
        made.rmdir()
    return targets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platform", choices=("all", "current"), default="all")
    parser.add_argument("--out", type=Path, default=ROOT / "dist")
    args = parser.parse_args()
    for target in build(args.out, args.platform):
        print(target)


if __name__ == "__main__":
    main()
