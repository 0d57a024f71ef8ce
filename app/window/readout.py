"""What the window says and marks about the state on screen. GUI thread only.

- the status bar: the chip (:func:`~isochor.app.editor.state.describe_status`), the volume as drawn,
  the level, the solver's numbers and the time;
- the Solve panel's sentence and the Constraints group (the goal's settings, what the
  far-side anchor holds, each body's volume, the centre of mass);
- the marks on the view: each node's role (free, held, pinned on some axes, pinned, moved)
  and the folded part of a folded result.

:class:`Readout` reads the window's session and document and draws; it owns its labels on
the status bar and what it last drew as held.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtWidgets import QLabel

from ..editor.state import bodies_sentence, centroid_sentence, held_sentence
from ..view import style

#: status tone -> colour of the status chip and the Solve panel's sentence
TONES = {"neutral": "#8b95a5", "busy": style.MOVED, "good": style.FREE, "bad": style.PINNED}


class Readout:
    """The status bar's labels and the marks on the view, for one window.

    Attributes
    ----------
    state_label : the status chip
    volume_label : the volume as drawn, and its target
    level_label : the levels solved (or the level a solve is on)
    solver_label : the solver's numbers
    time_label : the solve's time
    held_mask : (n,) the nodes drawn as held by the far-side anchor
    held_face : their face's name ("" when none)
    """

    def __init__(self, win) -> None:
        self.win = win
        sb = win.statusBar()
        self.state_label = QLabel()
        self.volume_label = QLabel()
        self.level_label = QLabel()
        self.solver_label = QLabel()
        self.time_label = QLabel()
        for w in self.labels:
            sb.addPermanentWidget(w)
        self.held_mask = np.zeros(0, dtype=bool)  #: (n,) the nodes drawn as held
        self.held_face = ""  #: their face's name ("" when none)

    @property
    def labels(self) -> list[QLabel]:
        """The status bar's labels, left to right."""
        return [
            self.state_label,
            self.volume_label,
            self.level_label,
            self.solver_label,
            self.time_label,
        ]

    # -- the state ---------------------------------------------------------------------------
    def show_state(self) -> None:
        """Everything that belongs to the current state: roles, held nodes, folds, the
        goal's settings and notes."""
        win = self.win
        st = win.state
        goal = st.goal
        win.panel.goal.show_goal(goal, st.surface.bodies.count)
        acts = win.action_set
        for action, on in (
            (acts.anchor, goal.anchor == "far-side"),
            (acts.centroid, goal.keep_centroid),
            (acts.per_body, goal.preserve == "per-body"),
            (acts.fold_guard, goal.fold_guard),
        ):
            action.blockSignals(True)
            action.setChecked(bool(on))
            action.blockSignals(False)
        acts.per_body.setEnabled(st.surface.bodies.count > 1 or goal.preserve == "per-body")
        r = st.result if st.solved else None
        folded = r.folded_vertices if r is not None and win.doc.preserve else None
        win.viewport.scene.set_folds(folded)
        self.show_held()

    def show_held(self) -> None:
        """The node roles with what the far-side anchor holds now (the state's, or during a
        drag what a solve of the drag would hold), and the Constraints group's notes."""
        win = self.win
        st = win.state
        mask, face = win.doc.held()
        self.held_mask, self.held_face = mask, face
        win.viewport.scene.set_roles(st.pin_axes, st.moved, mask)
        r = st.result if st.solved and win.doc.drag is None else None
        stats = []
        if r is not None:
            stats = [bodies_sentence(r.bodies), centroid_sentence(r.centroid_shift)]
        win.panel.goal.show_notes(
            held_sentence(int(mask.sum()), face), "\n".join(s for s in stats if s)
        )

    # -- the status --------------------------------------------------------------------------
    def status_changed(self) -> None:
        win = self.win
        chip, tone, sentence = win.session.status()
        color = TONES[tone]
        self.state_label.setText(f'<span style="color:{color}">&#9679;</span> {chip}')
        win.panel.show_solve_state(sentence, color)
        r = win.state.result
        if win.doc.drag is not None and not win.session.busy():
            # the last solve's figures belong to the state before the drag: none stay on
            # screen (a live solve's records fill them in)
            for label in (self.level_label, self.solver_label, self.time_label):
                label.setText("")
            return
        if win.session.busy() or win.doc.drag is not None:
            return  # the progress records say what runs
        if r is None or not win.doc.preserve:
            for label in (self.level_label, self.solver_label, self.time_label):
                label.setText("")
            return
        self.level_label.setText(r.span())
        self.solver_label.setText(
            f"σ {r.sigma:.3g} · λ {r.lam:.3g} · |dV|/V0 {abs(r.rel_volume_error):.1e} (full mesh)"
        )
        self.time_label.setText(f"{1000 * r.elapsed:.0f} ms")

    def know_volume(self, nodes) -> None:
        """When ``nodes`` are the current state's solved nodes, give the view the full
        mesh's volume its solve measured (no full-mesh volume is computed for the frame)."""
        win = self.win
        st = win.state
        r = st.result
        if not (win.doc.preserve and st.solved and r is not None and r.levels):
            return
        if np.array_equal(np.asarray(nodes), st.nodes):
            rest = st.surface.rest_volume
            volume = rest * st.goal.target_ratio + r.rel_volume_error * abs(rest)
            win.viewport.scene.model.know_volume(nodes, volume)

    def frame(self, record) -> None:
        """The labels of a drawn frame: the volume as drawn, the progress record's numbers."""
        win = self.win
        st = win.state
        scene = win.viewport.scene
        pct = 100 * scene.volume / st.surface.rest_volume
        if scene.volume_estimated:  # a big model's proxy is drawn: never the full mesh's
            text = f"Volume ≈ {pct:.2f} % (preview; target {100 * st.goal.target_ratio:.4g} %)"
            tip = (
                "Estimated on the coarser version of the model drawn while it moves; "
                "measured on the full mesh when it stops."
            )
        else:
            text = f"Volume {pct:.2f} % (target {100 * st.goal.target_ratio:.4g} %)"
            tip = "The volume of the full mesh as drawn."
        self.volume_label.setText(text)
        self.volume_label.setToolTip(tip)
        if record is not None:
            self.level_label.setText(
                f"Level {record.level + 1}/{record.n_levels} · {record.triangles:,} triangles"
            )
            self.solver_label.setText(
                f"step {record.step} · σ {record.sigma:.3g} · λ "
                f"{record.lam:.3g} · |dV|/V0 {abs(record.rel_volume_error):.1e}"
            )
            self.time_label.setText(f"{1000 * record.elapsed:.0f} ms")
        if win.doc.drag is not None:
            self.show_held()

    def show_frame_volume(self, volume: float, target: float, frame: int) -> None:
        """The volume of a timeline frame as drawn (percent of the rest volume) and its
        own target (a ratio), in place of the working edit's."""
        self.volume_label.setText(
            f"Volume {volume:.2f} % (target {100 * target:.4g} % at frame {frame})"
        )
