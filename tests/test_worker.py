"""The render process: frames through shared memory, restart after a crash without losing state."""

import numpy as np
import pytest

from igserver.render.worker import RenderService

from helpers import kill_render_process, tiny


@pytest.fixture(scope="module")
def service():
    with RenderService(tiny()) as svc:
        yield svc


def test_frames_come_back_tagged(service):
    scene = tiny({"host_frame": 41, "camera": {"pitch": 5}})
    service.set_state(scene)
    frame = service.render()
    assert frame.rgba.shape == (36, 64, 4) and frame.rgba.dtype == np.uint8
    assert frame.host_frame == 41 and frame.ig_frame >= 1 and frame.render_ms > 0
    assert "sky" in frame.passes
    info = service.info()
    assert info["ready"] and info["renderer"] and info["version"]


def test_restart_after_kill_keeps_the_accepted_state(service):
    other = service.render(tiny({"camera": {"heading": 300, "pitch": -30}})).rgba  # ground-heavy view
    state = tiny({"host_frame": 7, "camera": {"heading": 123, "pitch": 12}})
    service.set_state(state)
    before = service.render().rgba
    old_pid, restarts = service.pid, service.restarts
    kill_render_process(service)
    assert not service.alive
    after = service.render()  # restarts transparently and renders the same accepted state
    assert service.alive and service.pid != old_pid and service.restarts == restarts + 1
    # What the new process drew, not what the service object holds: the frame is tagged by the render
    # process with the state's host_frame, and it is the accepted state's picture (the dither may move
    # a level), clearly not another state's.
    assert after.host_frame == 7
    assert np.abs(after.rgba.astype(int) - before.astype(int)).max() <= 2
    assert np.abs(after.rgba.astype(int) - other.astype(int)).mean() > 10


def test_resolution_change_reallocates_the_ring(service):
    big = tiny({}, 128, 72)
    assert service.render(big).rgba.shape == (72, 128, 4)
    assert service.render(tiny()).rgba.shape == (36, 64, 4)
