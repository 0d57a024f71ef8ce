"""The session's drags: a node drag, a grab, rotate or scale, a handle drag, and the live
preview solves while one runs. A mixin of :class:`~isochor.app.session.controller.EditorSession`.

While "live" is on, the preview solve restarts (at most every :data:`LIVE_MS`) from the nodes
on screen with ``live=True``: it is solved on a coarse pyramid level only and never touches
the full mesh (:func:`isochor.core.solve.multilevel.solve`), so a frame of it costs milliseconds
even on a big model. The solve when the drag ends is the ordinary one, measured on the full
mesh.
"""

from __future__ import annotations

from ..editor.document import plural

LIVE_MS = 40  #: during a live drag, restart the preview solve at most this often


class DragMixin:
    """Needs the session's ``document``, ``live``, ``activity``, ``live_timer``, ``_pending``,
    ``_stop()``, ``_begin()``, ``commit()`` and ``statusChanged``."""

    # -- the drag ----------------------------------------------------------------------------
    def begin_drag(self, verb: str = "Move") -> bool:
        """Start a drag (or a grab, rotate or scale: ``verb``) of the selection."""
        return self._start_drag(lambda: self.document.begin_drag(verb))

    def begin_handle_drag(self, index: int | None = None, at=None) -> bool:
        """Start dragging handle ``index``'s target, or a new handle on the rest point
        ``at``; the drag's moves, finish and cancel are a node drag's."""
        return self._start_drag(lambda: self.document.begin_handle_drag(index, at))

    def _start_drag(self, begin) -> bool:
        """Stop the solve and start the drag ``begin()`` makes (False when it makes none)."""
        base = self.document.base_nodes()
        self._stop()
        self.document.live_nodes = base if self.document.preserve else None
        if begin() is None:
            return False
        self.activity = "dragging"
        self._pending = (base, None)
        self.statusChanged.emit()
        return True

    def drag_to(self, delta) -> None:
        """The dragged nodes moved by ``delta`` (3,) from where the drag started."""
        self._drag_by("move", delta)

    def drag_transform(self, matrix) -> None:
        """The dragged nodes mapped by the (4, 4) affine ``matrix`` from where they were."""
        self._drag_by("transform", matrix)

    def _drag_by(self, how: str, value) -> None:
        drag = self.document.drag
        if drag is None:
            return
        live = self._live_active()
        nodes = getattr(drag, how)(value, self.document.live_nodes if live else None)
        self._pending = (nodes, None)
        if live and not self.live_timer.isActive():
            self.live_timer.start()

    def finish_drag(self) -> None:
        self.live_timer.stop()
        self._near_next = self._live_active() and self.document.live_nodes is not None
        self._stop()
        self._live_preview = False
        self.activity = "idle"
        self.commit(self.document.end_drag())

    def cancel_drag(self) -> None:
        drag = self.document.drag
        if drag is None:
            return
        self._stop()
        self._live_preview = False
        self.document.cancel_drag()
        self.document.set_cell(drag.before)

    def drag_text(self, lock: str = "") -> str:
        drag = self.document.drag
        if drag is None:
            return ""
        lock = f" — locked to the {lock}" if lock else ""
        what = plural(len(drag.rows)) if len(drag.rows) else "the handle"
        return f"Moving {what}{lock} — X/Y/Z lock an axis, Shift+X/Y/Z a plane, Esc cancels"

    def _live_active(self) -> bool:
        return self.live and self.document.preserve

    def _live_solve(self) -> None:
        """Restart the preview solve from the nodes on screen (free nodes where the last
        preview left them, the dragged ones under the cursor)."""
        drag = self.document.drag
        if drag is None:
            return
        base = self.document.live_nodes if self.document.live_nodes is not None else drag.nodes
        self._solving_cell = None
        self._live_preview = True
        st = drag.before.state
        self._begin(st, drag.with_dragged(base), drag.fixed(), drag.handles, live=True)
