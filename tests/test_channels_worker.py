"""Channels through the render process and the REST edge (docs/channels.md): every channel of a frame
with one frame number and the host_frame of the state it was drawn from, under a host changing the
state every frame; bad channel lists refused with a 422 naming the field, changing nothing."""

from __future__ import annotations

import httpx
import numpy as np

from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.render.worker import RenderService
from igserver.scene import Scene, apply_patch

from helpers import tiny


def bridge(turn: float = 0.0) -> list[dict]:
    return [dict(id="port", heading=-60.0 + turn, width=48, height=27),
            dict(id="ahead", heading=turn, width=64, height=36),
            dict(id="starboard", heading=60.0 + turn, width=48, height=27)]


def gradient(**patch) -> Scene:
    # the gradient sky needs no precomputed tables: the render process is ready in ~1 s
    # a fixed exposure: a re-render of a state shows the stream's picture of it to the byte
    return apply_patch(tiny({"atmosphere": {"model": "gradient"}, "camera": {"exposure_ev": 13.0}}), patch)


def test_every_channel_of_a_frame_carries_its_frame_number_and_host_frame():
    with RenderService(gradient(channels=bridge())) as service:
        frames = []
        for i in range(6):  # the host changes the state every frame: a new host_frame and a turn
            got = service.submit(gradient(host_frame=100 + i, channels=bridge(turn=5.0 * i),
                                          camera={"pitch": 3.0 * i - 8.0, "exposure_ev": 13.0}, time={"sim_time": i / 30.0}), tag=i)
            if got is not None:
                frames.append(got)
        while service.in_flight:
            frames.append(service.collect())
        assert [f.host_frame for f in frames] == list(range(100, 106))
        assert [f.tag for f in frames] == list(range(6))
        for frame in frames:
            assert list(frame.channels) == ["port", "ahead", "starboard"]
            assert frame.rgba.shape == (36, 160, 4)  # side by side, top-aligned
            x = 0
            for cid, part in frame.channels.items():
                assert (part.ig_frame, part.host_frame, part.sim_time, part.ev100, part.tag) == (
                    frame.ig_frame, frame.host_frame, frame.sim_time, frame.ev100, frame.tag)
                assert np.array_equal(part.rgba, frame.rgba[:part.height, x:x + part.width])
                x += part.width
        assert len({f.ig_frame for f in frames}) == 6
        # the picture of the state drawn, the turn and pitch of frame 5, not another's
        again = service.render(gradient(host_frame=105, channels=bridge(turn=25.0), camera={"pitch": 7.0, "exposure_ev": 13.0},
                                        time={"sim_time": 5 / 30.0}))
        assert np.array_equal(again.rgba, frames[-1].rgba)
        assert not any(np.array_equal(again.rgba, f.rgba) for f in frames[:-1])
        plain = service.render(gradient())
        assert plain.channels is None and plain.rgba.shape == (36, 64, 4)


BAD = [
    ("duplicate", [dict(id="a"), dict(id="a")], "#/channels"),
    ("zero-width", [dict(id="a", width=0)], "#/channels/0/width"),
    ("negative-half-angle", [dict(id="a", fov_left=-10.0)], "#/channels/0/fov_left"),
    ("seventeen", [dict(id=f"c{i}", width=16, height=16) for i in range(17)], "#/channels"),
    ("over-budget", [dict(id=f"c{i}", width=3840, height=2160) for i in range(2)], "#/channels"),
]


def test_bad_channels_get_a_422_naming_the_field_and_change_nothing():
    with LoopbackServer(gradient(channels=bridge()), ServerSettings(keepalive_s=0.25)) as server:
        with httpx.Client(base_url=server.url, timeout=30) as http:
            http.patch("/v1/clock", json={"paused": True}).raise_for_status()  # a still state to compare
            before = http.get("/v1/state", headers={"Accept": "application/json"})
            for name, channels, pointer in BAD:
                response = http.patch("/v1/state", json={"channels": channels})
                assert response.status_code == 422, (name, response.text)
                assert pointer in [e["pointer"] for e in response.json()["errors"]], (name, response.json())
            after = http.get("/v1/state", headers={"Accept": "application/json"})
            assert after.json() == before.json()
            assert after.headers["x-ig-revision"] == before.headers["x-ig-revision"]
            ok = http.patch("/v1/state", json={"channels": bridge(turn=10.0)[:2]})
            assert ok.status_code == 200
            assert [c["id"] for c in http.get("/v1/state", headers={"Accept": "application/json"}).json()["channels"]] \
                == ["port", "ahead"]
