"""The window's timeline (issue 13): the Timeline dock's panel, scrubbing and playing (its
actions and keys are :class:`~isochor.app.window.actions.ActionSet`'). GUI thread only; the
edit rules are the document's (:mod:`isochor.app.editor.timelinerules`), what a frame shows
is :mod:`isochor.app.editor.timeline`'s (whose notes say what the artist sees) and the
frames are solved in the background by
:class:`~isochor.app.session.framesolver.FrameSolver`.

Playing shows the solved frames at the timeline's rate, looping; frames not solved yet are
skipped (while the background solve goes on, the loop grows as frames are solved).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject, Qt, QTimer
from PySide6.QtWidgets import QLabel

from ...core.errors import IsochorError
from ...core.scenario.poses import Pose
from ..editor import timelinerules
from ..editor.state import StateCell
from ..editor.timeline import describe, frame_fixed, frame_nodes, frame_target, pose_of, same_pose
from ..session.commands import GoToKeyCommand
from ..session.framesolver import FrameSolver
from .timelinebar import TimelinePanel


class TimelineTool(QObject):
    """The current frame, what the view shows, the background solve of the frames and
    playing, for one window.

    Attributes
    ----------
    panel : the Timeline dock's :class:`~isochor.app.window.timelinebar.TimelinePanel`
    label : the status bar's word on the frame on screen
    frame : the current frame
    showing : the view shows the frame's pose (between keys), not the working edit
    shown : (n, 3) the nodes shown for the frame, or None (the working edit is shown)
    solved : the shown frame is solved
    playing : playing
    solver : the :class:`~isochor.app.session.framesolver.FrameSolver` of the frames
    """

    def __init__(self, win) -> None:
        super().__init__(win)
        self.win = win
        self.frame = 0
        self.showing = False
        self.shown: np.ndarray | None = None
        self.solved = False
        self.playing = False
        self.solver = FrameSolver(win.session, self)
        self.panel = TimelinePanel()
        self.label = QLabel("")
        self.label.setMinimumWidth(1)  # its text never widens the window
        win.statusBar().insertPermanentWidget(0, self.label)
        # the working edit last seen (its problem and pose): an edit of it leaves the frame
        self._pose: tuple[object, Pose] | None = None
        self.play_timer = QTimer(self)
        self.play_timer.timeout.connect(self._tick)

    @property
    def doc(self):
        return self.win.session.document

    def connect_signals(self) -> None:
        win, s, p = self.win, self.win.session, self.panel
        s.documentLoaded.connect(self.loaded)
        s.stateChanged.connect(self.state_changed)
        fs = self.solver
        s.statusChanged.connect(self._drag_started)
        s.statusChanged.connect(fs.schedule)
        s.idle.connect(fs.schedule)
        s.solveStarted.connect(fs.stop)
        win.viewport.firstPainted.connect(fs.view_ready, Qt.ConnectionType.QueuedConnection)
        fs.frameSolved.connect(self._frame_solved)
        fs.changed.connect(self.refresh)
        win.action_set.preserve.toggled.connect(lambda _on: self.refresh())
        p.frameChosen.connect(self.go_to)
        p.scrubber.frameScrubbed.connect(lambda f: self.go_to(f, scrub=True))
        p.scrubber.scrubReleased.connect(self.go_to)
        p.rangeEdited.connect(
            lambda a, b: self._commit(lambda: timelinerules.edit_frame_range(self.doc.base(), a, b))
        )
        p.rateEdited.connect(
            lambda r: self._commit(
                lambda: timelinerules.edit_timeline_setting(self.doc.base(), "rate", r)
            )
        )
        p.interpolationChosen.connect(
            lambda name: self._commit(
                lambda: timelinerules.edit_timeline_setting(self.doc.base(), "interpolation", name)
            )
        )
        self.loaded()

    # -- the document ------------------------------------------------------------------------
    def loaded(self) -> None:
        """A new document: its first frame, its working edit shown, the old frames gone."""
        self.stop_playing(restore=False)
        self.solver.reset()
        self.frame = self.doc.state.timeline.start
        self.showing = False
        self._pose = None
        self.state_changed()

    def state_changed(self) -> None:
        """After every change of the current state: an edit of the working pose shows it
        again; another timeline selects its frame cache."""
        st = self.doc.state
        pose = (st.problem, pose_of(st, 0))
        old, self._pose = self._pose, pose
        edited = old is not None and (
            old[0] is not pose[0] or not same_pose(old[1], pose[1], st.lattice)
        )
        if edited or not st.timeline.keys:
            self.showing = False
            if edited:
                self.stop_playing(restore=False)
        self.solver.follow(st)
        self.frame = st.timeline.clamp(self.frame)
        self.refresh()  # (the session's statusChanged that follows starts the frames' solve)

    def _drag_started(self) -> None:
        """A drag, a G/R/S gesture or a handle drag moves the working edit: show it."""
        if self.doc.drag is not None and (self.showing or self.playing):
            self.playing = False
            self.play_timer.stop()
            self.showing = False
            self.refresh()

    @property
    def cache(self):
        """The :class:`~isochor.app.editor.timeline.FrameCache` of the current timeline, or None."""
        return self.solver.cache

    def _commit(self, rule) -> None:
        try:
            edit = rule()
        except IsochorError as exc:
            self.win.statusBar().showMessage(str(exc), 6000)
            self.refresh()
            return
        if edit is not None:
            self.win.commit_edit(edit)
            self.win.statusBar().showMessage(edit.text, 4000)

    # -- keys --------------------------------------------------------------------------------
    def set_key(self) -> None:
        if self.doc.drag is not None:
            return
        edit = timelinerules.edit_set_key(self.doc.base(), self.frame)
        if edit is None:
            self.win.statusBar().showMessage(f"Frame {self.frame} holds this key already.", 4000)
            return
        # keying the working edit, not the frame that was on screen: say so
        note = ": the working pose, not the frame that was shown" if self.showing else ""
        self.showing = False
        self.win.commit_edit(edit)
        self.win.statusBar().showMessage(f"{edit.text}{note}.", 6000)

    def remove_key(self) -> None:
        if self.doc.drag is not None:
            return
        edit = timelinerules.edit_remove_key(self.doc.base(), self.frame)
        if edit is None:
            self.win.statusBar().showMessage(f"There is no key at frame {self.frame}.", 4000)
            return
        self.win.commit_edit(edit)
        self.win.statusBar().showMessage(f"{edit.text}.", 4000)

    def _go_to_key(self, frame: int) -> None:
        """Load key ``frame``'s edit as the working edit (one merged undo step)."""
        doc = self.doc
        solved = None
        if self.cache is not None and doc.preserve:
            solved = self.cache.keys.get(frame)
        edit = timelinerules.edit_go_to_key(doc.base(), frame, solved)
        if edit is not None:
            self.win.frames.keep_camera()
            cmd = GoToKeyCommand(doc, edit.text, doc.cell, StateCell(edit.state))
            self.win.session.undo_stack.push(cmd)

    # -- going to a frame ------------------------------------------------------------------
    def go_to(self, frame: int, scrub: bool = False) -> None:
        """Make ``frame`` current. On a key frame (not while scrubbing or playing) the key's
        edit becomes the working edit; elsewhere the view shows the frame."""
        if self.doc.drag is not None:
            self.refresh()
            return
        tl = self.doc.state.timeline
        self.frame = tl.clamp(frame)
        if not tl.keys:
            self.showing = False
        elif scrub or self.playing or self.frame not in tl.key_frames:
            self.showing = True
        else:
            self.showing = False
            self._go_to_key(self.frame)
        self.refresh()

    def step(self, by: int) -> None:
        self.stop_playing(restore=False)
        self.go_to(self.frame + by)

    def go_to_end(self, side: int) -> None:
        self.stop_playing(restore=False)
        tl = self.doc.state.timeline
        self.go_to(tl.start if side < 0 else tl.end)

    def jump_key(self, direction: int) -> None:
        tl = self.doc.state.timeline
        frame = tl.next_key(self.frame) if direction > 0 else tl.previous_key(self.frame)
        if frame is None:
            where = "after" if direction > 0 else "before"
            self.win.statusBar().showMessage(f"No key {where} frame {self.frame}.", 3000)
            return
        self.stop_playing(restore=False)
        self.go_to(frame)

    # -- playing ---------------------------------------------------------------------------------
    def toggle_play(self) -> None:
        if self.playing:
            self.stop_playing()
            return
        if not self.doc.state.timeline.keys:
            self.win.statusBar().showMessage("Set a key (I) to have something to play.", 4000)
            return
        if self.doc.drag is not None:
            return
        self.playing = True
        self.showing = True
        self.play_timer.start(max(1, round(1000 / self.doc.state.timeline.rate)))
        self.refresh()

    def stop_playing(self, restore: bool = True) -> None:
        """Stop; ``restore``: settle on the frame as a click there would (a key loads)."""
        if not self.playing:
            return
        self.playing = False
        self.play_timer.stop()
        if restore:
            self.go_to(self.frame)
        else:
            self.refresh()

    def _tick(self) -> None:
        """The next solved frame (unsolved ones are skipped), looping."""
        solved = sorted(self.cache.frames) if self.cache is not None else []
        if solved:
            self.frame = next((f for f in solved if f > self.frame), solved[0])
        self.showing = True
        self.refresh()

    # -- what is shown ---------------------------------------------------------------------------
    def refresh(self) -> None:
        """The panel, the scrubber, the words and the view for the current frame."""
        win = self.win
        st = self.doc.state
        tl = st.timeline
        self.solved = False
        was_shown = self.shown is not None
        if self.showing and tl.keys:
            self.shown, self.solved = frame_nodes(tl, st.lattice, self.cache, self.frame)
            pins, moved = frame_fixed(tl, st.lattice, self.frame)
            win.viewport.scene.set_roles(pins, moved)
        else:
            if self.shown is not None:
                win.readout.show_held()  # the working edit's node roles again
            self.shown = None
        solved, unconverged = frame_states(self.cache)
        showing = self.showing and bool(tl.keys)
        key = tl.key_at(self.frame)
        keyed = key is not None and same_pose(pose_of(st, self.frame), key, st.lattice)
        shown = showing or (keyed and not self.showing)  # the frame's own pose is on screen
        self.panel.show_timeline(tl, self.frame, solved, shown, self.playing, unconverged)
        info = describe(tl, self.frame, showing, self.solved, keyed)
        self.label.setText(self._short(showing, keyed) if tl.keys else "")
        self.label.setToolTip(info)
        if self.playing:
            info = f"Playing at {tl.rate:g} fps (frames not solved yet are skipped) — {info}"
        self.panel.show_text(info, self.solver.progress())
        if self.playing:
            self.play_timer.setInterval(max(1, round(1000 / tl.rate)))
        if was_shown or self.shown is not None:
            win.session.redraw()

    def drawn(self) -> None:
        """After the window drew a frame: the volume's target is the frame's own."""
        if self.shown is None:
            return
        win = self.win
        st = self.doc.state
        target = frame_target(st.timeline, self.frame)
        volume = 100 * win.viewport.model_volume / st.surface.rest_volume
        win.readout.show_frame_volume(volume, target, self.frame)

    def _short(self, showing: bool, keyed: bool) -> str:
        """The status bar's word on the frame: ``"Frame 5 · solved"``."""
        if showing:
            what = "solved" if self.solved else "not solved yet"
        else:
            what = f"key {self.frame}" if keyed else "working pose"
        return f"Frame {self.frame} · {what}"

    def _frame_solved(self, frame) -> None:
        if self.showing and (frame.key or frame.frame == self.frame):
            self.refresh()  # the frame on screen (or its interpolated start) is better now
            return
        tl = self.doc.state.timeline
        p = self.panel
        solved = self.cache.frames
        shown = p.scrubber.shown
        p.scrubber.show_frames(tl.start, tl.end, self.frame, tl.key_frames, solved, shown)
        p.progress.setText(self.solver.progress())

    def shutdown(self) -> None:
        self.play_timer.stop()
        self.solver.shutdown()


def frame_states(cache) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The frames solved (the keys' own solves too) and, of them, those that did not
    converge; the frames in neither are pending."""
    if cache is None:
        return (), ()
    solved = set(cache.frames) | set(cache.keys)
    bad = set(cache.unconverged)
    bad |= {f for f, r in cache.keys.items() if r is not None and not r.converged}
    return tuple(sorted(solved)), tuple(sorted(bad))
