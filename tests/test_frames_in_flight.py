"""Frames in flight: a frame's pixels are copied out (pixel buffers) while the next one is drawn.

Each frame must be the one the synchronous path draws, bit for bit, and carry the host_frame and
sim_time of the scene it was drawn from, also when the host changes the state every frame.
"""

import threading
import time
from pathlib import Path

import httpx
import msgpack
import numpy as np
import pytest
from websockets.sync.client import connect

import igserver
from igserver.client.core import IGClient
from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.render.frame import FrameState
from igserver.render.worker import RenderService
from igserver.scene import Scene, apply_patch, load_scene

from helpers import kill_render_process, tiny


def _states(base, n: int) -> list:
    """A host that changes the state every frame: its frame counter, the clock and the view."""
    return [apply_patch(base, {"host_frame": 500 + i, "time": {"sim_time": base.time.sim_time + i / 30.0},
                               "camera": {"heading": base.camera.heading + 4.0 * i}}) for i in range(n)]


def _pipelined(renderer, scenes) -> list:
    out = [f for f in (renderer.submit(s) for s in scenes) if f is not None]
    while renderer.in_flight:
        out.append(renderer.collect())
    return out


EXAMPLES = sorted(p.stem for p in (Path(igserver.__file__).parent / "scenes").glob("*.toml"))


@pytest.mark.parametrize("name", EXAMPLES)
def test_frames_in_flight_are_bit_identical_and_tagged_exactly(renderer, name):
    scenes = _states(apply_patch(load_scene(name), {"camera": {"width": 96, "height": 54}}), 3)
    # the same eased state (fog, eye adaptation) at the start of both runs
    renderer.frame_state = FrameState()
    sync = [renderer.render(s) for s in scenes]
    renderer.frame_state = FrameState()
    piped = _pipelined(renderer, scenes)
    assert len(piped) == len(scenes) and renderer.in_flight == 0
    for scene, a, b in zip(scenes, sync, piped):
        assert (b.host_frame, b.sim_time) == (scene.host_frame, scene.time.sim_time)
        assert a.host_frame == b.host_frame and np.array_equal(a.rgba, b.rgba)
        assert b.total_ms > 0


def test_submit_returns_the_previous_frame_and_render_its_own(renderer):
    a, b, c = _states(tiny(), 3)
    renderer.collect()  # nothing left over from another test
    assert renderer.submit(a) is None and renderer.in_flight == 1
    # a synchronous frame in between is that very scene's; the one in flight stays in flight
    assert renderer.render(c).host_frame == c.host_frame and renderer.in_flight == 1
    assert renderer.submit(b).host_frame == a.host_frame
    assert renderer.collect().host_frame == b.host_frame
    assert renderer.collect() is None


def test_a_size_change_in_flight_keeps_each_frame_its_size(renderer):
    small, big = tiny({"host_frame": 1}), tiny({"host_frame": 2}, 128, 72)
    assert renderer.submit(small) is None
    first = renderer.submit(big)
    assert first.rgba.shape == (36, 64, 4) and first.host_frame == 1
    second = renderer.collect()
    assert second.rgba.shape == (72, 128, 4) and second.host_frame == 2
    assert np.array_equal(second.rgba, renderer.render(big).rgba)


@pytest.mark.parametrize("change", ["channels to none", "none to channels", "other channels"])
def test_views_changing_with_a_frame_in_flight(renderer, change):
    """A host drops its channels (or adds them, or swaps them) while a frame of the old views is in
    flight: the old views' meter copies go with them, and the frame in flight comes back whole (its
    meter cells, read after their copy was released, count as lost: the next frame meters itself)."""
    two = [dict(id=c, heading=h, width=48, height=36) for c, h in (("a", -30.0), ("b", 30.0))]
    other = [dict(id="c", heading=0.0, width=40, height=30)]
    views = {"channels to none": (two, []), "none to channels": ([], two), "other channels": (two, other)}[change]
    renderer.collect()  # nothing left over from another test
    base = tiny({"atmosphere": {"model": "gradient"}})
    old = [apply_patch(base, {"channels": views[0], "host_frame": i, "time": {"sim_time": 1 + i / 30}}) for i in range(3)]
    new = apply_patch(base, {"channels": views[1], "host_frame": 3, "time": {"sim_time": 1 + 3 / 30}})
    got = [renderer.submit(s) for s in (*old, new)] + [renderer.collect()]
    assert [f.host_frame for f in got if f is not None] == [0, 1, 2, 3]
    assert got[-1].channels is None if not views[1] else set(got[-1].channels) == {c["id"] for c in views[1]}


@pytest.fixture(scope="module")
def service():
    with RenderService(tiny()) as svc:
        yield svc


def test_render_process_frames_in_flight_match_and_keep_their_tags(service):
    scenes = _states(tiny(), 4)
    sync = [service.render(s) for s in scenes]
    piped = []
    for i, scene in enumerate(scenes):
        frame = service.submit(scene, tag=("revision", i))
        if frame is not None:
            piped.append(frame)
    while service.in_flight:
        piped.append(service.collect())
    assert [f.tag for f in piped] == [("revision", i) for i in range(4)]
    assert [f.host_frame for f in piped] == [s.host_frame for s in scenes]
    assert [f.sim_time for f in piped] == [s.time.sim_time for s in scenes]
    # the eye adapts over frames, so each run's first frame starts from a different state: compare the
    # last frames, after the same sequence of states
    assert np.abs(piped[-1].rgba.astype(int) - sync[-1].rgba.astype(int)).max() <= 1
    assert [f.ig_frame for f in piped] == sorted(f.ig_frame for f in piped)


