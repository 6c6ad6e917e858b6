"""Every channel of one state in one frame (docs/channels.md): the world once, the view per channel,
one exposure.

Order of a frame of N channels:

1. per channel, its scene (render/channels.py) and frame data (``build_frame``: the sky, its light
   and tables are world items, cached on their inputs, so only the first channel computes them);
2. one provisional exposure from the union of the channels' meter samples, given to every channel;
3. per channel, every pass but the post pass into the channel's own targets, and the GPU reduction
   of its HDR colour to meter cells (queued, not read: the channels' rasterisation overlaps the
   next channel's setup);
4. one meter over the union of all channels' cells, one step of the eye's adaptation, one exposure;
5. per channel, the post pass (halos, exposure, tone curve) with that exposure.

So adjacent channels show the same luminance as the same grey, and the adaptation state moves once
per frame, not once per channel. Items a pass keeps per view (LOD selections, visible sets, draw
plans) are memoised per view (render/memo.py keeps one value per channel of the frame), so a still
eyepoint costs no re-selection in any channel.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import moderngl
import numpy as np

from . import bindings, depth, gl_calls, presets
from .channels import channel_scene, side_by_side
from .common.aerial_table import AerialTable
from .frame import build_frame, provisional_ev100, set_exposure
from .frame_block import FrameBlock
from .memo import Memo
from .post import meter_lag
from .post.exposure import display_metered_ev100, exposure_of_ev100
from .scaling import scaled_scene


@dataclass
class ChannelView:
    id: str
    scene: object
    frame: object
    targets: object  # what the passes draw into: the internal render scale's size
    names: list
    output: object = None  # what the readback reads: ``targets``, or the upscale to the channel's size

    def __post_init__(self):
        if self.output is None:
            self.output = self.targets


class ChannelGroup:
    """The channels' LDR targets as the renderer's readback sees one frame's: ``ldr_fbo.read()`` gives
    the mosaic (the channels side by side, top-aligned, rows bottom-up as GL's), ``size`` its size,
    ``parts`` each channel's (framebuffer, (width, height)) for a readback ring, ``layout``
    [(id, x0, width, height)] (scene/channels.py mosaic_layout)."""

    def __init__(self, views: list):
        self.parts = [(v.output.ldr_fbo, v.output.size) for v in views]
        self.layout, x = [], 0
        for v in views:
            self.layout.append((v.id, x, *v.output.size))
            x += v.output.size[0]
        self.size = (x, max(h for _, (_, h) in self.parts))
        self.ldr_fbo = self

    def read(self, components: int = 4, alignment: int = 1) -> bytes:
        images = [np.frombuffer(fbo.read(components=4, alignment=1), np.uint8).reshape(h, w, 4)[::-1]
                  for fbo, (w, h) in self.parts]
        return side_by_side(images)[::-1].tobytes()


# Resident objects (render/resident.py) that hold one view's table: each channel has its own.
VIEW_RESIDENTS = (AerialTable,)
# Each view's counters start at a base of their own, far from every other's (a view that recomputes
# counts up from it): a key made of one cannot equal another view's. Negative: a single view's count
# up from 0.
_COUNTER_BASES = itertools.count(1)
COUNTER_SPACING = 1 << 32


def swap_view_state(ctx, passes: dict, held: dict) -> dict:
    """Put one view's state into ``passes`` and the resident objects (``held``: what an earlier swap
    returned for that view, or {} for a new view) and return the state it replaces, in that form."""
    out: dict = {}
    for name, render_pass in passes.items():
        attrs = render_pass.view_state + render_pass.view_counters
        if not attrs:
            continue
        out[name] = {a: render_pass.__dict__[a] for a in attrs if a in render_pass.__dict__}
        mine = held.get(name, {})
        for a in attrs:
            if a in mine:
                render_pass.__dict__[a] = mine[a]
            elif a in render_pass.view_counters:
                render_pass.__dict__[a] = -next(_COUNTER_BASES) * COUNTER_SPACING
            else:
                render_pass.__dict__.pop(a, None)
    for cls in VIEW_RESIDENTS:
        out[cls] = cls._resident.pop(ctx, None)
        if held.get(cls) is not None:
            cls._resident[ctx] = held[cls]
    return out


class _HazeOnce:
    """A fog transition (sky/haze.HazeTransition) stepped once a frame: the frame's first channel
    eases it to the frame's sim_time, and every channel gets that value (a second step at the same
    sim_time would end the transition at once, and the channels would differ)."""

    def __init__(self, haze):
        self.haze, self.beta = haze, None

    def apply(self, target_beta, duration: float, sim_time: float):
        if self.beta is None:
            self.beta = self.haze.apply(target_beta, duration, sim_time)
        return self.beta


class _OncePerFrame:
    """The renderer's FrameState as every channel of one frame sees it: the eye (adapted once, after
    the union is metered) and the fog transition stepped once."""

    def __init__(self, state):
        self.eye = state.eye
        self.haze = _HazeOnce(state.haze)
        self.meter = state.meter


def release_view_state(state: dict) -> None:
    """Release the GL objects a view's state holds (swap_view_state's form): its resident tables and
    the textures, framebuffers, buffers and vertex arrays its passes' attributes hold directly or in
    dicts and tuples (lists are not walked: ``_bound_shadow_maps`` lists the shared shadow maps)."""
    for key, value in state.items():
        if key in VIEW_RESIDENTS:
            if value is not None:
                value.release()
        else:
            for held in value.values():
                _release_gl(held)


def _release_gl(value) -> None:
    if isinstance(value, (moderngl.Texture, moderngl.Framebuffer, moderngl.Buffer, moderngl.VertexArray)):
        value.release()
    elif isinstance(value, dict):
        for v in value.values():
            _release_gl(v)
    elif isinstance(value, tuple):
        for v in value:
            _release_gl(v)


def draw_channels(renderer, scene, timed: bool):
    """Queue every pass of every channel of ``scene`` (renderer: a ``Renderer``); returns
    (the frame's result without pixels, [ChannelView], start time)."""
    own = renderer.frame_state
    renderer.frame_state = _OncePerFrame(own)  # the fog eased once for the frame, not once per channel
    try:
        return _draw_views(renderer, scene, timed)
    finally:
        renderer.frame_state = own


def _draw_views(renderer, scene, timed: bool):
    """draw_channels with the renderer's FrameState seen once per frame."""
    from .renderer import RenderResult

    start = time.perf_counter()
    ctx = renderer.ctx
    # The operating point's render scale applies to every channel alike: each draws at scale x its
    # size (the same frustum) and is upscaled to its size after the post pass, as a single view is.
    quality, scale, decision = renderer.quality_for(scene)
    Memo.slots = len(scene.channels)
    bindings.forget_bindings(ctx)
    views = []
    for channel in scene.channels:
        sub = channel_scene(scene, channel)
        drawn = scaled_scene(sub, scale) if scale < 1.0 else sub
        frame = build_frame(ctx, drawn, renderer.frame_state)
        frame.quality = quality
        frame.resources["view_slot"] = channel.id  # a channel's frame (passes.DepthCopyPass)
        targets = renderer.channel_targets(channel.id, drawn.camera.width, drawn.camera.height)
        views.append(ChannelView(channel.id, drawn, frame, targets, renderer.graph.plan(drawn, frame.view)))
    renderer.release_channel_targets(keep={v.id for v in views})

    # One provisional exposure: the union of the views' samples, as one view's are metered.
    samples = np.concatenate([v.frame.resources["meter_samples"] for v in views])
    target, meter = display_metered_ev100(samples)
    ev100 = provisional_ev100(scene, renderer.frame_state, target)
    shared = renderer.exposure_override if scene.camera.exposure_ev is None else None
    if shared is not None:  # the front's exposure for every renderer of the frame: the passes pre-expose with it
        ev100, meter = shared
    for v in views:
        set_exposure(v.frame, ev100, meter)

    post = renderer.graph.passes["post"]
    auto = scene.camera.exposure_ev is None
    pass_ms: dict[str, float] = {}
    channel_ms: dict[str, dict[str, float]] = {v.id: {} for v in views}
    if timed:
        ctx.finish()
        pass_ms["setup"] = (time.perf_counter() - start) * 1e3
    meters, own_meter = {}, getattr(post, "_meter_tex", None)
    # A stream of these channels meters the last frame's union of cells (post/meter_lag.py): read
    # now, when that frame is long done; this frame's cells are copied out while it is drawn.
    lag, key = renderer.frame_state.meter, tuple(v.id for v in views)
    if not auto or shared is not None:
        lag.clear()
    lagged = lag.take() if auto and shared is None and lag.continues(key, scene, renderer.frame_state.eye) else None
    state = {"single": None, "current": None}  # the passes' state of single-view frames; the view in them

    def enter(v: ChannelView) -> None:
        """Make ``v`` the view the passes draw: its pass state, its frame block, its framebuffer."""
        switched = state["current"] != v.id
        if switched:
            swapped = swap_view_state(ctx, renderer.graph.passes, renderer.view_states.get(v.id, {}))
            if state["current"] is None:
                state["single"] = swapped
            else:
                renderer.view_states[state["current"]] = swapped
            state["current"] = v.id
        _use_view(ctx, v, switched)
        ctx.depth_func = depth.NEAREST_WINS

    schedule: dict[str, list[ChannelView]] = {}  # per pass, the channels that draw it
    for v in views:
        v.targets.scene_fbo.use()
        v.targets.scene_fbo.clear(0.0, 0.0, 0.0, 1.0, depth=depth.CLEAR_DEPTH)
        for name in v.names:
            if name == "post":
                continue
            schedule.setdefault(name, []).append(v)
    # Pass-major: every channel's surfaces, then every channel's water, ...: the driver rasterises
    # one channel while the next is set up, and a pass that must wait for the frame so far (the
    # depth copy, the meter) waits once for all channels rather than once each.
    for name in merged_order([v.names for v in views]):
        for v in schedule.get(name, []):
            enter(v)
            t0 = time.perf_counter()
            renderer.graph.passes[name].execute(v.frame, v.targets)
            gl_calls.flush()
            if timed:
                ctx.finish()
                _add(pass_ms, channel_ms[v.id], name, (time.perf_counter() - t0) * 1e3)
    for v in views:
        if auto:  # each channel's cells in a texture of its own, all read after the last channel is queued
            post._meter_tex = renderer.channel_meters.get(v.id)
            meters[v.id] = renderer.channel_meters[v.id] = post.meter_dispatch(v.targets)
    if state["current"] is not None:
        renderer.view_states[state["current"]] = swap_view_state(ctx, renderer.graph.passes, state["single"])
    post._meter_tex = own_meter  # the single view's, for frames without channels
    t0 = time.perf_counter()
    correction = 1.0
    if auto:
        if lagged is not None:
            parts = []
            for v in views:
                copy = renderer.channel_meter_copies[v.id] = meter_lag.copy_for(
                    renderer.channel_meter_copies.get(v.id), ctx, meters[v.id])
                parts.append((copy, copy.queue(), v.frame.exposure))
            ticket, cells = meter_lag.MeterTicket(parts=parts), lagged
            renderer.meter_cells = None  # this frame's: when it is read (Renderer._finished)
        else:
            cells = renderer.meter_cells = np.concatenate([post.meter_cells(v.frame, meters[v.id]) for v in views])
            ticket = meter_lag.MeterTicket(cells)
        views[0].frame.resources["meter_ticket"] = ticket
        if shared is None:
            lag.hold(ticket, key, scene.time.sim_time)
        if len(cells):
            if shared is not None:  # the front meters the union of every renderer's cells
                ev, meter = shared
            else:
                target, meter = display_metered_ev100(cells)
                ev = renderer.frame_state.eye.update(target, scene.time.sim_time, scene.camera.adaptation)
            correction = exposure_of_ev100(ev) / views[0].frame.exposure
            for v in views:
                v.frame.ev100, v.frame.meter_luminance = ev, meter
    for v in views:
        t1 = time.perf_counter()
        FrameBlock.get(ctx).update(v.frame.uniforms)
        post.finish(v.frame, v.targets, correction)
        gl_calls.flush()
        if timed:
            ctx.finish()
            _add(pass_ms, channel_ms[v.id], "post", (time.perf_counter() - t1) * 1e3)
    for v, channel in zip(views, scene.channels):
        if v.targets.size != (channel.width, channel.height):
            t1 = time.perf_counter()
            v.output = renderer.channel_upscaler(v.id).execute(v.targets.ldr, (channel.width, channel.height))
            gl_calls.flush()
            if timed:
                ctx.finish()
                _add(pass_ms, channel_ms[v.id], "upscale", (time.perf_counter() - t1) * 1e3)
        else:  # back at scale 1: the channel's upscale output is not needed
            renderer.release_channel_upscaler(v.id)
    if timed:
        pass_ms["meter"] = (time.perf_counter() - t0) * 1e3 - pass_ms.get("post", 0.0)

    renderer.frames_rendered += 1
    frame = views[0].frame
    names = merged_order([v.names for v in views])
    level = frame.quality.name if isinstance(frame.quality, presets.Rung) else frame.quality
    common = dict(quality=level, ev100=frame.ev100, illuminance_lux=frame.illuminance_lux,
                  host_frame=scene.host_frame, sim_time=scene.time.sim_time, overload=decision.fields())
    result = RenderResult(None, names, pass_ms, 0.0, **common)
    result.channels = {v.id: RenderResult(None, v.names, channel_ms[v.id], 0.0, **common) for v in views}
    return result, views, start


def _use_view(ctx, v: ChannelView, switched: bool) -> None:
    """The frame block (when the view changed) and the framebuffer of channel ``v``."""
    if switched:
        FrameBlock.get(ctx).update(v.frame.uniforms)
    v.targets.scene_fbo.use()


def merged_order(lists: list[list[str]]) -> list[str]:
    """Every name of the channels' pass lists once, each after its predecessor in the list it came from."""
    merged: list[str] = []
    for names in lists:
        for i, name in enumerate(names):
            if name not in merged:
                merged.insert(merged.index(names[i - 1]) + 1 if i else 0, name)
    return merged


def _add(total: dict, own: dict, name: str, ms: float) -> None:
    total[name] = total.get(name, 0.0) + ms
    own[name] = own.get(name, 0.0) + ms
