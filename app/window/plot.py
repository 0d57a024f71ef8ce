"""The live convergence plot: node change and volume deviation against time, log scale.

Like the paper's Figures 5-8. While a solve runs, the node curve is the largest node
coordinate change between successive progress records (over the object size); when the
solve ends it is replaced by the paper's measure, each record's largest distance from the
final nodes (over the object size). The volume curve is |dV|/V0 of the level being solved.
Vertical lines mark where each pyramid level ended (levels counted from 1, coarsest first,
as in the status bar). Drawn with QPainter: matplotlib is not
a runtime dependency.
"""

from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt
from PySide6.QtGui import QColor, QFont, QPainter, QPainterPath, QPen
from PySide6.QtWidgets import QSizePolicy, QWidget

from ..view import style

FLOOR = 1e-8  # values below this are drawn at it


class ConvergencePlot(QWidget):
    """Call :meth:`reset` when a solve starts, :meth:`add` per progress record and
    :meth:`finish` with the final nodes; :meth:`update` repaints (with ``deferred``,
    :meth:`refresh` repaints what reset and finish changed)."""

    def __init__(self, parent=None, deferred: bool = False) -> None:
        super().__init__(parent)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setMinimumHeight(120)
        self.size_ref = 1.0
        self.tol_volume = 5e-4
        self.tol_nodes = 1e-3
        #: reset() and finish() leave the repaint to :meth:`refresh` (``stale``)
        self.deferred = deferred
        self.stale = False
        self.reset()

    def sizeHint(self) -> QSize:
        return QSize(520, 170)

    def reset(
        self, size_ref: float = 1.0, tol_volume: float = 5e-4, tol_nodes: float = 1e-3
    ) -> None:
        self.size_ref = float(size_ref) or 1.0
        self.tol_volume, self.tol_nodes = tol_volume, tol_nodes
        self.t: list[float] = []
        self.node_change: list[float] = []
        self.volume: list[float] = []
        self.nodes: list[np.ndarray] = []
        self.level_ends: list[tuple[float, int]] = []
        self.final = False
        self._changed()

    def add(
        self, t: float, nodes: np.ndarray, rel_volume_error: float, level: int, level_done: bool
    ) -> None:
        prev = self.nodes[-1] if self.nodes else None
        change = 0.0 if prev is None else float(np.max(np.abs(nodes - prev))) / self.size_ref
        self.t.append(float(t))
        self.nodes.append(np.asarray(nodes))
        self.node_change.append(change if prev is not None else math.nan)
        self.volume.append(abs(float(rel_volume_error)))
        if level_done:
            self.level_ends.append((float(t), int(level)))

    def finish(self, final_nodes: np.ndarray) -> None:
        """Switch the node curve to the distance from the final nodes (the paper's)."""
        if not self.nodes:
            return
        stack = np.stack(self.nodes)
        err = np.max(np.abs(stack - np.asarray(final_nodes)[None]), axis=(1, 2)) / self.size_ref
        self.node_change = [float(e) for e in err]
        self.final = True
        self._changed()

    def _changed(self) -> None:
        if self.deferred:
            self.stale = True
        else:
            self.update()

    def refresh(self) -> None:
        """Repaint now if anything changed (the window calls it with each frame, so that
        the plot is drawn with the frame: every repaint of a window that holds an OpenGL
        view composes the whole window again)."""
        if self.stale:
            self.stale = False
            self.update()

    # -- painting ----------------------------------------------------------------------------
    def paintEvent(self, ev) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        p.fillRect(self.rect(), QColor("#1b1e23"))
        font = QFont(self.font())
        font.setPointSizeF(max(7.0, font.pointSizeF() - 1))
        p.setFont(font)
        fm = p.fontMetrics()
        left, right, top, bottom = fm.horizontalAdvance("1e-10") + 12, 14, 24, fm.height() + 10
        plot = QRectF(
            left, top, max(10, self.width() - left - right), max(10, self.height() - top - bottom)
        )

        t = np.array(self.t)
        series = [
            (
                np.array(self.node_change),
                style.PLOT_NODES,
                "max node error vs final" if self.final else "max node change",
            ),
            (np.array(self.volume), style.PLOT_VOLUME, "|dV| / V0"),
        ]
        vals = np.concatenate([s[0] for s in series]) if len(t) else np.array([])
        vals = vals[np.isfinite(vals) & (vals > 0)]
        hi = max(1e-2, float(vals.max()) if len(vals) else 1e-2)
        lo = min(1e-6, float(vals.min()) if len(vals) else 1e-6, self.tol_volume / 10)
        lo_e = max(math.floor(math.log10(max(lo, FLOOR))), -8)
        hi_e = math.ceil(math.log10(hi))
        if hi_e <= lo_e:
            hi_e = lo_e + 1
        t_max = float(t.max()) if len(t) else 1.0
        t_max = t_max if t_max > 0 else 1.0

        def px(tt):
            return plot.left() + plot.width() * tt / t_max

        def py(v):
            e = math.log10(max(v, 10.0**lo_e))
            return plot.bottom() - plot.height() * (e - lo_e) / (hi_e - lo_e)

        grid = QPen(QColor("#2c313a"))
        axis_text = QColor("#8b95a5")
        p.setPen(grid)
        step = max(1, (hi_e - lo_e) // 5)
        for e in range(lo_e, hi_e + 1):
            y = py(10.0**e)
            p.setPen(grid)
            p.drawLine(QPointF(plot.left(), y), QPointF(plot.right(), y))
            if (e - lo_e) % step == 0:
                p.setPen(axis_text)
                label = f"1e{e}"
                p.drawText(
                    QRectF(0, y - fm.height() / 2, left - 6, fm.height()),
                    Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter,
                    label,
                )
        # time ticks
        for tt in _nice_ticks(t_max):
            x = px(tt)
            p.setPen(grid)
            p.drawLine(QPointF(x, plot.top()), QPointF(x, plot.bottom()))
            p.setPen(axis_text)
            p.drawText(
                QRectF(x - 30, plot.bottom() + 3, 60, fm.height()),
                Qt.AlignmentFlag.AlignHCenter,
                _fmt_time(tt),
            )
        # before the first record: the solver set its levels up (bases, volume operators)
        if len(t) and t[0] > 0.05 * t_max:
            band = QRectF(plot.left(), plot.top(), px(t[0]) - plot.left(), plot.height())
            p.fillRect(band, QColor(255, 255, 255, 10))
            label = "setting up levels"
            if band.width() > fm.horizontalAdvance(label) + 12:
                p.setPen(QColor("#6b7480"))
                p.drawText(band, Qt.AlignmentFlag.AlignCenter, label)
        # level ends
        for tt, k in self.level_ends:
            x = px(tt)
            p.setPen(QPen(QColor("#4d5563"), 1, Qt.PenStyle.DashLine))
            p.drawLine(QPointF(x, plot.top()), QPointF(x, plot.bottom()))
            p.setPen(QColor("#6b7480"))
            p.drawText(QPointF(x + 2, plot.top() + fm.ascent()), f"L{k + 1}")
        # tolerances
        for tol, color in (
            (self.tol_volume, style.PLOT_VOLUME),
            (self.tol_nodes, style.PLOT_NODES),
        ):
            c = QColor(color)
            c.setAlpha(110)
            p.setPen(QPen(c, 1, Qt.PenStyle.DotLine))
            y = py(tol)
            p.drawLine(QPointF(plot.left(), y), QPointF(plot.right(), y))
        # series
        p.setClipRect(plot.adjusted(-1, -1, 1, 1))
        for values, color, _ in series:
            path = QPainterPath()
            started = False
            for tt, v in zip(t, values):
                if not np.isfinite(v):
                    continue
                pt = QPointF(px(tt), py(max(v, FLOOR)))
                if started:
                    path.lineTo(pt)
                else:
                    path.moveTo(pt)
                    started = True
            p.setPen(QPen(QColor(color), 1.8))
            p.drawPath(path)
        p.setClipping(False)
        p.setPen(QPen(QColor("#3a404a")))
        p.drawRect(plot)
        # legend
        x = plot.left() + 4
        for _, color, label in series:
            p.setPen(QPen(QColor(color), 3))
            y = top / 2
            p.drawLine(QPointF(x, y), QPointF(x + 16, y))
            p.setPen(QColor("#c6ccd4"))
            p.drawText(QPointF(x + 22, y + fm.ascent() / 2 - 1), label)
            x += 22 + fm.horizontalAdvance(label) + 18
        p.setPen(axis_text)
        p.drawText(
            QRectF(plot.right() - 160, 0, 160, top),
            Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter,
            "dotted: tolerances",
        )
        p.end()


def _nice_ticks(t_max: float) -> list[float]:
    raw = t_max / 5
    mag = 10 ** math.floor(math.log10(raw)) if raw > 0 else 1
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    n = int(t_max / step + 1e-9)
    return [i * step for i in range(n + 1)]


def _fmt_time(t: float) -> str:
    if t == 0:
        return "0"
    if t < 1:
        return f"{t * 1000:.0f} ms"
    return f"{t:.3g} s"
