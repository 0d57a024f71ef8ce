"""The window's layout, remembered between runs: a part of the main window
(``window.layout_memory``).

The docks' places, sizes, tabs and visibility and the window's geometry are kept in the
user's settings (QSettings, organisation "Isochor": ``$XDG_CONFIG_HOME/Isochor/Isochor.conf``
on Linux) when the window closes, and put back when the next one opens. The first time,
the default is the view first: the Inspector (with the convergence plot as a tab behind it)
on the right, the timeline hidden until the document has keys. GUI thread only.
"""

from __future__ import annotations

from PySide6.QtCore import QSettings

#: bump when the docks change, so that an old layout is not restored onto new docks
LAYOUT_VERSION = 2


def settings() -> QSettings:
    """Isochor's user settings."""
    return QSettings("Isochor", "Isochor")


class LayoutMemory:
    """Saves and restores one window's layout."""

    def __init__(self, window) -> None:
        self.win = window

    def save(self) -> None:
        s = settings()
        s.setValue("window/geometry", self.win.saveGeometry())
        s.setValue("window/state", self.win.saveState(LAYOUT_VERSION))
        s.sync()

    def restore(self) -> bool:
        """Put back the layout saved last; False when there is none (the default stays)."""
        s = settings()
        geometry, state = s.value("window/geometry"), s.value("window/state")
        if geometry is None or state is None:
            return False
        self.win.restoreGeometry(geometry)
        return bool(self.win.restoreState(state, LAYOUT_VERSION))
