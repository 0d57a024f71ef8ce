"""The Inspector's "Handles" group: how many surface handles there are, each one's miss after
the last solve, the Handle tool, and a button to remove the selected handle.

The group only emits what the user did; the window commits the edits and shows the state
with :meth:`HandleBox.show_handles` (which never emits).
"""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QPushButton,
    QVBoxLayout,
)

from ..view import style

TOOL_TIP = (
    "Click the model to put a handle on it, drag a handle to pull that point of the model: "
    "the lattice moves so that the point follows, keeping the volume. Ctrl+click places a "
    "handle without the tool."
)


class HandleBox(QGroupBox):
    """Signals
    -------
    handleChosen(int) : a handle was chosen in the list (-1: none)
    removeClicked() : remove the selected handle
    """

    handleChosen = Signal(int)
    removeClicked = Signal()

    def __init__(self, parent=None) -> None:
        super().__init__("Handles", parent)
        lay = QVBoxLayout(self)
        self.tool_box = QCheckBox("Handle tool: click the model")
        self.tool_box.setToolTip(TOOL_TIP)
        self.count = QLabel("No handle. Ctrl+click the model to add one.")
        self.count.setWordWrap(True)
        self.count.setStyleSheet("color: #8b95a5;")
        self.list = QListWidget()
        self.list.setMaximumHeight(96)
        self.list.currentRowChanged.connect(self.handleChosen.emit)
        row = QHBoxLayout()
        self.remove = QPushButton("Remove handle")
        self.remove.setToolTip("Remove the selected handle (Delete)")
        self.remove.clicked.connect(self.removeClicked.emit)
        row.addWidget(self.remove)
        row.addStretch(1)
        lay.addWidget(self.tool_box)
        lay.addWidget(self.count)
        lay.addWidget(self.list)
        lay.addLayout(row)
        self.show_handles((), None, None)

    def show_handles(self, handles, results, selected: int | None) -> None:
        """The state's ``handles``, the last solve's ``results`` for them (None: not solved
        yet) and the ``selected`` one."""
        n = len(handles)
        self.list.setVisible(n > 0)
        self.remove.setEnabled(selected is not None)
        if n == 0:
            self.count.setText("No handle. Ctrl+click the model (or use the Handle tool).")
        elif results is None or len(results) != n:
            self.count.setText(f"{n} handle{'s' if n > 1 else ''}, not solved yet.")
        else:
            met = sum(r.met for r in results)
            worst = max(r.miss for r in results)
            if met == n:
                self.count.setText(f"{n} handle{'s' if n > 1 else ''}, all met.")
            else:
                self.count.setText(
                    f'<span style="color:{style.PINNED}">{n - met} of {n} handles missed</span>:'
                    f" fitted by least squares, largest miss {100 * worst:.3g}% of the size."
                )
        self.list.blockSignals(True)
        self.list.clear()
        for i, h in enumerate(handles):
            r = results[i] if results is not None and i < len(results) else None
            state = "" if r is None else (" · met" if r.met else f" · misses {100 * r.miss:.2g}%")
            to = ", ".join(f"{v:.3g}" for v in h.to)
            self.list.addItem(f"{i + 1}. to ({to}){state}")
        self.list.setCurrentRow(-1 if selected is None else selected)
        self.list.blockSignals(False)
