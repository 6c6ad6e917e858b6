"""Frames in flight: a frame's pixels are copied out (pixel buffers) while the next one is drawn.

Each frame must be the one the synchronous path draws, bit for bit, and carry the host_frame and
sim_time of the scene it was drawn from, also when the host changes the state every frame.
"""

import numpy as np
import pytest

from igserver.render.frame import FrameState
from igserver.render.worker import RenderService
from igserver.scene import apply_patch, load_scene

from helpers import tiny


def _states(base, n: int) -> list:
    """A host that changes the state every frame: its frame counter, the clock and the view."""
    return [apply_patch(base, {"host_frame": 500 + i, "time": {"sim_time": base.time.sim_time + i / 30.0},
                               "camera": {"heading": base.camera.heading + 4.0 * i}}) for i in range(n)]


def _pipelined(renderer, scenes) -> list:
    out = [f for f in (renderer.submit(s) for s in scenes) if f is not None]
    while renderer.in_flight:
        out.append(renderer.collect())
    return out


@pytest.mark.parametrize("name", ["demo", "night_fire"])
def test_frames_in_flight_are_bit_identical_and_tagged_exactly(renderer, name):
    scenes = _states(apply_patch(load_scene(name), {"camera": {"width": 96, "height": 54}}), 4)
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
    service.kill_for_test()
    assert service.submit(b) is None  # restarted: a went with the process, b is in flight
    assert service.collect().host_frame == b.host_frame and service.in_flight == 0
