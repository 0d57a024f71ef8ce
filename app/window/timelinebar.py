"""The Timeline dock's widgets: the scrubber (the frame range with the current frame, the keys
as diamonds and a band over every solved frame) and the panel around it (play and key
buttons, the current frame, the range, the rate, the interpolation, the progress of the
background solve and what the view shows).

The widgets only emit what the user did; the window (:mod:`isochor.app.window.timelinetools`)
commits the edits and shows the state with :meth:`TimelinePanel.show_timeline`, which never
emits. GUI thread only.
"""

from __future__ import annotations

from PySide6.QtCore import QPointF, QRectF, QSize, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPainterPath, QPen
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QSpinBox,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from ...core.scenario.poses import INTERPOLATIONS, MAX_FRAMES
from ..editor.timeline import RATE_RANGE
from ..view import style
from .panel import guard_wheel

TRACK = "#1b1e23"
TICK = "#5b6370"
LABEL = "#8b95a5"
SOLVED = style.HELD  # green: a converged frame
UNCONVERGED = style.FOLDED  # red: a frame whose solve did not converge
PENDING = "#3a404a"  # dim: a frame not solved yet
KEY = style.SELECTED  # yellow diamonds, as Blender's selected keys
CURRENT = style.FREE  # blue: the current frame
#: the scrubber's side margins, so that the first and last frames' marks fit
MARGIN = 14
#: label steps the ruler chooses from (frames between two numbers)
STEPS = (1, 2, 5, 10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 5000, 10000)


class Scrubber(QWidget):
    """The frame range as a ruler: click or drag to go to a frame.

    Signals
    -------
    frameScrubbed(int) : the mouse is on this frame (pressed or dragging)
    scrubReleased(int) : the mouse was released on this frame
    """

    frameScrubbed = Signal(int)
    scrubReleased = Signal(int)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.start, self.end, self.current = 0, 24, 0
        self.keys: tuple[int, ...] = ()
        self.solved: frozenset[int] = frozenset()
        self.unconverged: frozenset[int] = frozenset()  #: solved, not converged
        self.shown = True  #: the current frame's pose is on screen (False: the working edit)
        self._dragging = False
        self.setMinimumHeight(46)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.setCursor(Qt.CursorShape.PointingHandCursor)
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)  # then the arrows and Space are its
        self.setToolTip(
            "Click or drag to go to a frame; diamonds are keys. Under each frame: green "
            "converged, red not converged, grey not solved yet"
        )

    def sizeHint(self) -> QSize:
        return QSize(480, 46)

    # -- geometry (also what the tests use to click a frame) -----------------------------------
    def x_of(self, frame: float) -> float:
        span = max(1, self.end - self.start)
        return MARGIN + (frame - self.start) / span * (self.width() - 2 * MARGIN)

    def frame_at(self, x: float) -> int:
        span = max(1, self.end - self.start)
        f = self.start + (x - MARGIN) / max(1.0, self.width() - 2 * MARGIN) * span
        return int(min(max(round(f), self.start), self.end))

    def show_frames(self, start, end, current, keys, solved, shown: bool, unconverged=()) -> None:
        self.start, self.end, self.current = int(start), int(end), int(current)
        self.keys, self.solved, self.shown = tuple(keys), frozenset(solved), shown
        self.unconverged = frozenset(unconverged)
        self.update()

    def state_of(self, frame: int) -> str:
        """``"converged"``, ``"not converged"`` or ``"pending"``: what the band under
        ``frame`` shows."""
        if frame in self.unconverged:
            return "not converged"
        return "converged" if frame in self.solved else "pending"

    # -- painting ------------------------------------------------------------------------------
    def paintEvent(self, _ev) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        w, h = self.width(), self.height()
        p.fillRect(QRectF(0, 14, w, h - 14), QColor(TRACK))
        cell = (w - 2 * MARGIN) / max(1, self.end - self.start)
        # a band under every frame: green converged, red (taller) not converged, dim pending
        bands = {
            "converged": (QColor(SOLVED), 5),
            "not converged": (QColor(UNCONVERGED), 8),
            "pending": (QColor(PENDING), 3),
        }
        for f in range(self.start, self.end + 1):
            colour, tall = bands[self.state_of(f)]
            x = self.x_of(f)
            p.fillRect(QRectF(x - cell / 2, h - 2 - tall, max(cell, 1.5), tall), colour)
        # the ruler: a tick per frame when there is room, a number every few frames
        step = next((s for s in STEPS if s * cell >= 36), STEPS[-1])
        p.setPen(QPen(QColor(TICK), 1))
        every = cell >= 4
        first = self.start - self.start % step
        for f in range(self.start, self.end + 1):
            if every or f % step == 0:
                x = self.x_of(f)
                top = 14 if f % step == 0 else 22
                p.drawLine(QPointF(x, top), QPointF(x, 26))
        font = p.font()
        font.setPointSizeF(max(7.0, font.pointSizeF() - 1.5))
        p.setFont(font)
        p.setPen(QColor(LABEL))
        for f in range(first, self.end + 1, step):
            if f >= self.start:
                x = self.x_of(f)
                p.drawText(QRectF(x - 20, 0, 40, 13), Qt.AlignmentFlag.AlignCenter, str(f))
        # the keys
        for f in self.keys:
            if self.start <= f <= self.end:
                self._diamond(p, self.x_of(f), 32, 6.5, QColor(KEY))
        # the current frame
        x = self.x_of(self.current)
        colour = QColor(CURRENT)
        p.setPen(QPen(colour, 2))
        p.drawLine(QPointF(x, 14), QPointF(x, h))
        label = QRectF(x - 16, 0, 32, 14)
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(colour if self.shown else QColor(TICK))
        p.drawRoundedRect(label, 3, 3)
        p.setPen(QColor("#101317"))
        p.drawText(label, Qt.AlignmentFlag.AlignCenter, str(self.current))
        p.end()

    @staticmethod
    def _diamond(p: QPainter, x: float, y: float, r: float, colour: QColor) -> None:
        path = QPainterPath()
        path.moveTo(x, y - r)
        path.lineTo(x + r, y)
        path.lineTo(x, y + r)
        path.lineTo(x - r, y)
        path.closeSubpath()
        p.setPen(QPen(QColor("#101317"), 1))
        p.setBrush(colour)
        p.drawPath(path)

    # -- the mouse -----------------------------------------------------------------------------
    def mousePressEvent(self, ev) -> None:
        if ev.button() == Qt.MouseButton.LeftButton:
            self._dragging = True
            self.frameScrubbed.emit(self.frame_at(ev.position().x()))

    def mouseMoveEvent(self, ev) -> None:
        if self._dragging:
            frame = self.frame_at(ev.position().x())
            if frame != self.current:
                self.frameScrubbed.emit(frame)

    def mouseReleaseEvent(self, ev) -> None:
        if self._dragging and ev.button() == Qt.MouseButton.LeftButton:
            self._dragging = False
            self.scrubReleased.emit(self.frame_at(ev.position().x()))


