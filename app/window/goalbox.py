"""The Inspector's "Constraints" group: what the solve holds besides the volume (and the
symmetry of the edit), and what the last solve says about it (what it held, each body's
volume, the centre of mass).

The boxes only emit what the user clicked; the window commits the edit and shows the new
state with :meth:`GoalBox.show_goal` (which never emits).
"""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QComboBox, QGroupBox, QHBoxLayout, QLabel, QVBoxLayout

from ..view import style

#: the volume choice's items: (text, the goal's ``preserve``)
VOLUME_CHOICES = (("Total", "total"), ("Each body", "per-body"))
#: the symmetry choice's items: (text, the goal's ``symmetry``)
SYMMETRY_CHOICES = (("Off", "none"), ("X", "x"), ("Y", "y"), ("Z", "z"))

ANCHOR_TIP = (
    "When your pins leave the lattice free to slide or turn, hold the lattice face farthest "
    "from the nodes you moved, so the model stretches instead of drifting away. Untick it to "
    "let the whole model move."
)
CENTROID_TIP = "Also keep the solid's centre of mass where it was (three more constraints)."
VOLUME_TIP = (
    "Total: the whole model keeps its volume (one part may grow while another shrinks). "
    "Each body: every separate part keeps its own volume. Needs a model of several bodies."
)
SYMMETRY_TIP = (
    "Mirror every move, pin, transform and handle across the lattice's middle plane "
    "across X, Y or Z, so the result stays symmetric. Turning it on mirrors the side of "
    "the selection (or the more edited side) onto the other."
)
FOLD_TIP = (
    "Push back when the deformation nearly turns part of the model inside out, so the "
    "solver does not meet the volume by folding the model."
)


class GoalBox(QGroupBox):
    """Signals
    -------
    anchorClicked(bool) : Hold far side was clicked (on or off)
    centroidClicked(bool) : Keep centre of mass
    preserveChosen(str) : "total" or "per-body"
    foldGuardClicked(bool) : Fold guard
    symmetryChosen(str) : "none", "x", "y" or "z"
    """

    anchorClicked = Signal(bool)
    centroidClicked = Signal(bool)
    preserveChosen = Signal(str)
    foldGuardClicked = Signal(bool)
    symmetryChosen = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__("Constraints", parent)
        lay = QVBoxLayout(self)
        self.anchor_box = QCheckBox("Hold f&ar side")
        self.anchor_box.setToolTip(ANCHOR_TIP)
        self.anchor_box.setChecked(True)
        self.anchor_box.clicked.connect(
            lambda *_: self.anchorClicked.emit(self.anchor_box.isChecked())
        )
        self.centroid_box = QCheckBox("&Keep centre of mass")
        self.centroid_box.setToolTip(CENTROID_TIP)
        self.centroid_box.clicked.connect(
            lambda *_: self.centroidClicked.emit(self.centroid_box.isChecked())
        )
        row = QHBoxLayout()
        label = QLabel("Vol&ume")
        self.volume_choice = QComboBox()
        for text, mode in VOLUME_CHOICES:
            self.volume_choice.addItem(text, mode)
        self.volume_choice.setToolTip(VOLUME_TIP)
        label.setBuddy(self.volume_choice)
        label.setToolTip(VOLUME_TIP)
        self.volume_choice.activated.connect(
            lambda i: self.preserveChosen.emit(self.volume_choice.itemData(i))
        )
        row.addWidget(label)
        row.addWidget(self.volume_choice, 1)
        srow = QHBoxLayout()
        slabel = QLabel("S&ymmetry")
        self.symmetry_choice = QComboBox()
        for text, value in SYMMETRY_CHOICES:
            self.symmetry_choice.addItem(text, value)
        self.symmetry_choice.setToolTip(SYMMETRY_TIP)
        slabel.setBuddy(self.symmetry_choice)
        slabel.setToolTip(SYMMETRY_TIP)
        self.symmetry_choice.activated.connect(
            lambda i: self.symmetryChosen.emit(self.symmetry_choice.itemData(i))
        )
        srow.addWidget(slabel)
        srow.addWidget(self.symmetry_choice, 1)
        self.fold_box = QCheckBox("F&old guard")
        self.fold_box.setToolTip(FOLD_TIP)
        self.fold_box.setChecked(True)
        self.fold_box.clicked.connect(
            lambda *_: self.foldGuardClicked.emit(self.fold_box.isChecked())
        )
        lay.addWidget(self.anchor_box)
        lay.addWidget(self.centroid_box)
        lay.addLayout(row)
        lay.addLayout(srow)
        lay.addWidget(self.fold_box)
        self.held_note = QLabel("")
        self.held_note.setWordWrap(True)
        self.held_note.hide()
        self.stats = QLabel("")
        self.stats.setWordWrap(True)
        self.stats.hide()
        lay.addWidget(self.held_note)
        lay.addWidget(self.stats)

    def show_goal(self, goal, bodies: int) -> None:
        """Show the settings of ``goal`` (a :class:`isochor.core.goal.spec.Goal`); "Each
        body" only for a model of several bodies."""
        for box, on in (
            (self.anchor_box, goal.anchor == "far-side"),
            (self.centroid_box, goal.keep_centroid),
            (self.fold_box, goal.fold_guard),
        ):
            box.blockSignals(True)
            box.setChecked(bool(on))
            box.blockSignals(False)
        self.volume_choice.blockSignals(True)
        self.volume_choice.setCurrentIndex(self.volume_choice.findData(goal.preserve))
        self.volume_choice.blockSignals(False)
        several = bodies > 1
        self.volume_choice.setEnabled(several or goal.preserve == "per-body")
        tip = VOLUME_TIP if several else VOLUME_TIP + " This model is one body."
        self.volume_choice.setToolTip(tip)

    def show_symmetry(self, symmetry: str) -> None:
        """Show the state's symmetry (never emits)."""
        self.symmetry_choice.blockSignals(True)
        self.symmetry_choice.setCurrentIndex(self.symmetry_choice.findData(symmetry))
        self.symmetry_choice.blockSignals(False)

    def show_notes(self, held: str, stats: str) -> None:
        """What the far-side anchor holds, and the per-body and centre-of-mass statistics
        ("" hides a line)."""
        dot = f'<span style="color:{style.HELD}">&#9679;</span> '
        self.held_note.setText(dot + held if held else "")
        self.held_note.setVisible(bool(held))
        self.stats.setText(stats)
        self.stats.setVisible(bool(stats))
