"""The in-process renderer: one GL context, resident pipelines, one frame per call.

Used directly by the render worker process (and by tests/tools that own their process).
Every public method makes the renderer's context current first (context.py: the one rule for GL
contexts), so another context created or released in the same thread cannot take its calls.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..scene.model import Scene
from . import bindings, depth, gl_calls, presets, rehearsal
from .context import capabilities, create_context, make_current, release_context
from .frame import FrameState, build_frame
from .graph import FrameGraph
from .memo import Memo
from .multiview import ChannelGroup, draw_channels, release_view_state
from .overload import FrameQuality
from .readback import ReadbackRing
from .scaling import Upscaler, scaled_scene
from .shaders import ProgramCache
from .targets import Targets


@dataclass
class RenderResult:
    rgba: np.ndarray  # (height, width, 4) uint8, top row first
    passes: list[str]
    pass_ms: dict[str, float] = field(default_factory=dict)  # only when timed
    total_ms: float = 0.0
    quality: str = "medium"  # the quality level (or auto rung) the frame was rendered at
    # the frame's operating point (render/overload.py Decision.fields: scale, rungs, error, target_fps,
    # met); target_fps 0 when the scene holds no frame rate
    overload: dict | None = None
    ev100: float = 0.0  # exposure used (EV100)
    illuminance_lux: float = 0.0  # natural horizontal illuminance at the camera (lux)
    # Only when timed: per pass, CPU ms of the calling thread (llvmpipe: vertex work, triangle setup,
    # binning, Python) and of all other threads (llvmpipe: rasterisation and fragment shading).
    pass_cpu_ms: dict[str, tuple[float, float]] = field(default_factory=dict)
    host_frame: int = 0  # of the scene drawn: a frame returned later (frames in flight) names its own state
    sim_time: float = 0.0  # s, of the scene drawn
    # A scene with channels (docs/channels.md): each channel's frame by id, in the scene's order (same
    # exposure, host_frame, sim_time); ``rgba`` is then all of them side by side (scene/channels.py
    # mosaic_layout) and pass_ms the sum over the channels. None for a scene without channels.
    channels: dict[str, "RenderResult"] | None = None


@dataclass
class _Drawn:
    """A frame whose passes are queued and whose pixels are not read yet."""

    result: RenderResult  # rgba and total_ms filled in when the pixels are read
    targets: Targets
    start: float  # perf_counter s when the frame began
    drawn_at: float  # perf_counter s when its last pass was queued
    timed: bool
    queue_ms: float = 0.0  # ms to queue the readback (frames in flight)
    views: list | None = None  # a frame of channels: its multiview.ChannelView list (targets per channel)
    meter: object = None  # its meter cells (post/meter_lag.MeterTicket): read with its pixels at the latest


class Renderer:
    def __init__(self, ctx: moderngl.Context | None = None, device_index: int | None = None,
                 frames_in_flight: int = 1, atmosphere_direct: bool = False):
        self._ctx = make_current(ctx) if ctx is not None else create_context(device_index)
        self.caps = capabilities(self._ctx)
        self.reversed_z = depth.enable_reversed_z(self._ctx)  # clip depth [0, 1]; else the fallback
        # atmosphere_direct (a quality-study setting, off in production): every pass walks the 4D
        # atmosphere tables per pixel instead of reading the per-frame sky-view table, the reference
        # for that table's cost and image error.
        study = {"ATMOSPHERE_DIRECT_TABLES": 1} if atmosphere_direct else {}
        self.programs = ProgramCache(self._ctx, {**depth.shader_defines(self._ctx), **study})
        self.graph = FrameGraph(self._ctx, self.programs)
        self._targets: Targets | None = None
        self._channel_targets: dict[str, Targets] = {}
        self.channel_meters: dict = {}  # the post pass's meter texture of each channel (render/multiview.py)
        self.channel_meter_copies: dict = {}  # and its asynchronous copy (post/meter_lag.py MeterCopy)
        self.view_states: dict = {}  # each channel's per-view pass state (multiview.swap_view_state)
        self._channel_upscalers: dict[str, Upscaler] = {}  # below scale 1: each channel's upscale and output
        self.frames_rendered = 0
        self.frame_quality = FrameQuality()  # the overload controller, when a scene holds a frame rate
        # internal render scale (render/scaling.py): below 1 the passes draw at scale x the requested
        # size and the upscale pass makes the requested size; 1.0 = no scaled targets, no extra pass
        self.render_scale = 1.0
        self._upscaler: Upscaler | None = None
        self.frame_state = FrameState()  # eased fog, eye adaptation: carried between frames
        # Channels rendered by several renderers (igserver/cluster): the one (EV100, metered luminance cd/m^2)
        # every renderer applies, decided by their front from the union of their meters (None: this
        # renderer's own meter and eye), and the meter cells of the last frame with channels returned (linear
        # RGB, cd/m^2), which the front unites
        self.exposure_override: tuple[float, float] | None = None
        self.meter_cells: np.ndarray | None = None
        # submit(): frames drawn whose pixels are still being copied out (pixel buffers of the ring)
        self.frames_in_flight = frames_in_flight
        self._in_flight: deque = deque()
        self._readback: ReadbackRing | None = None

    def quality_for(self, scene: Scene):
        """(knobs, render scale, operating point) of this frame: the scene's preset at ``render_scale``,
        or the overload controller's point when the scene holds a frame rate."""
        decision = self.frame_quality.decide(scene, self.render_scale)
        if self.frame_quality.controller is None:
            return scene.quality.preset, self.render_scale, decision
        return decision.point.rung, decision.point.scale, decision

    @property
    def ctx(self) -> moderngl.Context:
        """The renderer's GL context, made current: callers that use it directly (quality tools,
        tests' compute probes) are then on the right context whatever was created meanwhile."""
        return make_current(self._ctx)

    def targets_for(self, width: int, height: int) -> Targets:
        if self._targets is None or self._targets.size != (width, height):
            if self._targets is not None:
                self._targets.release()
            self._targets = Targets(self.ctx, width, height)
        return self._targets

    def channel_targets(self, cid: str, width: int, height: int) -> Targets:
        """The render targets of channel ``cid`` (each channel keeps its own until the frame is read)."""
        held = self._channel_targets.get(cid)
        if held is None or held.size != (width, height):
            if held is not None:
                held.release()
            held = self._channel_targets[cid] = Targets(self.ctx, width, height)
        return held

    def channel_upscaler(self, cid: str) -> Upscaler:
        """Channel ``cid``'s upscale pass and its output target (kept until the frame is read)."""
        if cid not in self._channel_upscalers:
            self._channel_upscalers[cid] = Upscaler(self.ctx, self.programs)
        return self._channel_upscalers[cid]

    def release_channel_upscaler(self, cid: str) -> None:
        held = self._channel_upscalers.pop(cid, None)
        if held is not None:
            held.dispose()

    def release_channel_targets(self, keep: set[str]) -> None:
        for cid in [c for c in self._channel_upscalers if c not in keep]:
            self.release_channel_upscaler(cid)
        for cid in [c for c in self._channel_targets if c not in keep]:
            self._channel_targets.pop(cid).release()
            meter = self.channel_meters.pop(cid, None)
            if meter is not None:
                meter.release()
            copy = self.channel_meter_copies.pop(cid, None)
            if copy is not None:
                copy.release()
            release_view_state(self.view_states.pop(cid, {}))

    def render_channels(self, scene: Scene, timed: bool = False) -> dict[str, RenderResult]:
        """Every channel of ``scene`` (one state, one exposure) by channel id; a scene without channels
        gives its camera's frame under the id ``""``."""
        result = self.render(scene, timed)
        return result.channels if result.channels is not None else {"": result}

    def render(self, scene: Scene, timed: bool = False) -> RenderResult:
        """Render ``scene`` and return its frame; with ``timed`` each pass is bracketed by ctx.finish()
        and a wall clock. Frames submitted before and not yet collected stay in flight."""
        # A scene with channels renders them all (RenderResult.channels); its drawn "targets" are the
        # channels' group (multiview.ChannelGroup), read as their mosaic.
        drawn = self._draw(scene, timed)
        t0 = time.perf_counter()
        data = drawn.targets.ldr_fbo.read(components=4, alignment=1)
        width, height = drawn.targets.size
        rgba = np.ascontiguousarray(np.frombuffer(data, dtype=np.uint8).reshape(height, width, 4)[::-1])
        if timed:
            drawn.result.pass_ms["readback"] = (time.perf_counter() - t0) * 1e3
        result = self._finished(drawn, rgba, time.perf_counter())
        if not timed:  # a timed frame waits for every pass: not the cost of a frame
            self.frame_quality.observe(result.total_ms, result.passes)
        return result

    def rehearse(self, scene: Scene, report=None) -> dict:
        """Draw ``scene`` unseen with the changes a host most often makes (a fire, lights, rain, snow, the
        sea's states), so that their programs are compiled before a stream needs them; the stream's state
        is put back; ``report(done, total)`` after each scene (render/rehearsal.py). Returns {"scenes",
        "programs", "seconds"}."""
        return rehearsal.rehearse(self, scene, report)

    def submit(self, scene: Scene, timed: bool = False) -> RenderResult | None:
        """Draw ``scene`` and queue its readback without waiting for it; return the oldest frame in
        flight once ``frames_in_flight`` frames are queued (else None). A stream calls this once per
        frame, so frame N's pixels are copied out while frame N+1 is drawn; ``collect`` takes the rest.
        Each result carries the host_frame and sim_time of the scene it was drawn from."""
        cycle_start = time.perf_counter()
        drawn = self._draw(scene, timed)
        t0 = time.perf_counter()
        ticket = self._readback_ring().start(drawn.targets.ldr_fbo, drawn.targets.size)
        gl_calls.flush()  # hand the copy to the driver now, not at the next frame's first wait
        drawn.queue_ms = (time.perf_counter() - t0) * 1e3
        self._in_flight.append((drawn, ticket))
        if len(self._in_flight) <= self.frames_in_flight:
            return None
        # a timed frame waits for every pass: the cycle that draws it is not the cost of a frame
        return self.collect(cycle_start, measured=not timed)

    def collect(self, cycle_start: float | None = None, measured: bool = True) -> RenderResult | None:
        """The oldest submitted frame not yet returned (waiting for its copy if needed), or None.
        ``cycle_start`` (submit's): when the frame's successor began, so the controller sees the
        render thread's cycle (draw N+1, then wait for N's pixels: on llvmpipe N's rasterisation
        overlaps N+1's draw, and the cycle is what sets the stream's rate); None (a frame collected
        on its own, the stream idle): its draw and readback. ``measured`` False: the controller
        does not see this frame's time."""
        if not self._in_flight:
            return None
        make_current(self._ctx)
        drawn, ticket = self._in_flight.popleft()
        t0 = time.perf_counter()
        rgba = self._readback.take(ticket)
        end = time.perf_counter()
        if drawn.timed:  # queueing the copy plus taking it: the readback's cost to the calling thread
            drawn.result.pass_ms["readback"] = drawn.queue_ms + (end - t0) * 1e3
        # the frame's time: its draw plus taking its pixels, not the wait while it was in flight
        result = self._finished(drawn, rgba, drawn.drawn_at + (end - t0))
        if measured and not drawn.timed:
            cycle_ms = (end - cycle_start) * 1e3 if cycle_start is not None else result.total_ms
            self.frame_quality.observe(cycle_ms, result.passes)
        return result

    @property
    def in_flight(self) -> int:
        """Frames submitted and not yet collected."""
        return len(self._in_flight)

    def _readback_ring(self) -> ReadbackRing:
        if self._readback is None:
            self._readback = ReadbackRing(self._ctx, self.frames_in_flight + 1)
        return self._readback

    def _finished(self, drawn: "_Drawn", rgba: np.ndarray, end: float) -> RenderResult:
        result = drawn.result
        # Its meter cells, copied out with its pixels in a stream (done now: no wait), if its
        # successor's post pass has not read them already.
        cells = drawn.meter.cells() if drawn.meter is not None else None
        if drawn.views is not None and cells is not None:
            self.meter_cells = cells
        result.rgba = rgba
        result.total_ms = (end - drawn.start) * 1e3
        if drawn.views is not None:  # each channel's pixels, cut from the mosaic
            for cid, x, width, height in drawn.targets.layout:
                part = result.channels[cid]
                part.rgba, part.total_ms = np.ascontiguousarray(rgba[:height, x:x + width]), result.total_ms
        return result

    def _draw(self, scene: Scene, timed: bool) -> "_Drawn":
        """Every pass of ``scene`` queued into the LDR target; the frame's result without its pixels."""
        if scene.channels:
            result, views, start = draw_channels(self, scene, timed)
            return _Drawn(result, ChannelGroup(views), start, time.perf_counter(), timed, views=views,
                          meter=views[0].frame.resources.get("meter_ticket"))
        Memo.slots = 1
        if self._channel_targets:  # the channels are gone: their targets and tables with them
            self.release_channel_targets(keep=set())
        start = time.perf_counter()
        make_current(self._ctx)
        quality, scale, decision = self.quality_for(scene)
        drawn_scene = scaled_scene(scene, scale) if scale < 1.0 else scene
        # Units are bound once a frame at most: code outside the renderer (a quality study's probe, a
        # test) may have bound other textures on this context since the last frame.
        bindings.forget_bindings(self._ctx)
        frame = build_frame(self.ctx, drawn_scene, self.frame_state)
        frame.quality = quality
        targets = self.targets_for(drawn_scene.camera.width, drawn_scene.camera.height)
        names = self.graph.plan(scene, frame.view)
        targets.scene_fbo.use()
        targets.scene_fbo.clear(0.0, 0.0, 0.0, 1.0, depth=depth.CLEAR_DEPTH)
        self.ctx.depth_func = depth.NEAREST_WINS
        pass_ms: dict[str, float] = {}
        pass_cpu: dict[str, tuple[float, float]] = {}  # timed: (this thread's, other threads') CPU ms
        if timed:
            self.ctx.finish()
            pass_ms["setup"] = (time.perf_counter() - start) * 1e3
        for name in names:
            # Clocks only when timed: the process's CPU clock sums every thread's (llvmpipe's
            # workers too) and costs far more than a plain clock read.
            if timed:
                t0, cpu0, own0 = time.perf_counter(), time.process_time(), time.thread_time()
            self.graph.passes[name].execute(frame, targets)
            # The pass's work goes to the driver now: on llvmpipe its rasterisation then overlaps
            # the next pass's setup in this thread instead of waiting for the next forced wait.
            gl_calls.flush()
            if timed:
                self.ctx.finish()
                pass_ms[name] = (time.perf_counter() - t0) * 1e3
                own = (time.thread_time() - own0) * 1e3
                pass_cpu[name] = (own, (time.process_time() - cpu0) * 1e3 - own)
        output = targets  # what the readback reads: the LDR target, or the upscaled frame
        if drawn_scene is not scene:
            if self._upscaler is None:
                self._upscaler = Upscaler(self.ctx, self.programs)
            t0 = time.perf_counter()
            output = self._upscaler.execute(targets.ldr, (scene.camera.width, scene.camera.height))
            gl_calls.flush()
            if timed:
                self.ctx.finish()
                pass_ms["upscale"] = (time.perf_counter() - t0) * 1e3
        self.frames_rendered += 1
        quality = frame.quality.name if isinstance(frame.quality, presets.Rung) else frame.quality
        result = RenderResult(None, names, pass_ms, 0.0, quality, ev100=frame.ev100,
                              illuminance_lux=frame.illuminance_lux, pass_cpu_ms=pass_cpu,
                              host_frame=scene.host_frame, sim_time=scene.time.sim_time,
                              overload=self._report(decision))
        return _Drawn(result, output, start, time.perf_counter(), timed, meter=frame.resources.get("meter_ticket"))

    def _report(self, decision) -> dict:
        """``decision.fields()``, found once per decision (a frozen record: a scene without a frame
        rate gets the same one every frame); each frame gets its own copy."""
        held = getattr(self, "_held_report", None)
        if held is None or held[0] is not decision:
            held = self._held_report = (decision, decision.fields())
        return {**held[1], "rungs": dict(held[1]["rungs"])}

    def read_hdr(self) -> np.ndarray:
        """The last frame's pre-exposed linear HDR colour (float32, top row first), for quality tools."""
        make_current(self._ctx)
        t = self._targets
        data = np.frombuffer(t.hdr.read(), dtype=np.float16).reshape(t.size[1], t.size[0], 4)
        return data[::-1].astype(np.float32)

    def read_distance(self) -> np.ndarray:
        make_current(self._ctx)
        t = self._targets
        return np.frombuffer(t.distance.read(), dtype=np.float32).reshape(t.size[1], t.size[0])[::-1].copy()

    def release(self) -> None:
        make_current(self._ctx)
        if self._targets is not None:
            self._targets.release()
        self.release_channel_targets(keep=set())
        if self._readback is not None:
            self._readback.release()
        if self._upscaler is not None:
            self._upscaler.release()
        release_context(self._ctx)
