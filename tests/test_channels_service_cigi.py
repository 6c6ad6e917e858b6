"""CIGI views -> channels (docs/cigi.md#views-and-channels): View Control / View Definition of views
N > 0 are channels ``"N"`` of view 0's eyepoint, with their frustum half-angles and their attitude
relative to view 0; a bad view rejects the whole datagram and changes nothing; and through a real
server over UDP, the channels a host defined are what GET /v1/channels lists and every frame renders."""

from __future__ import annotations

import socket
import time

import httpx
import pytest

from helpers import tiny
from igserver.cigi.datagram import build
from igserver.cigi.engine import CigiEngine
from igserver.cigi.packets_host import EntityControl, IGControl, ViewControl, ViewDefinition
from igserver.protocol.metrics import ServiceMetrics
from igserver.protocol.settings import ServerSettings
from igserver.protocol.state import StateStore
from igserver.protocol.testing import LoopbackServer
from igserver.render.camera import body_to_world
from igserver.scene.files import load_scene

LAT0, LON0 = 59.93, 30.31
WINDOW = dict(left=-30.0, right=30.0, top=17.5, bottom=-17.5)  # one 60x35 deg bridge window


def engine(patch: dict | None = None) -> CigiEngine:
    return CigiEngine(StateStore(tiny(patch)), ServiceMetrics(), load_scene=load_scene)


def send(e: CigiEngine, *packets, frame: int = 1, **ig) -> bool:
    return e.handle(build([IGControl(host_frame=frame, **ig), *packets], ">")) is not None


def ship(yaw: float = 0.0) -> EntityControl:
    return EntityControl(entity_id=1, entity_type=1, lat=LAT0, lon=LON0, yaw=yaw)


def bridge() -> list:
    """Three views of one eyepoint on the ship: port (-60 deg), ahead, starboard (+60 deg)."""
    return [ship(), ViewControl(view_id=0, entity_id=1, z=-12.0), ViewDefinition(view_id=0, **WINDOW),
            ViewControl(view_id=1, entity_id=1, yaw=-60.0, z=-12.0), ViewDefinition(view_id=1, **WINDOW),
            ViewControl(view_id=2, entity_id=1, yaw=60.0, z=-12.0), ViewDefinition(view_id=2, **WINDOW)]


def test_views_become_channels_of_one_eyepoint():
    e = engine()
    assert send(e, *bridge())
    scene = e.store.scene
    assert [c.id for c in scene.channels] == ["0", "1", "2"]
    assert [c.heading for c in scene.channels] == pytest.approx([0.0, -60.0, 60.0], abs=1e-9)
    for c in scene.channels:
        assert (c.fov_left, c.fov_right, c.fov_up, c.fov_down) == pytest.approx((30.0, 30.0, 17.5, 17.5))
        assert (c.width, c.height) == (scene.camera.width, scene.camera.height)
    # the ship turns: the camera (view 0) turns with it, the channels' offsets from it stay
    assert send(e, ship(yaw=90.0), frame=2)
    scene = e.store.scene
    assert scene.camera.heading == pytest.approx(90.0)
    assert [c.heading for c in scene.channels] == pytest.approx([0.0, -60.0, 60.0], abs=1e-9)


