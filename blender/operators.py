"""The add-on's operators: Preserve volume (one solve on a background thread, the operator
modal meanwhile: progress in the status bar and the header, Esc cancels), Live (re-solves
while points move), Bake (a frame range), Measure (the volume read-out: an open mesh's
capped volume, the report line saying how many holes were capped). Each solve is one undo
step; bad input is one line in the report area and changes nothing."""

from __future__ import annotations

import bpy

from .caps import add_caps
from .export import write_scenario
from .scene import RigError, Target, Volumes, holes_capped
from .solving import LiveSolver, Settings, Solve, bake


def _settings(context) -> Settings:
    props = context.scene.isochor
    preserve = "per-body" if props.preserve == "BODIES" else "total"
    return Settings(props.pins, props.group, props.ratio, preserve)


def _errors():
    """The exceptions that are bad input (one line), not bugs."""
    from isochor import IsochorError

    return (RigError, IsochorError)


def _line(exc: Exception) -> str:
    """The one line for the report area."""
    line = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return line if line.startswith("Isochor:") else f"Isochor: {line}"


def measure(context, target: Target) -> Volumes:
    """The read-out set to the volume the solve keeps (an open mesh's capped volume)."""
    props = context.scene.isochor
    volumes = target.volumes()
    props.volume, props.volume_ratio, props.holes = volumes.now, volumes.ratio, volumes.holes
    return volumes


class ISOCHOR_OT_preserve_volume(bpy.types.Operator):
    """Solve the free lattice points so the mesh keeps its volume (or the target ratio);
    it solves in the background (Esc cancels)"""

    bl_idname = "isochor.preserve_volume"
    bl_label = "Preserve Volume"
    bl_options = {"REGISTER", "UNDO"}

    _job: Solve | None = None
    _timer = None

    def _start(self, context) -> bool:
        try:
            self._job = Solve(Target.of(context.active_object), _settings(context))
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return False
        return True

    def _finish(self, context):
        job, self._job = self._job, None
        try:
            error = job.finish()
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return {"CANCELLED"}
        volumes = measure(context, job.target)
        self.report({"INFO"}, f"Isochor: volume kept within {abs(error):.1e}{volumes.capped()}")
        return {"FINISHED"}

    def execute(self, context):  # scripts, and Blender without a window: waits for the solve
        if not self._start(context):
            return {"CANCELLED"}
        self._job.wait()
        return self._finish(context)

    def invoke(self, context, event):
        if context.window is None:
            return self.execute(context)
        if not self._start(context):
            return {"CANCELLED"}
        self._timer = context.window_manager.event_timer_add(0.1, window=context.window)
        context.window_manager.modal_handler_add(self)
        self._show(context, "Isochor: solving… (Esc cancels)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC" and event.value == "PRESS":
            job.cancel()
        if event.type != "TIMER":
            return {"RUNNING_MODAL"} if event.type == "ESC" else {"PASS_THROUGH"}
        if job.running:
            self._show(
                context,
                f"Isochor: {'solving' if job.stage == 'solve' else 'preparing'} "
                f"{100 * job.fraction:.0f} % (Esc cancels)",
            )
            return {"RUNNING_MODAL"}
        context.window_manager.event_timer_remove(self._timer)
        self._show(context, None)
        return self._finish(context)

    @staticmethod
    def _show(context, text) -> None:
        """The progress in the status bar and the 3D view's header (None clears them)."""
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        if context.area is not None:
            context.area.header_text_set(text)


class ISOCHOR_OT_measure(bpy.types.Operator):
    """Measure the volume of the mesh as Blender evaluates it"""

    bl_idname = "isochor.measure"
    bl_label = "Measure Volume"

    def execute(self, context):
        try:
            volumes = measure(context, Target.of(context.active_object))
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return {"CANCELLED"}
        self.report(
            {"INFO"},
            f"Isochor: volume {volumes.now:.6g}, {100 * volumes.ratio:.2f} % of rest"
            f"{volumes.capped()}",
        )
        return {"FINISHED"}


class ISOCHOR_OT_bake(bpy.types.Operator):
    """Solve every frame of the keyframed lattice points over the range and key the result"""

    bl_idname = "isochor.bake"
    bl_label = "Bake"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        props = context.scene.isochor
        try:
            target = Target.of(context.active_object)
            errors = bake(target, _settings(context), props.frame_start, props.frame_end)
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return {"CANCELLED"}
        volumes = measure(context, target)
        worst = max(abs(e) for e in errors)
        self.report(
            {"INFO"},
            f"Isochor: baked {len(errors)} frames, volume within {worst:.1e}{volumes.capped()}",
        )
        return {"FINISHED"}


class ISOCHOR_OT_live(bpy.types.Operator):
    """Re-solve while pinned lattice points move (Esc stops)"""

    bl_idname = "isochor.live"
    bl_label = "Live"
    bl_options = {"REGISTER", "UNDO"}

    _solver: LiveSolver | None = None
    _timer = None

    def invoke(self, context, event):
        props = context.scene.isochor
        if props.live:  # pressed again: stop
            props.live = False
            return {"CANCELLED"}
        try:
            self._solver = LiveSolver(Target.of(context.active_object), _settings(context))
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return {"CANCELLED"}
        props.live = True
        self._timer = context.window_manager.event_timer_add(0.04, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        props = context.scene.isochor
        if event.type == "ESC" or not props.live:
            return self._end(context)
        if event.type == "TIMER":
            try:
                running = self._solver.tick()
                if not running and self._solver.last is not None:
                    measure(context, self._solver.target)
            except _errors() as exc:
                self.report({"ERROR"}, _line(exc))
                return self._end(context)
            if context.area is not None:
                context.area.tag_redraw()
        return {"PASS_THROUGH"}

    def _end(self, context):
        context.scene.isochor.live = False
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
        if self._solver is not None:
            self._solver.stop()
        return {"FINISHED"}


class ISOCHOR_OT_export_scenario(bpy.types.Operator):
    """Write the scene's problem as an Isochor scenario (JSON) and its mesh (OBJ), for
    `isochor solve` and the Isochor editor"""

    bl_idname = "isochor.export_scenario"
    bl_label = "Export Isochor Scenario"

    filepath: bpy.props.StringProperty(subtype="FILE_PATH")
    filter_glob: bpy.props.StringProperty(default="*.json", options={"HIDDEN"})

    def invoke(self, context, event):
        if not self.filepath:
            self.filepath = "scenario.json"
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        if not self.filepath:
            self.report({"ERROR"}, "Isochor: give the scenario a file name")
            return {"CANCELLED"}
        try:
            target = Target.of(context.active_object)
            scenario, model = write_scenario(
                target, _settings(context), bpy.path.abspath(self.filepath)
            )
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Isochor: wrote {scenario.name} and {model.name}")
        return {"FINISHED"}


class ISOCHOR_OT_add_caps(bpy.types.Operator):
    """Close the active mesh's holes with Isochor's caps as real geometry, so that
    Blender measures the volume a solve keeps"""

    bl_idname = "isochor.add_caps"
    bl_label = "Add Caps"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            holes = add_caps(context.active_object)
        except _errors() as exc:
            self.report({"ERROR"}, _line(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Isochor: {holes_capped(holes)}" if holes else "Isochor: no holes")
        return {"FINISHED"}


CLASSES = (
    ISOCHOR_OT_add_caps,
    ISOCHOR_OT_preserve_volume,
    ISOCHOR_OT_measure,
    ISOCHOR_OT_bake,
    ISOCHOR_OT_live,
    ISOCHOR_OT_export_scenario,
)
