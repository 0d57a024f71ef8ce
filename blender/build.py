"""Build the Isochor extension for Blender (``make addon``): ``dist/isochor-VERSION.zip``.

The add-on's modules and manifest are staged with the wheels Blender lacks: isochor itself
(built from this tree) and what its core needs beyond the numpy Blender ships (scipy, trimesh,
fast-simplification, threadpoolctl), at the versions installed here, for Python 3.11 (Blender
4.2 to 5.0) on each platform (``--platform``: ``all`` or ``current``). Blender's own extension
tool then builds and validates the zip (``blender_ext.py build`` / ``validate`` from the
``bpy`` package, or ``blender --command extension ...``).

    python blender/build.py [--platform all|current] [--out dist]
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: what isochor's core imports beyond numpy (Blender ships numpy; PySide6/pyvista are the
#: editor's, not the add-on's)
NEEDS = ("scipy", "trimesh", "fast-simplification", "threadpoolctl")
#: Blender 4.2 to 5.0 run Python 3.11
PYTHON = "3.11"
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
    if which == "all":
        return list(PLATFORMS.values())
    tag = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    if tag.startswith("linux"):
        return [PLATFORMS["linux-x64"]]
    if tag.startswith("win"):
        return [PLATFORMS["windows-x64"]]
    return [PLATFORMS["macos-arm64" if tag.endswith("arm64") else "macos-x64"]]


def _pip(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", *args], check=True)


def stage(folder: Path, platforms: list[str]) -> list[str]:
    """The add-on's files and wheels in ``folder``; returns the wheels' manifest paths."""
    for path in HERE.iterdir():
        if path.suffix == ".py" and path.name != "build.py" or path.name == "blender_manifest.toml":
            shutil.copy2(path, folder / path.name)
    wheels = folder / "wheels"
    wheels.mkdir()
    _pip("wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels), str(ROOT))
    pins = [f"{name}=={importlib.metadata.version(name)}" for name in NEEDS]
    for platform in platforms:
        _pip(
            "download", "--no-deps", "--only-binary=:all:", "-q", "--dest", str(wheels),
            "--python-version", PYTHON, "--platform", platform, *pins,
        )  # fmt: skip
    return sorted(f"./wheels/{w.name}" for w in wheels.glob("*.whl"))


def build(out: Path, which: str = "all") -> Path:
    tool = _tool()
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="isochor-addon-") as tmp:
        folder = Path(tmp) / "isochor"
        folder.mkdir()
        listed = stage(folder, _platforms(which))
        manifest = folder / "blender_manifest.toml"
        text = manifest.read_text()
        lines = ",\n".join(f'  "{w}"' for w in listed)
        text = re.sub(r"^wheels = \[\]$", f"wheels = [\n{lines},\n]", text, flags=re.M)
        version = re.search(
            r'^__version__ = "(.+)"$', (ROOT / "isochor" / "__init__.py").read_text(), re.M
        ).group(1)
        text = re.sub(r'^version = ".*"$', f'version = "{version}"', text, count=1, flags=re.M)
        manifest.write_text(text)
        target = out / f"isochor-{version}.zip"
        subprocess.run(
            [*tool, "build", "--source-dir", str(folder), "--output-filepath", str(target)],
            check=True,
        )
        subprocess.run([*tool, "validate", str(target)], check=True)
    return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platform", choices=("all", "current"), default="all")
    parser.add_argument("--out", type=Path, default=ROOT / "dist")
    args = parser.parse_args()
    print(build(args.out, args.platform))


if __name__ == "__main__":
    main()
