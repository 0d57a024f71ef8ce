"""CHANGELOG.md keeps the Keep a Changelog form, and the package's version follows it:
``isochor.__version__`` is the newest released section's."""

from __future__ import annotations

import re
from datetime import date
from pathlib import Path

import isochor

CHANGELOG = Path(__file__).resolve().parents[1] / "CHANGELOG.md"
#: the kinds of change Keep a Changelog names
KINDS = {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}


def _sections() -> list[str]:
    return re.findall(r"^## (.+)$", CHANGELOG.read_text(encoding="utf-8"), re.M)


def test_the_version_is_the_newest_release():
    sections = _sections()
    assert sections[0] == "[Unreleased]", sections
    released = [re.fullmatch(r"\[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})", s) for s in sections[1:]]
    assert released and all(released), sections
    assert released[0][1] == isochor.__version__, (released[0][1], isochor.__version__)
    versions = [tuple(map(int, m[1].split("."))) for m in released]
    dates = [date.fromisoformat(m[2]) for m in released]
    assert versions == sorted(versions, reverse=True) and len(set(versions)) == len(versions)
    assert dates == sorted(dates, reverse=True)


def test_every_change_is_under_a_known_kind():
    text = CHANGELOG.read_text(encoding="utf-8")
    kinds = re.findall(r"^### (.+)$", text, re.M)
    assert kinds and set(kinds) <= KINDS, set(kinds) - KINDS
    for block in re.split(r"^## ", text, flags=re.M)[1:]:
        for part in re.split(r"^### ", block, flags=re.M)[1:]:
            items = re.findall(r"^- \S", part, re.M)
            assert items, f"an empty '### {part.splitlines()[0]}' section"
