"""The window and the 3D view are composed from parts, checked headless with :mod:`ast`.

- no class in ``app/view`` or ``app/window`` is assembled from mixins (one base class each);
- no module there reads or writes another object's private attribute (``other._x``);
- no module assigns attributes onto the window or the view (``win.x = ...``,
  ``setattr(vp, ...)``): each part owns its state and is asked through its methods.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("app/view", "app/window")
#: the names the window's and the view's modules give the window and the view
HOSTS = {
    "win",
    "window",
    "self.win",
    "self.window",
    "vp",
    "viewport",
    "self.viewport",
    "win.viewport",
    "self.win.viewport",
}


def _modules() -> list[Path]:
    paths = [p for folder in FOLDERS for p in sorted((ROOT / folder).glob("*.py"))]
    assert len(paths) > 10, "the view's and the window's modules were not found"
    return paths


def _where(path: Path, node: ast.AST) -> str:
    return f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', '?')}: {ast.unparse(node)}"


def _host(node: ast.expr) -> bool:
    """``node`` is the window or the view."""
    return ast.unparse(node) in HOSTS


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.stem)
def test_parts_own_their_state(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and len(node.bases) > 1:
            bad.append(f"{_where(path, node.bases[0])}: {node.name} has several bases (mixins)")
        elif (
            isinstance(node, ast.Attribute)
            and node.attr.startswith("_")
            and not node.attr.startswith("__")
            and ast.unparse(node.value) not in ("self", "cls")
        ):
            bad.append(f"{_where(path, node)}: another object's private attribute")
        elif isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if isinstance(t, ast.Attribute) and _host(t.value):
                    bad.append(f"{_where(path, t)}: an attribute assigned onto the window/view")
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id == "setattr"
            and node.args
            and _host(node.args[0])
        ):
            bad.append(f"{_where(path, node)}: an attribute assigned onto the window/view")
    assert not bad, "\n".join(bad)
