"""Classes are composed from parts that own their state, checked headless with :mod:`ast`
over every module of ``core/`` and ``app/``.

- no class is assembled from mixins (one base class each);
- no module reads or writes another object's private attribute (``other._x``);
- no module assigns attributes onto the editor's big objects (the window, the view, the
  session, the document: ``win.x = ...``, ``setattr(vp, ...)``): each part owns its state
  and is asked through its methods.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("core", "app")
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
    "session",
    "self.session",
    "win.session",
    "doc",
    "document",
    "self.doc",
    "self.document",
    "win.doc",
    "self.win.doc",
}


def _modules() -> list[Path]:
    paths = [p for folder in FOLDERS for p in sorted((ROOT / folder).rglob("*.py"))]
    assert len(paths) > 50, "the modules of core/ and app/ were not found"
    return paths


def _where(path: Path, node: ast.AST) -> str:
    return f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', '?')}: {ast.unparse(node)}"


def _host(node: ast.expr) -> bool:
    """``node`` is the window or the view."""
    return ast.unparse(node) in HOSTS


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.relative_to(ROOT).as_posix())
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
