"""The editor's lattice rebuild asks the estimate first (isochor.core.estimate): a lattice
whose solve does not fit the machine's memory is not rebuilt, and the status bar says why
in one line."""

from __future__ import annotations

from isochor.core import estimate as est


def test_a_lattice_beyond_the_memory_is_not_rebuilt_and_the_status_bar_says_why(
    qtbot, window, monkeypatch
):
    win = window
    panel = win.panel
    panel.basis.setCurrentIndex(panel.basis.findData("bspline"))
    before = win.state.lattice
    undo = win.undo_stack.count()
    monkeypatch.setattr(est, "available_memory", lambda: 400e6)  # 400 MB free
    for spin in panel.shape:
        spin.setValue(40)
    panel.rebuild.click()
    assert win.state.lattice is before and win.undo_stack.count() == undo
    line = win.statusBar().currentMessage()
    assert line.startswith("The lattice was not rebuilt: a 40x40x40 lattice needs about ")
    assert "400 MB free; " in line and " fits" in line and "\n" not in line
    # a lattice that fits is rebuilt as before
    monkeypatch.setattr(est, "available_memory", lambda: 4e9)
    for spin, n in zip(panel.shape, (4, 3, 5)):
        spin.setValue(n)
    panel.rebuild.click()
    assert win.state.lattice.shape == (4, 3, 5)
