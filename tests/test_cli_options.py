"""A mistyped option or command, out of process: one line naming it, with the nearest
known one when one is near, exit 2, nothing written; before argparse could take the
mistyped option's value for a file (``--ot x.obj``)."""

from __future__ import annotations

import pytest

from tests.test_cli_goals import isochor


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (["solve", "--bogus"], "unknown option --bogus (see 'isochor solve --help')"),
        (
            ["solve", "--ot", "x.obj"],
            "unknown option --ot; did you mean --out? (see 'isochor solve --help')",
        ),
        (
            ["solve", "--example", "torus-compression", "--ot", "x.obj"],
            "unknown option --ot; did you mean --out? (see 'isochor solve --help')",
        ),
        (
            ["solve", "--example", "torus-compression", "--report=r.json", "--no-fold-gard"],
            "unknown option --no-fold-gard; did you mean --no-fold-guard? "
            "(see 'isochor solve --help')",
        ),
        (
            ["edit", "--screnshot", "s.png", "x.obj"],
            "unknown option --screnshot; did you mean --screenshot? (see 'isochor edit --help')",
        ),
        (["--verison"], "unknown option --verison; did you mean --version? (see 'isochor --help')"),
        (["slove"], "unknown command 'slove'; did you mean 'solve'? (see 'isochor --help')"),
    ],
    ids=["bogus", "ot", "ot-after-example", "boolean", "edit", "top", "command"],
)
def test_an_unknown_option_is_named_with_the_nearest(tmp_path, args, line):
    run = isochor(*args, cwd=tmp_path)
    assert run.returncode == 2, run
    assert run.stderr == f"isochor: {line}\n", run.stderr
    assert run.stdout == ""
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_known_options_and_their_prefixes_still_work(tmp_path):
    """The check refuses only what argparse would: an option's unambiguous start is the
    option, a negative number is a value, and an ambiguous start is argparse's to say."""
    run = isochor(
        "solve", "--example", "cup-squeeze", "--rep", "r.json", "--target", "-1", cwd=tmp_path
    )
    assert run.returncode == 1 and "--target -1" in run.stderr, run  # the value's range
    run = isochor("solve", "--example", "cup-squeeze", "--rep=r.json", "-q", cwd=tmp_path)
    assert run.returncode == 0, run
    assert (tmp_path / "r.json").is_file()
    run = isochor("solve", "--example", "cup-squeeze", "--ou", "x.obj", cwd=tmp_path)
    assert run.returncode == 2 and "ambiguous option: --ou" in run.stderr, run
