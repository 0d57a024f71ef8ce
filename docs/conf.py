"""Sphinx configuration of the API reference (``make docs``: build/docs/index.html).

The reference is made from the docstrings (autodoc; napoleon reads their numpy-style
sections) and the Markdown pages beside it (MyST): the scenario format, the command line
and the Blender add-on. Warnings are errors (``sphinx-build -W``)."""

from __future__ import annotations

import re
from pathlib import Path

import isochor

HERE = Path(__file__).parent

project = "Isochor"
author = "Isochor developers"
copyright = "2026, Isochor developers"
release = version = isochor.__version__

extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "myst_parser"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
#: the pages of the reference; the other Markdown files in docs/ are the developers'
#: (linked from the README), not part of it
exclude_patterns = ["_build", "ARCHITECTURE.md", "BENCHMARKS.md", "CONSTRAINTS.md"]

#: the add-on's page: docs/BLENDER.md where it exists, else a short page from the README
ADDON = "BLENDER" if (HERE / "BLENDER.md").is_file() else "api/addon"
exclude_patterns.append("api/addon.md" if ADDON == "BLENDER" else "BLENDER.md")

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
myst_heading_anchors = 3
# the Markdown pages link to files of the repository (../README.md, ../core/...): they are
# not pages of the reference
suppress_warnings = ["myst.xref_missing"]

html_theme = "alabaster"
html_title = f"Isochor {release}"


def _addon_page(app, docname, source) -> None:
    """The index's toctree names the add-on's page that exists (see :data:`ADDON`)."""
    if docname == "index":
        source[0] = source[0].replace("ADDON_PAGE", ADDON)


#: the sections whose entries are ``name : what it is``
_FIELDS = {"Parameters", "Other Parameters", "Attributes", "Keyword Arguments"}
_ENTRY = re.compile(r"^(\*{0,2}[A-Za-z_][\w, *]*?) : (.+)$")
#: ``|x|`` written for an absolute value, outside inline literals (reST reads a substitution)
_BARS = re.compile(r"(?<![`\w|\\])\|([^|`\n]+)\|(?![`\w|])")


def _numpy_fields(app, what, name, obj, options, lines: list[str]) -> None:
    """The project's docstrings write a parameter as ``name : what it is`` on one line
    (the type and the words together); numpy's form puts the words below the name. So
    napoleon reads them as descriptions, not types, each entry becomes ``name`` and its
    words indented under it; a paragraph after the entries (at their indent, after a
    blank line) becomes the section's end, a Notes section. And ``|x|``, an absolute
    value, is written as text, not a reST substitution."""
    lines[:] = [_BARS.sub(r"\\|\1\\|", line) for line in lines]
    out: list[str] = []
    section = None
    for i, line in enumerate(lines):
        below = lines[i + 1].strip() if i + 1 < len(lines) else ""
        if line.strip() and len(below) >= 3 and set(below) == {"-"}:
            section = line.strip()
        elif section in _FIELDS and line and not line[0].isspace() and set(line) != {"-"}:
            entry = _ENTRY.match(line)
            if entry:
                out += [entry[1], "    " + entry[2]]
                continue
            if out and not out[-1]:
                out += ["Notes", "-----"]
                section = "Notes"
        out.append(line)
    lines[:] = out


def setup(app):
    app.connect("source-read", _addon_page)
    # before napoleon (priority 500) turns the sections into fields
    app.connect("autodoc-process-docstring", _numpy_fields, priority=400)
