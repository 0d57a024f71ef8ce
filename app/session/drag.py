"""The session's drags: a node drag, a grab, rotate or scale, a handle drag, and the live
preview solves while one runs. A part of
:class:`~isochor.app.session.controller.EditorSession`.

:class:`SessionDrag` owns what is the drag's own: the live switch, the timer of the preview
solves and whether the solve after the drag starts near its last frame. The drag itself
(where it started, where its nodes are) is the document's
(:meth:`isochor.app.editor.document.Document.begin_drag`). Everything else a drag does to
the session goes through the :class:`DragHost` the session hands it: stop the solve, show
nodes, start a preview, commit the edit, say what the session is doing.

While "live" is on, the preview solve restarts (at most every :data:`LIVE_MS`) from the nodes
on screen with ``live=True``: it is solved on a coarse pyramid level only and never touches
the full mesh (:func:`isochor.core.solve.multilevel.solve`), so a frame of it costs milliseconds
even on a big model. The solve when the drag ends is the ordinary one, measured on the full
mesh.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from PySide6.QtCore import QObject, QTimer

from ..editor.document import DocState, Document, Edit, plural

LIVE_MS = 40  #: during a live drag, restart the preview solve at most this often


@dataclass(frozen=True)
class DragHost:
    """What a drag may do to its session: the whole interface between the two.

    Attributes
    ----------
    document : returns the session's current document
    stop : stops the running solve (its queued records are dropped)
    show : draws these (n, 3) nodes at the next frame
    preview : starts a live preview solve of ``(state, nodes, fixed, handles)``: the state
        whose goal to hold, the nodes on screen, the (n, 3) fixed coordinates, the handles
    commit : pushes an edit as one undo step (None: nothing to do)
    activity : sets what the session is doing (``"dragging"``, ``"idle"``), silently
    told : tells the session's listeners that its status changed
    """

    document: Callable[[], Document]
    stop: Callable[[], None]
    show: Callable[[np.ndarray], None]
    preview: Callable[[DocState, np.ndarray, np.ndarray, tuple], None]
    commit: Callable[[Edit | None], bool]
    activity: Callable[[str], None]
    told: Callable[[], None]


class SessionDrag:
    """The drags of one editing session and their live previews.

    Parameters
    ----------
    host : what the drag may do to the session (:class:`DragHost`)
    parent : the QObject that owns the preview timer (the session)
    """

    def __init__(self, host: DragHost, parent: QObject | None = None) -> None:
        self.host = host
        self._live = False
        #: the timer of the preview solves: one restart at most every LIVE_MS
        self.timer = QTimer(parent)
        self.timer.setSingleShot(True)
        self.timer.setInterval(LIVE_MS)
        self.timer.timeout.connect(self._preview)
        #: the next solve starts from a live drag's last frame (read once: :meth:`take_near`)
        self.near_next = False

    # -- starting ------------------------------------------------------------------------------
    def begin(self, verb: str = "Move") -> bool:
        """Start a drag (or a grab, rotate or scale: ``verb``) of the selection."""
        return self._start(lambda doc: doc.begin_drag(verb))

    def begin_handle(self, index: int | None = None, at=None) -> bool:
        """Start dragging handle ``index``'s target, or a new handle on the rest point ``at``;
        the drag's moves, finish and cancel are a node drag's."""
        return self._start(lambda doc: doc.begin_handle_drag(index, at))

    def _start(self, begin: Callable[[Document], object]) -> bool:
        """Stop the solve and start the drag ``begin(document)`` makes (False when it makes
        none)."""
        host = self.host
        doc = host.document()
        base = doc.base_nodes()
        host.stop()
        doc.show_live(base if doc.preserve else None)
        if begin(doc) is None:
            return False
        host.activity("dragging")
        host.show(base)
        host.told()
        return True

    # -- moving --------------------------------------------------------------------------------
    def move(self, delta) -> None:
        """The dragged nodes moved by ``delta`` (3,) from where the drag started."""
        self._drag_by("move", delta)

    def transform(self, matrix) -> None:
        """The dragged nodes mapped by the (4, 4) affine ``matrix`` from where they were."""
        self._drag_by("transform", matrix)

    def _drag_by(self, how: str, value) -> None:
        doc = self.host.document()
        drag = doc.drag
        if drag is None:
            return
        live = self.live_active()
        nodes = getattr(drag, how)(value, doc.live_nodes if live else None)
        self.host.show(nodes)
        if live and not self.timer.isActive():
            self.timer.start()

    # -- ending --------------------------------------------------------------------------------
    def finish(self) -> None:
        """The drag ends: its edit is committed, and solved from its last live frame."""
        host = self.host
        doc = host.document()
        self.timer.stop()
        self.near_next = self.live_active() and doc.live_nodes is not None
        host.stop()
        host.activity("idle")
        before = doc.drag.before if doc.drag is not None else None
        if not host.commit(doc.end_drag()) and before is not None:
            doc.set_cell(before)  # nothing moved: the state from before (no live preview)

    def cancel(self) -> None:
        """The drag ends without an edit: the state from before it comes back."""
        doc = self.host.document()
        drag = doc.drag
        if drag is None:
            return
        self.host.stop()
        doc.cancel_drag()
        doc.set_cell(drag.before)

    def stop_previews(self) -> None:
        """No preview solve is started any more (one that runs is the session's to stop)."""
        self.timer.stop()

    def take_near(self) -> bool:
        """Whether the solve starting now starts near a live drag's last frame (once)."""
        near, self.near_next = self.near_next, False
        return near

    # -- what it says --------------------------------------------------------------------------
    def text(self, lock: str = "") -> str:
        """What the view says while the drag runs ("" with none); ``lock``: the axis or
        plane it is locked to."""
        drag = self.host.document().drag
        if drag is None:
            return ""
        lock = f" — locked to the {lock}" if lock else ""
        what = plural(len(drag.rows)) if len(drag.rows) else "the handle"
        return f"Moving {what}{lock} — X/Y/Z lock an axis, Shift+X/Y/Z a plane, Esc cancels"

    @property
    def live(self) -> bool:
        """Solve while dragging (live previews)."""
        return self._live

    def set_live(self, on: bool) -> None:
        self._live = bool(on)

    def live_active(self) -> bool:
        """Live previews run: live is on and so is the volume constraint."""
        return self._live and self.host.document().preserve

    def _preview(self) -> None:
        """Restart the preview solve from the nodes on screen (free nodes where the last
        preview left them, the dragged ones under the cursor)."""
        doc = self.host.document()
        drag = doc.drag
        if drag is None:
            return
        base = doc.live_nodes if doc.live_nodes is not None else drag.nodes
        st = drag.before.state
        self.host.preview(st, drag.with_dragged(base), drag.fixed(), drag.handles)
