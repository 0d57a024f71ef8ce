"""Writing the user's files (isochor.core.io.atomic) and the command line's signals
(isochor.app.cli.interrupts), in process: what is refused, all-or-none, roll-back."""

from __future__ import annotations

import errno
import os
import signal
import stat
import sys
import weakref

import pytest

import isochor.core.io.atomic as atomic
from isochor.app.cli import interrupts
from isochor.core.errors import IsochorError
from isochor.core.io.atomic import check_outputs, write_outputs


def listing(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture
def files(tmp_path):
    model = tmp_path / "model.obj"
    model.write_text("v 0 0 0\n")
    scene = tmp_path / "scene.json"
    scene.write_text("{}")
    return tmp_path, [(model, "the model"), (scene, "the scenario")]


@pytest.mark.parametrize(
    "spell",
    [
        lambda d: d / "model.obj",
        lambda d: d / "sub" / ".." / "model.obj",
        lambda d: os.path.relpath(d / "model.obj"),
    ],
)
def test_an_output_naming_an_input_is_refused(files, spell):
    folder, inputs = files
    (folder / "sub").mkdir()
    with pytest.raises(IsochorError, match="would overwrite the model"):
        check_outputs([(spell(folder), "--out")], inputs)


def test_hard_and_symbolic_links_to_an_input_are_the_input(files):
    folder, inputs = files
    os.link(folder / "model.obj", folder / "hard.obj")
    os.symlink(folder / "scene.json", folder / "soft.json")
    with pytest.raises(IsochorError, match="hard.obj: --out would overwrite the model"):
        check_outputs([(folder / "hard.obj", "--out")], inputs)
    with pytest.raises(IsochorError, match="soft.json: --report would overwrite the scenario"):
        check_outputs([(folder / "soft.json", "--report")], inputs)


def test_two_outputs_on_one_file_are_refused(tmp_path):
    with pytest.raises(IsochorError, match="--report and --out name the same file"):
        check_outputs([(tmp_path / "x.ply", "--out"), (tmp_path / "x.ply", "--report")])


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda d: d, "is a folder"),
        (lambda d: "/dev/null", "not a regular file"),
        (lambda d: (os.mkfifo(d / "pipe"), d / "pipe")[1], "not a regular file"),
        (lambda d: d / "missing" / "x.ply", "does not exist"),
        (lambda d: str(d / "a\0b.ply"), "not a valid file name"),
        (
            lambda d: (os.symlink(d / "b", d / "a"), os.symlink(d / "a", d / "b"), d / "a")[2],
            "loop of symbolic links",
        ),
    ],
)
def test_what_cannot_be_written_is_refused_with_its_name(tmp_path, make, words):
    path = make(tmp_path)
    before = listing(tmp_path)
    with pytest.raises(IsochorError, match=words) as err:
        check_outputs([(path, "--out")])
    assert "\n" not in str(err.value)
    assert listing(tmp_path) == before
    if str(path) == "/dev/null":
        assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_a_symbolic_link_writes_its_target_and_stays_a_link(tmp_path):
    (tmp_path / "real").mkdir()
    link, dangling = tmp_path / "link.ply", tmp_path / "dangling.ply"
    os.symlink(tmp_path / "real" / "a.ply", link)
    os.symlink(tmp_path / "real" / "b.ply", dangling)
    (tmp_path / "real" / "a.ply").write_bytes(b"old")
    outs = check_outputs([(link, "--out"), (dangling, "--report")])
    write_outputs([(outs[0], b"mesh"), (outs[1], b"report")])
    assert link.is_symlink() and dangling.is_symlink()
    assert (tmp_path / "real" / "a.ply").read_bytes() == b"mesh"
    assert (tmp_path / "real" / "b.ply").read_bytes() == b"report"
    assert listing(tmp_path / "real") == ["a.ply", "b.ply"]


def _failing_after(monkeypatch, calls: int, exc: BaseException):
    """os.replace works ``calls`` times, then raises ``exc`` (the roll-back's own renames
    are let through)."""
    real, seen = os.replace, []

    def replace(src, dst):
        seen.append(dst)
        if len(seen) == calls + 1:
            raise exc
        return real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)


@pytest.mark.parametrize(
    "exc", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()]
)
def test_outputs_are_written_all_or_none(tmp_path, monkeypatch, exc):
    old, new = tmp_path / "old.ply", tmp_path / "new.json"
    old.write_bytes(b"the user's file")
    outs = check_outputs([(old, "--out"), (new, "--report")])
    _failing_after(monkeypatch, 1, exc)  # the first rename happens, the second fails
    with pytest.raises(IsochorError if isinstance(exc, OSError) else KeyboardInterrupt) as err:
        write_outputs([(outs[0], b"mesh"), (outs[1], b"report")])
    assert old.read_bytes() == b"the user's file"  # put back
    assert listing(tmp_path) == ["old.ply"]  # no new file, no temporary file
    assert not atomic.PENDING
    if isinstance(exc, OSError):  # the user's path, not the temporary file's name
        assert str(err.value) == f"{new}: cannot write the file (No space left on device)"