def test_view_attitude_is_relative_to_view_0_and_enables_are_honoured():
    e = engine()
    assert send(e, *bridge())
    # view 0 pitches down 5 deg, view 2 down 15: channel 2 is 10 deg below the camera, still 60 to starboard
    assert send(e, ViewControl(view_id=0, entity_id=1, z=-12.0, pitch=-5.0),
                ViewControl(view_id=2, entity_id=1, yaw=60.0, pitch=-15.0, z=-12.0), frame=2)
    scene = e.store.scene
    cam, c2 = scene.camera, scene.channels[2]
    assert (cam.heading, cam.pitch) == pytest.approx((0.0, -5.0))
    # the channel's orientation (the camera's turned by its offsets in the camera's frame, docs/channels.md)
    # is view 2's own: the ship's (heading 0) turned by the view's yaw 60, pitch -15
    seen = body_to_world(cam.heading, cam.pitch, cam.roll) @ body_to_world(c2.heading, c2.pitch, c2.roll)
    assert seen == pytest.approx(body_to_world(60.0, -15.0, 0.0), abs=1e-9)
    assert c2.pitch != pytest.approx(-10.0, abs=0.5)  # not a difference of angles: a relative rotation
    # a View Definition with only the near enable set changes near alone
    assert send(e, ViewDefinition(view_id=1, near_enable=True, far_enable=False, left_enable=False,
                                  right_enable=False, top_enable=False, bottom_enable=False, near=2.0), frame=3)
    c1 = e.store.scene.channels[1]
    # (far stays the packet's 100 km of the first definition, whose enables were all set)
    assert (c1.near, c1.far, c1.fov_left) == pytest.approx((2.0, 100_000.0, 30.0))


def test_an_operators_channel_keeps_its_size_and_others_stay():
    e = engine({"channels": [{"id": "mirror", "heading": 180.0, "width": 64, "height": 32},
                             {"id": "1", "width": 320, "height": 120}]})
    assert send(e, *bridge())
    channels = {c.id: c for c in e.store.scene.channels}
    assert list(channels) == ["mirror", "1", "0", "2"]
    assert (channels["1"].width, channels["1"].height, channels["1"].heading) == (320, 120, pytest.approx(-60.0))
    assert channels["mirror"].heading == 180.0
    # IG Control reset: the host's channels go, the operator's stays
    assert send(e, frame=2, ig_mode=0)
    assert [c.id for c in e.store.scene.channels] == ["mirror"]


@pytest.mark.parametrize("bad", [
    ViewDefinition(view_id=1, left=10.0, right=40.0),  # a frustum that does not contain its axis
    ViewDefinition(view_id=1, top=-5.0, bottom=-30.0),
], ids=["left-of-axis-positive", "top-below-axis"])
def test_a_bad_view_rejects_the_datagram_and_changes_nothing(bad):
    e = engine()
    assert send(e, *bridge())
    before, revision = e.store.scene.model_dump(exclude={"time"}), e.store.revision  # (the clock runs)
    assert not send(e, ship(yaw=45.0), bad, frame=2)
    # nothing changed: the ship did not turn either
    assert e.store.scene.model_dump(exclude={"time"}) == before and e.store.revision == revision
    assert "channels" in e.last_error


def test_more_than_16_views_rejected():
    e = engine()
    views = [ViewDefinition(view_id=n, **WINDOW) for n in range(1, 17)]  # with view 0: 17 channels
    assert not send(e, *views)
    assert e.store.scene.channels == [] and "channels" in e.last_error


def test_cigi_views_through_the_server():
    """A host's three views over loopback UDP: GET /v1/channels lists them, a frame has the three images."""
    host = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    host.bind(("127.0.0.1", 0))
    settings = ServerSettings(cigi=True, cigi_port=0, cigi_host="127.0.0.1", cigi_host_port=host.getsockname()[1],
                              cigi_allow=["127.0.0.1"])
    scene = tiny({"atmosphere": {"model": "gradient"}}, width=96, height=54)
    with LoopbackServer(scene, settings) as server, httpx.Client(base_url=server.url, timeout=60) as http:
        port = server.runtime.cigi.transport.get_extra_info("sockname")[1]
        host.sendto(build([IGControl(host_frame=42), *bridge()], ">"), ("127.0.0.1", port))
        deadline = time.monotonic() + 10
        while server.runtime.store.scene.host_frame != 42 and time.monotonic() < deadline:
            time.sleep(0.02)
        listed = http.get("/v1/channels").json()["channels"]
        assert [(c["id"], c["heading"], c["width"]) for c in listed] == [("0", 0.0, 96), ("1", -60.0, 96),
                                                                        ("2", 60.0, 96)]
        response = http.post("/v1/render", json={"host_frame": 43})
        assert response.status_code == 200 and response.headers["x-ig-channels"] == "0,1,2"
    host.close()
