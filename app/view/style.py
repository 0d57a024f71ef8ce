"""Colours and the application look.

Node colours are from the Okabe-Ito palette, which stays distinguishable under the common
forms of colour blindness; the role of each colour is also spelled out in the legend.
"""

from __future__ import annotations

#: Okabe-Ito colours by node role.
FREE = "#56B4E9"  # sky blue: the solver may move it
PINNED = "#D55E00"  # vermillion: stays where it is
AXIS_PINNED = "#CC79A7"  # reddish purple: pinned on some axes, free on the others
MOVED = "#E69F00"  # orange: placed by the user, fixed until unpinned
HELD = "#009E73"  # bluish green: held by the solver so the model does not drift
SELECTED = "#F0E442"  # yellow, drawn larger
GUIDE = "#CC79A7"  # reddish purple: a guide line of no one axis
#: the world axes, as Blender and most 3D tools colour them: the gizmo's arrows and the
#: guide line of a locked axis
AXIS_COLOURS = {"x": "#F0435A", "y": "#7FCC1A", "z": "#3D8EF5"}
HANDLE = "#FF8C1A"  # a brighter orange than MOVED: a surface handle's target (a big sphere)

MODEL = "#d8d2c4"  # warm clay
FOLDED = "#ff2d55"  # the part of the model a result turned inside out
GHOST = "#9fb3c8"
CAPS = "#56B4E9"  # sky blue: the caps over an open model's holes, shown on demand
SPRING_AXIS = "#8b95a5"
SPRING_DIAGONAL = "#4d5563"
BACKGROUND_TOP = "#3a404a"
BACKGROUND_BOTTOM = "#16191e"

#: Plot series.
PLOT_NODES = FREE
PLOT_VOLUME = MOVED


def hex_to_rgb(color: str) -> tuple[int, int, int]:
    c = color.lstrip("#")
    return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)


#: the node shapes of each role, as the legend draws them (:mod:`isochor.app.view.glyphs`)
SHAPES = {"sphere": "&#9679;", "cube": "&#9632;", "diamond": "&#9670;", "ringed": "&#9673;"}


def legend_html() -> str:
    """The node legend of the 3D view (colour and shape of each role), as rich text."""

    def mark(color, shape, label):
        return f'<span style="color:{color}; font-size:14px">{SHAPES[shape]}</span>&nbsp;{label}'

    gap = "&nbsp;&nbsp;&nbsp;"
    first = [
        mark(FREE, "sphere", "free"),
        mark(PINNED, "cube", "pinned"),
        mark(MOVED, "ringed", "moved (fixed)"),
        f'<span style="color:{HANDLE}; font-size:18px">&#9679;</span>&nbsp;handle',
    ]
    halo = f'<span style="color:{SELECTED}; font-size:14px">&#9711;</span>&nbsp;selected'
    second = [
        mark(AXIS_PINNED, "diamond", "pinned on some axes"),
        mark(HELD, "sphere", "held (far side)"),
        halo,
    ]
    return gap.join(first) + "<br>" + gap.join(second)


def apply_dark_theme(app) -> None:
    """Fusion style with a dark palette: a calm frame around the 3D view."""
    from PySide6.QtGui import QColor, QPalette

    app.setStyle("Fusion")
    pal = QPalette()
    window, base, text = QColor("#23272e"), QColor("#1b1e23"), QColor("#e3e6eb")
    pal.setColor(QPalette.ColorRole.Window, window)
    pal.setColor(QPalette.ColorRole.WindowText, text)
    pal.setColor(QPalette.ColorRole.Base, base)
    pal.setColor(QPalette.ColorRole.AlternateBase, QColor("#2a2f37"))
    pal.setColor(QPalette.ColorRole.ToolTipBase, QColor("#2f343d"))
    pal.setColor(QPalette.ColorRole.ToolTipText, text)
    pal.setColor(QPalette.ColorRole.Text, text)
    pal.setColor(QPalette.ColorRole.Button, QColor("#2c313a"))
    pal.setColor(QPalette.ColorRole.ButtonText, text)
    pal.setColor(QPalette.ColorRole.BrightText, QColor("#ffffff"))
    pal.setColor(QPalette.ColorRole.Highlight, QColor("#0072B2"))
    pal.setColor(QPalette.ColorRole.HighlightedText, QColor("#ffffff"))
    pal.setColor(QPalette.ColorRole.Link, QColor(FREE))
    pal.setColor(QPalette.ColorRole.PlaceholderText, QColor("#7d8590"))
    for role in (
        QPalette.ColorRole.WindowText,
        QPalette.ColorRole.Text,
        QPalette.ColorRole.ButtonText,
    ):
        pal.setColor(QPalette.ColorGroup.Disabled, role, QColor("#6b727c"))
    app.setPalette(pal)
    app.setStyleSheet(STYLESHEET)


STYLESHEET = """
QMainWindow::separator { background: #1b1e23; width: 3px; height: 3px; }
QToolBar { background: #2a2f37; border: none; border-bottom: 1px solid #1b1e23;
           spacing: 2px; padding: 3px 6px; }
QToolBar QToolButton { color: #e3e6eb; padding: 4px 8px; border-radius: 4px; }
QToolBar QToolButton:hover { background: #363c46; }
QToolBar QToolButton:checked { background: #0072B2; color: white; }
QToolBar::separator { background: #3a404a; width: 1px; margin: 4px 6px; }
QDockWidget { color: #aab2bd; font-weight: 600; }
QDockWidget::title { background: #2a2f37; padding: 5px 8px; text-align: left; }
QGroupBox { border: 1px solid #343a44; border-radius: 6px; margin-top: 14px;
            padding: 8px 8px 6px 8px; }
QGroupBox::title { subcontrol-origin: margin; left: 10px; padding: 0 4px;
                   color: #8fa1b3; font-weight: 600; }
QStatusBar { background: #2a2f37; color: #c6ccd4; border-top: 1px solid #1b1e23; }
QStatusBar QLabel { padding: 0 8px; }
QPushButton { background: #343a44; border: 1px solid #3f4652; border-radius: 4px;
              padding: 4px 10px; }
QPushButton:hover { background: #3d4450; }
QPushButton:pressed { background: #0072B2; }
QDoubleSpinBox, QSpinBox { background: #1b1e23; border: 1px solid #3a404a;
                           border-radius: 4px; padding: 2px 4px; }
QLabel#overlay { background: rgba(22, 25, 30, 190); color: #e3e6eb; border-radius: 6px;
                 padding: 6px 10px; }
QLabel#hint { background: rgba(22, 25, 30, 150); color: #aab2bd; border-radius: 6px;
              padding: 4px 10px; }
"""
