"""One frame of the view drawn in passes, one pass per event-loop turn, and shown whole at
the end (:class:`Composer`). GUI thread only.

Why: in software OpenGL (llvmpipe, no GPU) one render of the 346k armadillo's full mesh
holds the GUI thread 45-60 ms, twice a frame of its 21.6k proxy; a press landing on it
waits for all of it. Drawn in passes of :data:`~isochor.app.view.meshprep.STEP_FACES`
triangles, a press waits for one pass (5-16 ms on an idle machine), and the frame is shown
by a paint that draws only what is translucent or overlaid (see docs/BENCHMARKS.md).

How: VTK renders into a framebuffer of its own and copies it to the one Qt composes only
when the render window swaps buffers. With swapping off, a render adds to that
framebuffer and shows nothing; with the renderer's erase off it keeps the colours and
depths earlier passes drew. So the first pass draws the background and the opaque actors
but the model; each next pass draws one piece of the model (an actor on a range of its
triangles in draw order, sharing the full mesh's points and arrays, so nothing is
uploaded twice), depth-tested against everything before; the view's next paint
(:meth:`Composer.showing`) draws what is translucent, two-dimensional or on the overlay
layer on top and swaps. Opaque triangles tested against one depth buffer give the same
pixels in any order (but where two are at exactly the same depth; none differed on the
346k armadillo, the bunny with its caps, ghost and gizmo, or the tests' torus). Each pass
is flushed (llvmpipe rasterises when flushed, so its cost stays in its own turn). A render
that is not a pass (anything repainting the view meanwhile), or a change to any actor or
the camera between passes, starts the passes again.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

#: passes started again at most this often for one frame (then its paint renders it whole)
MAX_RESTARTS = 3


def _props(renderer) -> list:
    items = renderer.GetViewProps()
    items.InitTraversal()
    return [items.GetNextProp() for _ in range(items.GetNumberOfItems())]


def _renderers(window) -> list:
    items = window.GetRenderers()
    items.InitTraversal()
    return [items.GetNextItem() for _ in range(items.GetNumberOfItems())]


def _opaque(prop) -> bool:
    """A 3D actor with nothing translucent: drawn in the passes, not in the last paint."""
    return bool(prop.IsA("vtkActor") and not prop.HasTranslucentPolygonalGeometry())


class Composer:
    """Draws one frame of ``renderer`` (in ``window``) in passes.

    :meth:`passes` runs them (a generator: one render a step), with ``pieces`` (hidden
    actors that together draw the model) in place of ``held`` (the model's own actors,
    which the frame shows but the passes do not draw); :meth:`showing` wraps the view's
    paint that shows the frame. ``ready`` says the passes are done and nothing has changed
    since.
    """

    def __init__(self, window, renderer) -> None:
        self.window = window
        self.renderer = renderer
        self.ready = False
        self.passes_drawn = 0  #: passes rendered (restarts included), for the tests
        self.restarts = 0  #: passes started again because the scene changed meanwhile
        self.shown = 0  #: composed frames shown (the others rendered as always)
        self.pass_seconds: list[float] = []  #: how long each pass of the last frame took
        self._mine = False  # a render of ours is running
        self._rendered = False  # the render window did render (not when it cannot: hidden)
        self._spoiled = False  # something else rendered since the last pass
        self._stamp: tuple | None = None
        self._drawn: list = []  # what the passes drew: hidden in the last paint
        window.AddObserver("StartEvent", self._started)

    def _started(self, *_args) -> None:
        self._rendered = True
        if not self._mine:
            self._spoiled = True
            self.ready = False

    def stamp(self) -> tuple:
        """What the frame depends on: every actor's redraw time (its data, property,
        visibility) and the camera's."""
        stamps = [self.renderer.GetActiveCamera().GetMTime()]
        for r in _renderers(self.window):
            stamps.append(r.GetMTime())
            stamps.extend(p.GetRedrawMTime() for p in _props(r))
        return tuple(stamps)

    def cancel(self) -> None:
        """The frame being drawn is not wanted (the model moved)."""
        self.ready = False
        self._stamp = None

    def passes(self, pieces: Sequence, held: Sequence) -> Iterator[None]:
        """The passes, one render a step (yields between them). Afterwards the caller makes
        ``held`` visible as the frame wants them and calls :meth:`arm`."""
        self.ready = False
        self._drawn = []
        self.pass_seconds = []
        for _ in range(MAX_RESTARTS + 1):
            drawn = yield from self._passes(list(pieces), list(held))
            if drawn is not None:
                self._drawn = drawn
                return
            if not self._rendered:  # (a hidden view draws nothing: its next paint will)
                return
            self.restarts += 1

    def _passes(self, pieces: list, held: list) -> Iterator[None]:
        self._spoiled = False
        own = {id(a) for a in pieces + held}
        props = _props(self.renderer)
        opaque = [p for p in props if id(p) not in own and p.GetVisibility() and _opaque(p)]
        if not self._render(props, opaque, erase=True):
            return None
        for piece in pieces:
            yield
            if self._spoiled or self.stamp() != self._stamp:
                return None
            if not self._render(props, [piece], erase=False):
                return None
        yield
        if self._spoiled or self.stamp() != self._stamp:
            return None
        return opaque + pieces + held

    def _render(self, props: list, shown: list, erase: bool) -> bool:
        """One pass: only ``shown`` of the renderer's actors drawn, the other renderers (the
        overlay layer) not at all, nothing shown on screen. False when the window did not
        render (a view not on screen)."""
        others = [r for r in _renderers(self.window) if r is not self.renderer]
        visible = [p.GetVisibility() for p in props]
        swap = self.window.GetSwapBuffers()
        keep = {id(p) for p in shown}
        t0 = time.perf_counter()
        self._mine, self._rendered = True, False
        try:
            for p in props:
                p.SetVisibility(id(p) in keep)
            for r in others:
                r.SetDraw(False)
            self.renderer.SetErase(erase)
            self.window.SetSwapBuffers(False)
            self.window.Render()
            self.window.WaitForCompletion()  # (llvmpipe rasterises when flushed: here)
            self.passes_drawn += 1
        finally:
            self.window.SetSwapBuffers(swap)
            self.renderer.SetErase(True)
            for r in others:
                r.SetDraw(True)
            for p, v in zip(props, visible, strict=True):
                p.SetVisibility(v)
            self._mine = False
        self._stamp = self.stamp()
        self.pass_seconds.append(time.perf_counter() - t0)
        return self._rendered

    def arm(self) -> None:
        """The passes are done and the model's actors show the frame: the next paint shows
        it (:meth:`showing`)."""
        self.ready = bool(self._drawn) and not self._spoiled
        self._stamp = self.stamp()

    @contextmanager
    def showing(self) -> Iterator[bool]:
        """A context for the view's paint (it says whether it shows a composed frame): when
        the frame is ready and nothing changed since, the paint draws only what the passes
        did not (translucent, 2D, the overlay layer) on top of them and shows it; otherwise
        it renders as always."""
        show = self.ready and not self._spoiled and self.stamp() == self._stamp
        self.ready, self._stamp = False, None
        if not show:
            yield False
            return
        drawn = {id(p) for p in self._drawn}
        hidden = [p for p in _props(self.renderer) if id(p) in drawn and p.GetVisibility()]
        self._mine = True
        try:
            for p in hidden:
                p.SetVisibility(False)
            self.renderer.SetErase(False)
            self.shown += 1
            yield True
        finally:
            self.renderer.SetErase(True)
            for p in hidden:
                p.SetVisibility(True)
            self._mine = False