def test_a_render_between_submits_keeps_frame_numbers_in_drawing_order(service):
    a, b, c = _states(tiny(), 3)
    assert service.submit(a, tag="a") is None
    now = service.render(c)  # REST /v1/frame while a stream has a frame in flight
    assert now.host_frame == c.host_frame and now.tag is None
    earlier = service.submit(b, tag="b")  # the frame drawn before the render comes out first, older
    assert earlier.tag == "a" and earlier.host_frame == a.host_frame and earlier.ig_frame < now.ig_frame
    last = service.collect()
    assert last.tag == "b" and last.ig_frame > now.ig_frame and service.collect() is None


def test_a_killed_render_process_loses_only_its_frames_in_flight(service):
    a, b = _states(tiny(), 2)
    assert service.submit(a) is None
    kill_render_process(service)
    assert service.submit(b) is None  # restarted: a went with the process, b is in flight
    assert service.collect().host_frame == b.host_frame and service.in_flight == 0


# --------------------------------------------------------------------------- through a real server

PITCHES = (55.0, 0.0, -55.0)  # sky, horizon, ground: a frame tagged one or two states off looks clearly wrong


def _look(host_frame: int) -> dict:
    return {"host_frame": host_frame, "camera": {"pitch": PITCHES[host_frame % 3]}}


def _stream_host(url: str, stop: threading.Event, rate_hz: float, start_frame: int) -> None:
    """A host that sends new states without waiting for frames (at 1000 Hz: as fast as HTTP goes, faster
    than the IG draws, so frames are in flight)."""
    with IGClient(url) as ig:
        n, period, t0 = 0, 1.0 / rate_hz, time.perf_counter()
        while not stop.is_set():
            ig.patch_state(_look(start_frame + n), minimal=True)
            n += 1
            time.sleep(max(0.0, t0 + n * period - time.perf_counter()))


def test_a_stream_in_flight_tags_every_frame_with_its_own_state_when_the_host_changes_it_every_frame():
    scene = Scene.model_validate({"camera": {"width": 64, "height": 36}, "atmosphere": {"model": "gradient"}})
    with LoopbackServer(scene, ServerSettings(max_fps=1000.0)) as srv:
        httpx.patch(srv.url + "/v1/clock", json={"paused": True}).raise_for_status()
        assert srv.runtime.gateway.pipelined
        with IGClient(srv.url) as ig:  # each look's picture, one frame at a time
            for _ in range(3):  # the eye settles on each look
                references = [_raw(ig.render(_look(3_000 + k), format="raw")) for k in range(3)]
        gateway, overlapped = srv.runtime.gateway, []
        submit = gateway.submit

        async def counted(*args):  # a frame a submit returns was read while the next one was drawn
            encoded = await submit(*args)
            overlapped.append(encoded is not None)
            return encoded

        gateway.submit = counted
        stop = threading.Event()
        host = threading.Thread(target=_stream_host, args=(srv.url, stop, 1000.0, 40_000))
        frames = []
        with connect(srv.url.replace("http", "ws") + "/v1/ws", compression=None) as ws:
            ws.send(msgpack.packb({"type": "hello", "credits": 4, "format": "raw"}))
            host.start()
            deadline = time.monotonic() + 3.0
            while time.monotonic() < deadline:
                message = msgpack.unpackb(ws.recv(10), raw=False)
                ws.send(msgpack.packb({"type": "ack", "frame": message["frame"]}))
                if message["host_frame"] >= 40_000:
                    rgba = np.frombuffer(message["data"], np.uint8).reshape(message["height"], message["width"], 4)
                    frames.append((message["host_frame"], rgba))
        stop.set()
        host.join(10)
    assert len(frames) >= 5 and sum(overlapped) >= 3, (len(frames), overlapped)
    for host_frame, rgba in frames:
        distance = [np.abs(rgba.astype(int) - ref.astype(int)).mean() for ref in references]
        assert int(np.argmin(distance)) == host_frame % 3, (host_frame, distance)


def _raw(frame) -> np.ndarray:
    return np.frombuffer(frame.data, np.uint8).reshape(frame.height, frame.width, 4)


def test_the_service_bench_times_a_saturated_stream_from_each_state_to_its_frame():
    from igserver.client.core import latency_bench, summarize

    scene = Scene.model_validate({"camera": {"width": 64, "height": 36}, "atmosphere": {"model": "gradient"}})
    with LoopbackServer(scene) as srv:
        result = latency_bench(srv.url, frames=8, warmup=2, mode="ws-stream", rate_hz=200.0)
    summary = summarize(result)
    assert summary["frames"] == 8 and summary["e2e_p50"] > 0 and summary["fps"] > 0
    assert all(e >= r for e, r in zip(result["e2e_ms"], result["render_ms"]))  # a frame after its render