def test_a_failed_temporary_write_leaves_nothing(tmp_path, monkeypatch):
    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", full)
    outs = check_outputs([(tmp_path / "a.ply", "--out"), (tmp_path / "b.json", "--report")])
    with pytest.raises(IsochorError, match=r"a.ply: cannot write the file \(No space"):
        write_outputs([(outs[0], b"mesh"), (outs[1], b"report")])
    assert listing(tmp_path) == []


def test_replacing_keeps_the_file_mode(tmp_path):
    path = tmp_path / "x.json"
    path.write_text("old")
    path.chmod(0o640)
    atomic.atomic_write_text(path, "new")
    assert path.read_text() == "new" and stat.S_IMODE(path.stat().st_mode) == 0o640
    assert listing(tmp_path) == ["x.json"]


# -- signals ------------------------------------------------------------------------------
@pytest.fixture
def armed():
    interrupts.install()
    interrupts.arm()
    yield
    interrupts.release()


def test_sigterm_is_recorded_and_raised_at_the_next_safe_point(armed):
    os.kill(os.getpid(), signal.SIGTERM)  # the handler runs here, and only records it
    assert interrupts.state.pending == signal.SIGTERM and interrupts.state.armed
    with pytest.raises(interrupts.Interrupted) as err:
        interrupts.check()
    assert err.value.status == 143 and err.value.name == "SIGTERM"
    assert isinstance(err.value, KeyboardInterrupt)  # stops a solve like Ctrl-C


@pytest.mark.skipif(
    signal.getsignal(signal.SIGINT) is signal.SIG_IGN,
    reason="SIGINT is ignored in this test run (a background job of a shell), and stays so",
)
def test_only_the_first_signal_is_raised_and_none_after_hold(armed):
    os.kill(os.getpid(), signal.SIGINT)
    os.kill(os.getpid(), signal.SIGTERM)  # recorded after the first: the first counts
    with pytest.raises(interrupts.Interrupted) as err:
        interrupts.check()
    assert err.value.status == 130
    interrupts.check()  # answered once
    os.kill(os.getpid(), signal.SIGTERM)  # the way out: only noted
    assert interrupts.state.pending == signal.SIGTERM
    with pytest.raises(interrupts.Interrupted):
        interrupts.arm()  # a new run raises the noted one at once
    assert not interrupts.state.armed


def test_a_signal_while_committing_lets_the_outputs_complete(armed, tmp_path):
    outs = check_outputs([(tmp_path / "a.ply", "--out"), (tmp_path / "b.json", "--report")])

    def commit():
        interrupts.hold()
        os.kill(os.getpid(), signal.SIGTERM)

    write_outputs([(outs[0], b"mesh"), (outs[1], b"report")], on_commit=commit)
    assert listing(tmp_path) == ["a.ply", "b.json"]


def test_a_signal_where_python_swallows_exceptions_is_answered_before_writing(armed, tmp_path):
    """The handler never raises, so a ``try: ... except BaseException`` (a library's
    optional import) cannot lose it; the commit answers it and nothing is written."""
    outs = check_outputs([(tmp_path / "a.ply", "--out"), (tmp_path / "b.json", "--report")])
    try:
        os.kill(os.getpid(), signal.SIGTERM)
    except BaseException:  # what a library's `try: import ... except BaseException` does
        pytest.fail("the handler raised")
    assert interrupts.state.armed  # still armed: the signal is waiting for a safe point
    with pytest.raises(interrupts.Interrupted) as err:
        write_outputs([(outs[0], b"mesh"), (outs[1], b"report")], on_commit=interrupts.commit)
    assert err.value.name == "SIGTERM" and listing(tmp_path) == []


def test_after_the_commit_a_signal_is_answered_when_the_renames_are_done(armed, tmp_path):
    outs = check_outputs([(tmp_path / "a.ply", "--out")])

    def commit():
        interrupts.commit()
        os.kill(os.getpid(), signal.SIGTERM)  # the renames go on

    write_outputs([(outs[0], b"mesh")], on_commit=commit)
    assert listing(tmp_path) == ["a.ply"] and interrupts.state.pending == signal.SIGTERM
    interrupts.commit()  # once committed, the run completes: no second check
    assert interrupts.finish() == signal.SIGTERM  # the caller's line: all were written
    os.kill(os.getpid(), signal.SIGTERM)  # the status is decided: ignored
    assert interrupts.state.pending is None


def test_an_interrupt_python_ignores_is_not_printed(monkeypatch):
    seen = []
    monkeypatch.setattr(sys, "unraisablehook", seen.append)
    interrupts.install()

    class Thing:
        pass

    def interrupt(_):
        raise interrupts.Interrupted(signal.SIGTERM)

    def fail(_):
        raise ValueError("not a signal")

    try:
        for callback in (interrupt, fail):  # a weakref callback's exception is ignored
            thing = Thing()
            ref = weakref.ref(thing, callback)
            del thing
    finally:
        interrupts.release()
    assert ref() is None
    assert [type(u.exc_value) for u in seen] == [ValueError]  # only the interrupt is dropped
    assert sys.unraisablehook == seen.append  # given back


def test_a_signal_before_arming_is_raised_on_arming():
    interrupts.install()
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        with pytest.raises(interrupts.Interrupted) as err:
            interrupts.arm()
        assert err.value.name == "SIGTERM"
    finally:
        interrupts.release()
    assert signal.getsignal(signal.SIGTERM) is not interrupts._handler