def _tool(text: str) -> QToolButton:
    b = QToolButton()
    b.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
    b.setAutoRaise(True)
    b.setText(text)
    return b


def _frame_spin(tip: str) -> QSpinBox:
    s = QSpinBox()
    s.setRange(-MAX_FRAMES, MAX_FRAMES)
    s.setKeyboardTracking(False)  # one edit on Enter, not one per digit
    s.setToolTip(tip)
    s.setAlignment(Qt.AlignmentFlag.AlignRight)
    s.setMaximumWidth(76)
    return s


class TimelinePanel(QWidget):
    """The Timeline dock's contents.

    Signals
    -------
    frameChosen(int) : the Frame box was set
    rangeEdited(int, int) : the Start or End box was set (start, end)
    rateEdited(float) : frames a second
    interpolationChosen(str) : "linear" or "smooth"
    """

    frameChosen = Signal(int)
    rangeEdited = Signal(int, int)
    rateEdited = Signal(float)
    interpolationChosen = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("timeline")
        lay = QVBoxLayout(self)
        lay.setContentsMargins(8, 2, 8, 4)
        lay.setSpacing(2)
        row = QHBoxLayout()
        row.setSpacing(4)
        self.buttons = {
            name: _tool(text)
            for name, text in (
                ("first", "|◀"),
                ("prev_key", "◆◀"),
                ("play", "▶"),
                ("next_key", "▶◆"),
                ("last", "▶|"),
                ("set_key", "◆ Set key"),
                ("remove_key", "◇ Remove"),
            )
        }
        for name in ("first", "prev_key", "play", "next_key", "last"):
            row.addWidget(self.buttons[name])
        self.frame = _frame_spin("The current frame")
        self.frame.valueChanged.connect(self.frameChosen.emit)
        self.start = _frame_spin("The first frame to solve and play")
        self.end = _frame_spin("The last frame to solve and play")
        for box in (self.start, self.end):
            guard_wheel(box)
            box.valueChanged.connect(
                lambda _=0: self.rangeEdited.emit(self.start.value(), self.end.value())
            )
        self.rate = QDoubleSpinBox()
        self.rate.setRange(*RATE_RANGE)
        self.rate.setDecimals(2)
        self.rate.setMaximumWidth(96)
        self.rate.setKeyboardTracking(False)
        self.rate.setSuffix(" fps")
        self.rate.setToolTip("Frames a second, for playing")
        guard_wheel(self.rate)
        self.rate.valueChanged.connect(self.rateEdited.emit)
        self.interpolation = QComboBox()
        for name in INTERPOLATIONS:
            self.interpolation.addItem(name.title(), name)
        self.interpolation.setToolTip(
            "Between two keys the fixed nodes move on a straight path: at an even pace "
            "(Linear) or starting and stopping at rest (Smooth)"
        )
        self.interpolation.activated.connect(
            lambda i: self.interpolationChosen.emit(self.interpolation.itemData(i))
        )
        for text, box in (
            ("Frame", self.frame),
            ("Start", self.start),
            ("End", self.end),
            ("", self.rate),
            ("", self.interpolation),
        ):
            if text:
                label = QLabel(text)
                label.setBuddy(box)
                row.addWidget(label)
            row.addWidget(box)
        row.addWidget(self.buttons["set_key"])
        row.addWidget(self.buttons["remove_key"])
        row.addStretch(1)
        play = self.buttons["play"]
        play.setFixedWidth(play.fontMetrics().horizontalAdvance("❚❚▶") + 12)
        self.progress = QLabel("")
        self.progress.setStyleSheet(f"color: {LABEL};")
        self.progress.setMinimumWidth(1)  # a longer text never widens the window
        row.addWidget(self.progress)
        lay.addLayout(row)
        self.scrubber = Scrubber()
        lay.addWidget(self.scrubber)
        self.info = QLabel("")
        self.info.setStyleSheet(f"color: {LABEL};")
        self.info.setMinimumWidth(1)
        lay.addWidget(self.info)

    def use_actions(self, actions: dict) -> None:
        """Give the buttons their actions (name -> QAction): a click triggers the action,
        the tooltip names its shortcut."""
        for name, action in actions.items():
            button = self.buttons[name]
            text = button.text()
            button.setDefaultAction(action)
            button.setText(text)
            keys = action.shortcut().toString()
            tip = action.toolTip() or action.text().replace("&", "")
            button.setToolTip(f"{tip} ({keys})" if keys else tip)

    def show_timeline(
        self, tl, frame: int, solved, shown: bool, playing: bool, unconverged=()
    ) -> None:
        """Show the timeline ``tl`` (:class:`~isochor.app.editor.timeline.TimelineState`) at
        ``frame``; ``solved`` frames, of which ``unconverged`` did not converge; the frame's
        pose is ``shown`` (never emits)."""
        for box, lo, hi, value in (
            (self.frame, tl.start, tl.end, frame),
            (self.start, -MAX_FRAMES, MAX_FRAMES, tl.start),
            (self.end, -MAX_FRAMES, MAX_FRAMES, tl.end),
        ):
            box.blockSignals(True)
            box.setRange(lo, hi)
            box.setValue(value)
            box.blockSignals(False)
        self.rate.blockSignals(True)
        self.rate.setValue(tl.rate)
        self.rate.blockSignals(False)
        self.interpolation.blockSignals(True)
        self.interpolation.setCurrentIndex(self.interpolation.findData(tl.interpolation))
        self.interpolation.blockSignals(False)
        self.buttons["play"].setText("❚❚" if playing else "▶")
        self.scrubber.show_frames(
            tl.start, tl.end, frame, tl.key_frames, solved, shown, unconverged
        )

    def show_text(self, info: str, progress: str) -> None:
        self.info.setText(info)
        self.progress.setText(progress)
