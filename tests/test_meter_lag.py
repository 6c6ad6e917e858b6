"""The exposure meter of a stream one frame late (render/post/meter_lag.py): a stream's frames after the
first never read their meter synchronously (the read that made the calling thread wait for the GPU in
the middle of every frame), frame N+1 adapts toward exactly frame N's target, and every frame without a
continuous predecessor (a single render, a jump, a cut, another view, a fixed or shared exposure)
meters its own cells at once, bit for bit as before.
"""

import numpy as np
import pytest

from igserver.render.frame import FrameState
from igserver.render.gl_count import GLCallCounter
from igserver.render.post import meter_lag
from igserver.render.post.exposure import EyeAdaptation, display_metered_ev100
from igserver.render.post.post import PostPass
from igserver.scene import apply_patch, load_scene



def _stream(base, n: int, dt: float = 1 / 30.0, turn: float = 5.0) -> list:
    """A host streaming one view: the clock at ``dt`` s a frame, the camera turning ``turn`` degrees a frame
    (the meter sees a different view each frame, so a lag shows)."""
    return [apply_patch(base, {"host_frame": i, "time": {"sim_time": base.time.sim_time + i * dt},
                               "camera": {"heading": (base.camera.heading + turn * i) % 360.0}}) for i in range(n)]


def _night(width=96, height=54):
    return apply_patch(load_scene("night_fire"), {"camera": {"width": width, "height": height}})


@pytest.fixture
def sync_reads(monkeypatch):
    """Counts the synchronous meter reads (PostPass.meter_cells: the single view's and the channels')."""
    calls = []
    original = PostPass.meter_cells

    def counted(frame, tex):
        calls.append(frame.scene.time.sim_time)
        return original(frame, tex)

    monkeypatch.setattr(PostPass, "meter_cells", staticmethod(counted))
    return calls


@pytest.fixture
def targets(monkeypatch):
    """The exposure targets (EV100) the eye adapts toward, in order."""
    seen = []
    original = EyeAdaptation.update

    def update(self, target, sim_time, enabled=True):
        seen.append(target)
        return original(self, target, sim_time, enabled)

    monkeypatch.setattr(EyeAdaptation, "update", update)
    return seen


def _pipelined(renderer, scenes) -> list:
    out = [f for f in (renderer.submit(s) for s in scenes) if f is not None]
    while renderer.in_flight:
        out.append(renderer.collect())
    return out


@pytest.mark.parametrize("name", ["demo", "night_fire", "bridge_3ch"])
def test_a_single_render_meters_its_own_frame_bit_for_bit(renderer, monkeypatch, sync_reads, name):
    """A single render (no predecessor) is the synchronous meter's frame: the same pixels as with the
    lag disabled altogether, its cells read once, at once."""
    scene = apply_patch(load_scene(name), {"camera": {"width": 96, "height": 54}})
    renderer.frame_state = FrameState()
    lagged = renderer.render(scene)
    assert len(sync_reads) == len(scene.channels or [None])  # each view's meter, at once
    monkeypatch.setattr(meter_lag.MeterLag, "continues", lambda *a: False)
    renderer.frame_state = FrameState()
    sync = renderer.render(scene)
    assert np.array_equal(lagged.rgba, sync.rgba) and lagged.ev100 == sync.ev100


@pytest.mark.parametrize("name", ["night_fire", "bridge_3ch"])
def test_a_streams_frames_after_the_first_never_wait_for_their_meter(renderer, sync_reads, name):
    """Through submit (frames in flight): only the first frame reads its meter back synchronously; the
    others neither read a texture nor finish the context, and the pixels' framebuffer is never read
    synchronously either (its pixel-pack copy is)."""
    scenes = _stream(apply_patch(load_scene(name), {"camera": {"width": 96, "height": 54}}), 5)
    renderer.frame_state = FrameState()
    renderer.collect()
    views = len(scenes[0].channels or [None])
    assert renderer.submit(scenes[0]) is None
    assert len(sync_reads) == views
    with GLCallCounter() as calls:
        out = [renderer.submit(s) for s in scenes[1:]]
    assert len(sync_reads) == views
    for blocking in ("Texture.read", "Framebuffer.read", "Context.finish"):
        assert calls.by_name[blocking] == 0, blocking
    assert calls.by_name["Framebuffer.read_into"] >= 4  # the meter's copies (and the pixels')
    assert [f.host_frame for f in out] == [0, 1, 2, 3]
    assert renderer.collect().host_frame == 4


