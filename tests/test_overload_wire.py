"""The overload controller's report on the wire, through a real server (real render process, 64x36
frames): the X-IG-Quality header, the WebSocket frame message's ``quality``, the MJPEG part headers
and the /metrics gauges, with quality.target_fps set and off."""

from __future__ import annotations

import re

import httpx
import msgpack
import pytest
from websockets.sync.client import connect

from igserver.client.latency import mjpeg_rate
from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene

W, H = 64, 36
HEADER = re.compile(r"^scale=[0-9.]+; rungs=[a-z]+:[a-z>]+(,[a-z]+:[a-z>]+)*; error=[0-9.]+; target=(\d+); met=(true|false)$")


@pytest.fixture(scope="module")
def server():
    scene = Scene.model_validate({"camera": {"width": W, "height": H}, "atmosphere": {"model": "gradient"},
                                  "quality": {"preset": "auto", "target_fps": 20}})
    with LoopbackServer(scene, ServerSettings(keepalive_s=0.25)) as srv:
        yield srv


def test_frame_header(server):
    with httpx.Client(base_url=server.url, timeout=30) as http:
        response = http.get("/v1/frame", params={"format": "png"})
        assert response.status_code == 200
        match = HEADER.match(response.headers["x-ig-quality"])
        assert match and match.group(2) == "20", response.headers["x-ig-quality"]
        metrics = http.get("/metrics").text
        assert re.search(r"^igserver_quality_target_fps 20\.0$", metrics, re.M)
        assert re.search(r"^igserver_quality_scale (1\.0|0\.\d+)$", metrics, re.M)
        # the target off: the preset at scale 1, target 0
        http.patch("/v1/state", json={"quality": {"preset": "medium", "target_fps": 0}}).raise_for_status()
        response = http.get("/v1/frame", params={"format": "png"})
        assert response.headers["x-ig-quality"].startswith("scale=1; rungs=")
        assert response.headers["x-ig-quality"].endswith("; target=0; met=true")
        assert re.search(r"^igserver_quality_target_fps 0\.0$", http.get("/metrics").text, re.M)
        http.patch("/v1/state", json={"quality": {"preset": "auto", "target_fps": 20}}).raise_for_status()


def test_websocket_and_mjpeg(server):
    with connect(server.url.replace("http", "ws") + "/v1/ws", compression=None) as ws:
        ws.send(msgpack.packb({"type": "hello", "credits": 1, "format": "jpeg"}))
        for _ in range(20):  # the first may be a frame of the state before the target was set again
            message = msgpack.unpackb(ws.recv(10.0), raw=False)
            if message["quality"]["target_fps"] == 20:
                break
            ws.send(msgpack.packb({"type": "ack", "frame": message["frame"]}))
    quality = message["quality"]
    assert quality["target_fps"] == 20 and 0.5 <= quality["scale"] <= 1.0 and quality["error"] >= 0.0
    assert isinstance(quality["met"], bool) and quality["rungs"]
    with httpx.Client(base_url=server.url, timeout=30) as http:
        with http.stream("GET", "/v1/stream.mjpg", params={"frames": 1}) as response:
            head = b""
            for chunk in response.iter_bytes():
                head += chunk
                if b"\r\n\r\n" in head.split(b"--igframe", 1)[-1]:
                    break
    part = head.split(b"--igframe", 1)[1].split(b"\r\n\r\n", 1)[0].decode()
    value = re.search(r"X-IG-Quality: (.*)", part).group(1).strip()
    assert HEADER.match(value) and HEADER.match(value).group(2) == "20", part


