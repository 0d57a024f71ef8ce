"""The side panel: the selection (exact position, pin, pinned axes), solve options, what the
solve holds (:class:`~isochor.app.window.goalbox.GoalBox`), the surface handles
(:class:`~isochor.app.window.handlebox.HandleBox`), lattice, display."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QEvent, QObject, Qt, Signal
from PySide6.QtGui import QAction
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from ...core.goal.spec import RATIO_RANGE
from ...core.lattice import MAX_NODES, MIN_NODES
from ...core.localbasis import BERNSTEIN, KINDS, MAX_LOCAL, MIN_LOCAL
from ..editor.state import axes_words
from ..view import style
from .goalbox import GoalBox
from .handlebox import HandleBox


def bind(action: QAction, box: QCheckBox) -> None:
    """Keep a checkable action and a check box in step, both ways."""
    box.setChecked(action.isChecked())
    box.toggled.connect(action.setChecked)
    action.toggled.connect(
        lambda on: (box.blockSignals(True), box.setChecked(on), box.blockSignals(False))
    )


class _WheelGuard(QObject):
    """The mouse wheel scrolls the Inspector; it changes a spin box only after the user
    clicked into it (a wheel passing over a field must not edit the document)."""

    def eventFilter(self, obj, ev) -> bool:
        if ev.type() == QEvent.Type.Wheel and not obj.hasFocus():
            ev.ignore()  # the scroll area behind gets it
            return True
        return False


def guard_wheel(box) -> None:
    """Let ``box`` take focus only by click or Tab, and the wheel only while focused."""
    box.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
    box.installEventFilter(_WheelGuard(box))  # (the box owns it: its child)


def _spin(lo: float, hi: float, decimals: int, suffix: str = "") -> QDoubleSpinBox:
    s = QDoubleSpinBox()
    guard_wheel(s)
    s.setRange(lo, hi)
    s.setDecimals(decimals)
    s.setKeyboardTracking(False)
    s.setSuffix(suffix)
    s.setAlignment(Qt.AlignmentFlag.AlignRight)
    return s


class Panel(QWidget):
    """Signals
    -------
    positionEdited(int, float) : axis 0-2 and the typed coordinate (of the node, or of the
                                 centroid of a multi-selection)
    pinClicked(bool) : the pin check box was clicked: pin (True) or unpin the selection
    pinAxisClicked(int, bool) : an axis box was clicked: pin (True) or free the selection on
                                that axis (0-2) only
    targetEdited(float) : target volume, percent of the original
    latticeRequested(tuple) : rebuild the lattice with (l, m, n) nodes
    """

    positionEdited = Signal(int, float)
    pinClicked = Signal(bool)
    pinAxisClicked = Signal(int, bool)
    targetEdited = Signal(float)
    latticeRequested = Signal(tuple)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(8, 4, 8, 8)
        lay.setSpacing(6)

        # selection
        sel = QGroupBox("Selection")
        form = QVBoxLayout(sel)
        self.sel_title = QLabel("No node selected")
        self.sel_title.setStyleSheet("font-weight: 600;")
        self.sel_role = QLabel("Click a node, or Shift-drag a box.")
        self.sel_role.setStyleSheet("color: #8b95a5;")
        self.sel_role.setWordWrap(True)
        form.addWidget(self.sel_title)
        form.addWidget(self.sel_role)
        grid = QGridLayout()
        self.coord = []
        for i, name in enumerate("XYZ"):
            label = QLabel(name)
            label.setStyleSheet("color: #8b95a5; font-weight: 600;")
            s = _spin(-1e9, 1e9, 4)
            s.valueChanged.connect(lambda v, axis=i: self.positionEdited.emit(axis, v))
            grid.addWidget(label, i, 0)
            grid.addWidget(s, i, 1)
            self.coord.append(s)
        form.addLayout(grid)
        self.pin_box = QCheckBox("Pinned (fixed during the solve)")
        self.pin_box.setTristate(False)
        self.pin_box.clicked.connect(lambda on: self.pinClicked.emit(bool(on)))
        form.addWidget(self.pin_box)
        axes_row = QHBoxLayout()
        axes_label = QLabel("Pinned on")
        axes_label.setStyleSheet("color: #8b95a5;")
        axes_row.addWidget(axes_label)
        self.axis_boxes = []
        for i, name in enumerate("XYZ"):
            box = QCheckBox(name)
            box.setToolTip(
                f"Pin the selected nodes on {name.lower()}: the solver keeps their "
                f"{name.lower()} and moves them on the other axes"
            )
            box.clicked.connect(lambda _=False, axis=i, b=box: self._axis_clicked(axis, b))
            axes_row.addWidget(box)
            self.axis_boxes.append(box)
        axes_row.addStretch(1)
        form.addLayout(axes_row)
        row = QHBoxLayout()
        self.pin_all = QPushButton("Pin all")
        self.unpin_all = QPushButton("Unpin all")
        row.addWidget(self.pin_all)
        row.addWidget(self.unpin_all)
        form.addLayout(row)
        lay.addWidget(sel)

        # solve
        solve = QGroupBox("Solve")
        sform = QFormLayout(solve)
        sform.setLabelAlignment(Qt.AlignmentFlag.AlignLeft)
        self.preserve_box = QCheckBox("Preserve volume")
        self.live_box = QCheckBox("Live: solve while dragging")
        self.target = _spin(100 * RATIO_RANGE[0], 100 * RATIO_RANGE[1], 2, " %")
        self.target.setValue(100.0)
        self.target.setSingleStep(5.0)
        self.target.valueChanged.connect(self.targetEdited.emit)
        sform.addRow(self.preserve_box)
        sform.addRow(self.live_box)
        sform.addRow("Target volume", self.target)
        self.solve_state = QLabel("")
        self.solve_state.setWordWrap(True)
        sform.addRow(self.solve_state)
        buttons = QHBoxLayout()
        self.solve_button = QPushButton("Solve again")
        self.reset_button = QPushButton("Reset nodes")
        buttons.addWidget(self.solve_button)
        buttons.addWidget(self.reset_button)
        sform.addRow(buttons)
        lay.addWidget(solve)
        self.goal = GoalBox()
        guard_wheel(self.goal.volume_choice)
        guard_wheel(self.goal.symmetry_choice)
        lay.addWidget(self.goal)
        self.handles = HandleBox()
        lay.addWidget(self.handles)

        # lattice
        lat = QGroupBox("Lattice")
        lgrid = QGridLayout(lat)
        self.shape = []
        for i, name in enumerate("XYZ"):
            s = QSpinBox()
            guard_wheel(s)
            s.setRange(MIN_NODES, MAX_NODES)
            s.setAlignment(Qt.AlignmentFlag.AlignRight)
            s.setPrefix(f"{name}  ")
            lgrid.addWidget(s, 0, i)
            self.shape.append(s)
        self.basis = QComboBox()
        guard_wheel(self.basis)
        for name, label in BASIS_LABELS.items():
            self.basis.addItem(label, name)
        self.basis.setToolTip(
            "Bernstein: the paper's basis, every node moves every point (2 to 10 per axis). "
            "B-spline, Catmull-Rom, Cardinal, Linear: Blender's lattice, each point moves "
            "with the 4x4x4 nodes around it (1 to 64 per axis)."
        )
        self.basis.currentIndexChanged.connect(self._basis_ranges)
        lgrid.addWidget(QLabel("Basis"), 1, 0)
        lgrid.addWidget(self.basis, 1, 1, 1, 2)
        self.outside_box = QCheckBox("Outside")
        self.outside_box.setToolTip(
            "Blender's Outside option (local bases only): points outside the box are moved "
            "as if the lattice went on beyond its last nodes, instead of following the "
            "nearest face."
        )
        lgrid.addWidget(self.outside_box, 2, 1, 1, 2)
        self._basis_ranges()
        self.rebuild = QPushButton("Rebuild lattice")
        self.rebuild.clicked.connect(
            lambda: self.latticeRequested.emit(tuple(s.value() for s in self.shape))
        )
        lgrid.addWidget(self.rebuild, 3, 0, 1, 3)
        note = QLabel("Nodes per axis, basis and Outside. Rebuilding resets moves and pins.")
        note.setStyleSheet("color: #8b95a5;")
        note.setWordWrap(True)
        lgrid.addWidget(note, 4, 0, 1, 3)
        lay.addWidget(lat)

        # display
        disp = QGroupBox("Display")
        dl = QVBoxLayout(disp)
        self.lattice_box = QCheckBox("Lattice nodes and springs")
        self.diag_box = QCheckBox("Diagonal springs")
        self.ghost_box = QCheckBox("Ghost of the original")
        self.smooth_box = QCheckBox("Smooth shading")
        for b in (self.lattice_box, self.diag_box, self.ghost_box, self.smooth_box):
            dl.addWidget(b)
        lay.addWidget(disp)
        lay.addStretch(1)

    # -- updates from the window (never emit) -----------------------------------------------
    def show_selection(
        self,
        lattice,
        rows: np.ndarray,
        nodes: np.ndarray,
        pin_axes: np.ndarray,
        moved: np.ndarray,
        step: float,
        held: np.ndarray | None = None,
    ) -> None:
        rows = np.asarray(rows, dtype=int)
        enabled = len(rows) > 0
        for s in self.coord:
            s.setEnabled(enabled)
            s.setSingleStep(step)
        self.pin_box.setEnabled(enabled)
        for b in self.axis_boxes:
            b.setEnabled(enabled)
        if not enabled:
            self.sel_title.setText("No node selected")
            self.sel_role.setText("Click a node, or Shift-drag a box around several.")
            self._set_coords(None)
            self._set_pin(False, np.zeros((0, 3), bool))
            return
        axes = np.asarray(pin_axes, bool) | np.asarray(moved, bool)[:, None]
        fixed = axes[rows].any(axis=1)
        if len(rows) == 1:
            r = int(rows[0])
            i, j, k = lattice.ijk(r)
            self.sel_title.setText(f"Node ({i}, {j}, {k})")
            hold = held is not None and r < len(held) and bool(held[r])
            color, role = _role(axes[r], bool(moved[r]), hold)
            self.sel_role.setText(f'<span style="color:{color}">&#9679;</span> {role}')
            self._set_coords(nodes[r])
        else:
            some = int((fixed & ~axes[rows].all(axis=1)).sum())
            some = f", {some} of them on some axes only" if some else ""
            self.sel_title.setText(f"{len(rows)} nodes selected")
            self.sel_role.setText(
                f"{int(fixed.sum())} fixed{some}, {int((~fixed).sum())} free; "
                "the fields show their centre."
            )
            self._set_coords(nodes[rows].mean(axis=0))
        self._set_pin(bool(axes[rows].all()), axes[rows])

    def _set_coords(self, p) -> None:
        for i, s in enumerate(self.coord):
            if s.hasFocus():
                continue  # never overwrite what the user is typing
            s.blockSignals(True)
            s.setValue(0.0 if p is None else float(p[i]))
            s.blockSignals(False)

    def _set_pin(self, on: bool, axes: np.ndarray) -> None:
        """The pin box (every selected node fixed on every axis) and the axis boxes
        (checked: every selected node pinned on that axis; partly: some are)."""
        self.pin_box.blockSignals(True)
        self.pin_box.setChecked(on)
        self.pin_box.blockSignals(False)
        for a, box in enumerate(self.axis_boxes):
            box.blockSignals(True)
            if len(axes) and axes[:, a].all():
                box.setTristate(False)
                box.setCheckState(Qt.CheckState.Checked)
            elif len(axes) and axes[:, a].any():
                box.setCheckState(Qt.CheckState.PartiallyChecked)
            else:
                box.setTristate(False)
                box.setCheckState(Qt.CheckState.Unchecked)
            box.blockSignals(False)

    def _axis_clicked(self, axis: int, box: QCheckBox) -> None:
        """A click pins the axis unless every selected node was pinned on it already."""
        self.pinAxisClicked.emit(axis, box.checkState() != Qt.CheckState.Unchecked)

    def show_target(self, percent: float) -> None:
        self.target.blockSignals(True)
        self.target.setValue(percent)
        self.target.blockSignals(False)

    def show_shape(self, shape, basis=None, outside=None) -> None:
        """The lattice's node counts, and its basis (one name for all axes) and Outside
        option when given."""
        if outside is not None:
            self.outside_box.blockSignals(True)
            self.outside_box.setChecked(bool(outside))
            self.outside_box.blockSignals(False)
        if basis is not None:
            self.basis.blockSignals(True)
            at = self.basis.findData(basis[0] if len(set(basis)) == 1 else BERNSTEIN)
            self.basis.setCurrentIndex(max(at, 0))
            self.basis.blockSignals(False)
            self._basis_ranges()
        for s, v in zip(self.shape, shape):
            s.blockSignals(True)
            s.setValue(int(v))
            s.blockSignals(False)

    def basis_name(self) -> str:
        """The basis chosen in the lattice box (a name of :data:`BASIS_LABELS`)."""
        return str(self.basis.currentData())

    def outside(self) -> bool:
        """Blender's Outside option as the lattice box shows it (False for Bernstein)."""
        return self.outside_box.isEnabled() and self.outside_box.isChecked()

    def _basis_ranges(self) -> None:
        """The node-count range of the chosen basis on the spin boxes, and the Outside
        option offered for a local basis only."""
        local = self.basis_name() != BERNSTEIN
        self.outside_box.setEnabled(local)
        low, high = (MIN_LOCAL, MAX_LOCAL) if local else (MIN_NODES, MAX_NODES)
        for s in self.shape:
            s.setRange(low, high)

    def show_solve_state(self, text: str, color: str = "#c6ccd4") -> None:
        self.solve_state.setText(f'<span style="color:{color}">{text}</span>')


#: the lattice box's basis choice: name -> label (Blender's names for its interpolations)
BASIS_LABELS = {
    BERNSTEIN: "Bernstein (paper)",
    **{k: {"bspline": "B-Spline", "catmull-rom": "Catmull-Rom"}.get(k, k.title()) for k in KINDS},
}


def _role(axes: np.ndarray, moved: bool, held: bool) -> tuple[str, str]:
    """The colour and the words of one node's role (``axes``: its (3,) fixed axes)."""
    if moved:
        return style.MOVED, "moved by you: fixed until unpinned"
    if axes.all():
        return style.PINNED, "pinned"
    if axes.any():
        words = f"pinned on {axes_words(axes)} only: the solver moves it in {axes_words(~axes)}"
        return style.AXIS_PINNED, words
    if held:
        return style.HELD, "free, held for now so the model does not drift (Hold far side)"
    return style.FREE, "free: the solver moves it"