def test_the_lag_is_exactly_one_frame(renderer, targets):
    """Frame N+1's exposure target is the synchronous target of frame N (its own cells, whose copy is
    the meter texture bit for bit), frame 0's its own; the eye eases from there as before."""
    scenes = _stream(_night(), 6)
    renderer.frame_state = FrameState()
    renderer.collect()
    post = renderer.graph.passes["post"]
    own = []  # each frame's own target, from its own cells
    for i, s in enumerate(scenes):
        renderer.render(s)
        if i:  # copied out, not read: the copy holds what a synchronous read of the texture gives
            assert post._meter_copy.buffer.read() == post._meter_tex.read()
        own.append(display_metered_ev100(renderer.frame_state.meter.ticket.cells())[0])
    assert targets[0] == own[0]
    assert targets[1:] == own[:-1]
    assert len(set(np.round(own, 6))) > 2  # the view changes: a lag would show


def test_frames_in_flight_lag_the_same_as_frames_rendered_one_by_one(renderer):
    scenes = _stream(_night(), 5)
    renderer.frame_state = FrameState()
    one_by_one = [renderer.render(s) for s in scenes]
    renderer.frame_state = FrameState()
    piped = _pipelined(renderer, scenes)
    for a, b in zip(one_by_one, piped):
        assert a.ev100 == b.ev100 and np.array_equal(a.rgba, b.rgba)


@pytest.mark.parametrize("cut", ["jump", "adaptation off", "fixed exposure"])
def test_a_frame_without_a_continuous_predecessor_meters_itself(renderer, sync_reads, cut):
    """The third frame of a stream is a jump of 5 s, a cut (adaptation off: its own exposure) or a fixed
    exposure. The jump and the cut read their own cells at once (and the next frame lags on them); the
    fixed exposure meters nothing and the frame after it has no metered predecessor."""
    scenes = _stream(_night(), 4)
    t = [s.time.sim_time for s in scenes]
    if cut == "jump":
        t[2:] = [t[2] + 5.0, t[3] + 5.0]
        scenes[2:] = [apply_patch(s, {"time": {"sim_time": u}}) for s, u in zip(scenes[2:], t[2:])]
    elif cut == "adaptation off":
        scenes[2] = apply_patch(scenes[2], {"camera": {"adaptation": False}})
    else:
        scenes[2] = apply_patch(scenes[2], {"camera": {"exposure_ev": 12.0}})
    renderer.frame_state = FrameState()
    for s in scenes:
        renderer.render(s)
    assert sync_reads == ([t[0], t[3]] if cut == "fixed exposure" else [t[0], t[2]])


def test_another_view_meters_itself(renderer, sync_reads):
    """A single view after the channels (or the channels after it) is not their stream."""
    channels = apply_patch(load_scene("bridge_3ch"), {"camera": {"width": 96, "height": 54}})
    single = apply_patch(channels, {"channels": []})
    scenes = _stream(channels, 4)
    scenes[2] = apply_patch(_stream(single, 4)[2], {})
    renderer.frame_state = FrameState()
    for s in scenes:
        renderer.render(s)
    n = len(channels.channels)
    t = [s.time.sim_time for s in scenes]
    assert sync_reads == [t[0]] * n + [t[2]] + [t[3]] * n


def test_the_clusters_shared_exposure_stays_synchronous(renderer, sync_reads):
    """With the front's exposure (igserver/cluster) every frame reads its own cells, and meter_cells are
    that frame's: the front unites them before the next frame."""
    scenes = _stream(apply_patch(load_scene("bridge_3ch"), {"camera": {"width": 96, "height": 54}}), 3)
    renderer.frame_state = FrameState()
    try:
        for i, s in enumerate(scenes):
            renderer.exposure_override, renderer.meter_cells = (12.0, 100.0), None
            result = renderer.render(s)
            assert result.ev100 == 12.0 and renderer.meter_cells is not None
    finally:
        renderer.exposure_override = None
    assert len(sync_reads) == len(scenes) * len(scenes[0].channels)


def test_channel_streams_report_each_frames_own_cells(renderer, sync_reads):
    """In a stream of channels the meter cells a collected frame leaves in ``renderer.meter_cells`` are
    its own (copied out with its pixels), not its predecessor's that it was exposed by."""
    scenes = _stream(apply_patch(load_scene("bridge_3ch"), {"camera": {"width": 96, "height": 54}}), 4)
    ids = [c.id for c in scenes[0].channels]
    renderer.frame_state = FrameState()
    previous = None
    for s in scenes:
        renderer.render(s)
        raw = np.concatenate([meter_lag.finite_cells(renderer.channel_meters[c].read(), 1.0) for c in ids])
        cells = renderer.meter_cells
        ratio = raw / np.maximum(cells, 1e-30)  # the frame's pre-exposure, the same for every cell
        assert np.allclose(ratio[cells > 0], np.median(ratio[cells > 0]), rtol=1e-6)
        assert previous is None or not np.array_equal(cells, previous)
        previous = cells.copy()
    assert len(sync_reads) == len(ids)  # the first frame's channels only