def test_demo_stream_holds_its_target():
    """The demo requested at 640x360 with target 25 fps streams at >= 20 fps at a client (today, with no
    target: ~13). Tolerance: the target is 24 fps with a 45 ms p95 on a quiet 2-core machine; the suite
    shares those cores with other test processes, whose load the controller can only see as a slower
    machine (it holds the cheapest point then and reports it), so the test asks 80 % of the target on
    the mean and leaves the p95 to the measurement in docs/operations.md."""
    import time

    import numpy as np

    from igserver.scene import apply_patch, load_scene

    scene = apply_patch(load_scene("demo"), {"camera": {"width": 640, "height": 360},
                                             "quality": {"preset": "auto", "target_fps": 25}})
    with LoopbackServer(scene, ServerSettings()) as srv, httpx.Client(base_url=srv.url, timeout=60) as http:
        http.get("/v1/frame").raise_for_status()
        arrivals, headers = [], []
        with http.stream("GET", "/v1/stream.mjpg", params={"frames": 300}) as response:
            buf = b""
            for chunk in response.iter_bytes():
                buf += chunk
                while (m := re.search(rb"X-IG-Quality: ([^\r]*)\r\n\r\n", buf)) is not None:
                    arrivals.append(time.perf_counter())
                    headers.append(m.group(1).decode())
                    buf = buf[m.end():]
    intervals = np.diff(arrivals[60:])  # after the controller's first moves
    assert len(arrivals) == 300 and 1.0 / np.mean(intervals) >= 20.0, 1.0 / np.mean(intervals)
    # Evenly spaced: no two parts at once followed by a double gap (frames in flight collected right after
    # the frame before went out: 18 % of intervals under 10 ms, a p95 of twice the median). Tolerance: a
    # loaded machine delays a part now and then, and the next one follows it closely.
    pairs = float(np.mean(intervals < 0.3 * np.median(intervals)))
    assert pairs < 0.05, (pairs, np.round(intervals * 1e3).astype(int).tolist())
    assert all("target=25" in h for h in headers)


def test_a_running_clock_animates_at_the_target_rate_when_it_is_higher():
    """While the IG clock runs the pump re-renders at ``animation_fps``; a scene that asks the IG to hold a
    higher frame rate (quality.target_fps) is animated at that rate, else a 60 fps target would stream at
    the animation rate. 64x36 gradient-sky frames take a few ms, so both rates are reachable; tolerances:
    with the target, at least twice the animation rate (it asks 4x); without it, at most 1.4x."""
    scene = Scene.model_validate({"camera": {"width": W, "height": H}, "atmosphere": {"model": "gradient"},
                                  "quality": {"preset": "auto", "target_fps": 20}})
    with LoopbackServer(scene, ServerSettings(animation_fps=5)) as srv, \
            httpx.Client(base_url=srv.url, timeout=60) as http:
        http.patch("/v1/clock", json={"mode": "free", "paused": False, "rate": 1.0}).raise_for_status()
        assert mjpeg_rate(srv.url, frames=27, warmup=3)["fps"] >= 10.0
        http.patch("/v1/state", json={"quality": {"target_fps": 0}}).raise_for_status()
        assert mjpeg_rate(srv.url, frames=9, warmup=3)["fps"] <= 7.0


def test_fire_ahead_stands_in_front_of_the_camera():
    from igserver.client.latency import FIRE_AHEAD_M, fire_ahead

    east = Scene.model_validate({"camera": {"position": [100.0, 200.0, 10.0], "heading": 90.0, "pitch": 0.0}})
    assert fire_ahead(east)["position"] == pytest.approx([100.0 + FIRE_AHEAD_M, 200.0, 8.5])
    down = Scene.model_validate({"camera": {"position": [0.0, 0.0, 30.0], "heading": 0.0, "pitch": -30.0}})
    x, y, z = fire_ahead(down)["position"]
    assert (x, y, z) == pytest.approx((0.0, FIRE_AHEAD_M * 3**0.5 / 2, 30.0 - FIRE_AHEAD_M / 2 - 1.5))


def test_the_fire_bench_starts_a_fire_halfway_and_times_the_stream_around_it(server):
    """``igserver bench --service --modes mjpeg-fire``: the stream before and after a host starts a fire
    (the bench's figures are measured on a quiet machine; here only what it reports)."""
    from igserver.client.latency import mjpeg_fire, summarize

    result = mjpeg_fire(server.url, frames=30, warmup=3)
    summary = summarize(result)
    assert summary["fps_before"] > 0 and result["after_ms"] and summary["longest_after"] > 0
    assert len(result["interval_ms"]) >= 10  # the fire came halfway: half the frames before it
    effects = httpx.get(server.url + "/v1/effects", timeout=30).json()
    assert any(e["id"] == "bench-fire" and e["type"] == "fire" for e in effects), effects
    httpx.delete(server.url + "/v1/effects/bench-fire", params={"immediate": True}, timeout=30)
