"""The service as an operator runs it, through a real server and render process:
the IG clock, the render budget, named profile assets, render time limit and watchdog, frame memory,
readiness with precompute progress, and graceful shutdown with open streams."""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import httpx
import msgpack
import numpy as np
import pytest
from PIL import Image
from websockets.sync.client import connect

from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.render.worker import RING_SLOTS
from igserver.scene import Scene

W, H = 64, 36
FIRE_SCENE = {
    # a night fire filling the middle of a tiny frame: the picture is dark except for the flames
    "camera": {"width": W, "height": H, "position": [0.0, -20.0, 3.0], "pitch": 4.0, "exposure_ev": 6.0},
    "time": {"utc": "2026-09-15T21:00:00Z"},
    "atmosphere": {"model": "gradient"},
}


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    """A configured asset directory (set before the render process spawns, so both processes see it)."""
    root = tmp_path_factory.mktemp("assets")
    profiles = root / "profiles"
    profiles.mkdir()
    Image.new("RGBA", (32, 64), (255, 200, 120, 0)).save(profiles / "transparent.png")  # density 0: no flame
    os.mkfifo(profiles / "pipe.png")
    (profiles / "escape.png").symlink_to("/etc/passwd")
    saved = os.environ.get("IGSERVER_ASSETS")
    os.environ["IGSERVER_ASSETS"] = str(root)
    yield root
    if saved is None:
        os.environ.pop("IGSERVER_ASSETS", None)
    else:
        os.environ["IGSERVER_ASSETS"] = saved


@pytest.fixture(scope="module")
def server(assets):
    settings = ServerSettings(keepalive_s=0.25, render_timeout_s=3.0, watchdog_interval_s=0.1,
                              max_raw_frame_bytes=W * H * 4, animation_fps=10)
    with LoopbackServer(Scene.model_validate(FIRE_SCENE), settings) as srv:
        yield srv


@pytest.fixture()
def http(server):
    with httpx.Client(base_url=server.url, timeout=60) as client:
        client.put("/v1/state", json=FIRE_SCENE).raise_for_status()  # each test starts from the fire scene
        client.patch("/v1/clock", json={"mode": "free", "paused": False, "rate": 1.0}).raise_for_status()
        yield client


def png(response) -> np.ndarray:
    assert response.status_code == 200, response.text
    return np.asarray(Image.open(io.BytesIO(response.content)).convert("RGB"), dtype=np.float64)


def flame(image: np.ndarray) -> float:
    # mean of the frame's central third, where the fire stands; night ground and sky are near 0 at EV 6
    h, w = image.shape[:2]
    return float(image[h // 3: 2 * h // 3 + 4, w // 3: 2 * w // 3].mean())


# --------------------------------------------------------------------------- 1. the IG clock

def test_clock_runs_by_itself_pauses_rates_and_sets(http):
    a = http.get("/v1/clock").json()
    time.sleep(0.5)
    b = http.get("/v1/clock").json()
    assert a["mode"] == b["mode"] == "free" and not a["paused"]
    # real time: 0.5 s of sleep, plus scheduling slack on a loaded machine (but never less than the sleep)
    assert 0.45 <= b["sim_time"] - a["sim_time"] <= 3.0
    # frames carry the sim_time they show, and it moves without any host message
    t1 = float(http.get("/v1/frame").headers["x-ig-sim-time"])
    time.sleep(0.3)
    t2 = float(http.get("/v1/frame").headers["x-ig-sim-time"])
    assert t2 > t1

    paused = http.patch("/v1/clock", json={"paused": True}).json()
    time.sleep(0.3)
    assert http.get("/v1/clock").json()["sim_time"] == paused["sim_time"]
    assert http.patch("/v1/clock", json={"sim_time": 100.0}).json()["sim_time"] == 100.0
    http.patch("/v1/clock", json={"paused": False, "rate": 4.0})
    time.sleep(0.5)
    fast = http.get("/v1/clock").json()["sim_time"] - 100.0
    assert 4 * 0.45 <= fast <= 4 * 3.0  # four times real time

    bad = http.patch("/v1/clock", json={"rate": -1, "mode": "sideways"})
    assert bad.status_code == 422
    assert {"#/rate", "#/mode"} <= {e["pointer"] for e in bad.json()["errors"]}


def test_host_sending_sim_time_takes_the_clock(http):
    http.patch("/v1/state", json={"time": {"sim_time": 500.0}}).raise_for_status()
    time.sleep(0.3)
    clock = http.get("/v1/clock").json()
    assert clock["mode"] == "host" and clock["sim_time"] == 500.0
    assert float(http.get("/v1/frame").headers["x-ig-sim-time"]) == 500.0
    # frame-stepping host: each /v1/render shows exactly the sim_time it sent
    stepped = http.post("/v1/render", json={"time": {"sim_time": 500.04}})
    assert float(stepped.headers["x-ig-sim-time"]) == pytest.approx(500.04)
    back = http.patch("/v1/clock", json={"mode": "free"}).json()
    assert back["mode"] == "free" and back["sim_time"] >= 500.04


def test_effect_fades_animate_without_a_host(http):
    http.post("/v1/effects", json={"id": "fade-test", "diameter": 6.0, "fade": 1.0, "seed": 3}).raise_for_status()
    clock = http.get("/v1/clock").json()["sim_time"]
    effect = http.get("/v1/effects/fade-test").json()
    assert abs(effect["changed_at"] - clock) < 1.0  # stamped by the IG clock, not by a host's sim_time
    early = flame(png(http.get("/v1/frame", params={"format": "png"})))
    time.sleep(1.5)  # past the 1 s fade-in
    lit = flame(png(http.get("/v1/frame", params={"format": "png"})))
    # the fade-in grows the container and the opacity from 0: a burning fire is far brighter than at its start
    assert lit > early + 20, (early, lit)
    http.patch("/v1/effects/fade-test", json={"active": False}).raise_for_status()
    time.sleep(1.5)
    out = flame(png(http.get("/v1/frame", params={"format": "png"})))
    assert out < lit - 20, (lit, out)  # "stop" fades the fire out (it used to jump to full strength)
    http.delete("/v1/effects/fade-test", params={"immediate": True})


# --------------------------------------------------------------------------- 2, 2c. accepted states render within a budget

@pytest.mark.parametrize("patch, pointer", [
    ({"camera": {"width": 7680, "height": 4320}}, "#/camera/width"),
    ({"atmosphere": {"quality": "high", "scattering_orders": 32}}, "#/atmosphere/scattering_orders"),
    ({"quality": {"preset": "high"}, "camera": {"width": 640, "height": 360},
      "effects": [{"id": f"f{i}", "diameter": 500.0, "emits_smoke": True} for i in range(64)]}, "#/effects"),
])
def test_over_budget_states_are_rejected_naming_the_field(http, patch, pointer):
    before = http.get("/v1/state").headers["x-ig-revision"]
    response = http.patch("/v1/state", json=patch)
    assert response.status_code == 422
    problem = response.json()
    assert pointer in [e["pointer"] for e in problem["errors"]], problem
    assert "budget" in problem["detail"]
    assert http.get("/v1/state").headers["x-ig-revision"] == before


@pytest.mark.parametrize("utc", ["2026-06-21T22:00:00Z", "2026-06-21T12:00:00Z"])
def test_camera_in_space_renders(http, utc):
    # the model's limit: 1e7 m (it used to fail every frame with log2(0) in the daylight code)
    try:
        http.patch("/v1/state", json={"camera": {"position": [0.0, 0.0, 1.0e7]}, "time": {"utc": utc}}).raise_for_status()
        frame = png(http.get("/v1/frame", params={"format": "png"}))
        assert np.isfinite(frame).all()
    finally:
        http.patch("/v1/state", json=FIRE_SCENE).raise_for_status()


def test_render_failure_detail_has_no_traceback_or_path(server):
    from igserver.render.worker import RenderError

    # a scene the render process cannot draw (no time: model_copy skips validation): the failure and its
    # traceback stay on the server
    scene = Scene.model_validate(FIRE_SCENE)
    broken = scene.model_copy(update={"time": None})
    with pytest.raises(RenderError) as info:
        server.service.render(broken)
    message = str(info.value)
    assert "Traceback" not in message and "/" not in message and ".py" not in message
    assert server.service.alive


# --------------------------------------------------------------------------- 2b. profiles are named assets

@pytest.mark.parametrize("name", ["/proc/self/fd/10", "../../etc/passwd", "pipe.png", "escape.png", "missing"])
def test_profile_paths_devices_and_links_are_refused(http, name):
    http.post("/v1/effects", json={"id": "profiled", "diameter": 6.0}).raise_for_status()
    try:
        response = http.patch("/v1/effects/profiled", json={"profile": name})
        assert response.status_code == 422
        problem = response.json()
        assert [e["pointer"] for e in problem["errors"]] == ["#/profile"]
        assert str(os.environ["IGSERVER_ASSETS"]) not in response.text  # no server paths in the answer
        assert http.get("/v1/effects/profiled").json()["profile"] is None
    finally:
        http.delete("/v1/effects/profiled", params={"immediate": True})


def test_named_profile_changes_the_picture(http):
    http.patch("/v1/clock", json={"paused": True})
    http.post("/v1/effects", json={"id": "profiled", "diameter": 6.0, "fade": 0.0, "seed": 3}).raise_for_status()
    try:
        burning = flame(png(http.get("/v1/frame", params={"format": "png"})))
        http.patch("/v1/effects/profiled", json={"profile": "transparent"}).raise_for_status()
        clear = flame(png(http.get("/v1/frame", params={"format": "png"})))
        # the transparent profile has zero density everywhere: the flame disappears from the frame
        assert burning > clear + 20, (burning, clear)
    finally:
        http.delete("/v1/effects/profiled", params={"immediate": True})


# --------------------------------------------------------------------------- 2e. render time limit, watchdog

def wait_until_ready(http, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while http.get("/v1/ready").status_code != 200:
        assert time.monotonic() < deadline, http.get("/v1/ready").json()
        time.sleep(0.05)


def test_render_over_time_limit_is_abandoned_and_state_falls_back(server, http):
    http.patch("/v1/clock", json={"paused": True})
    http.patch("/v1/state", json={"camera": {"heading": 0.0}}).raise_for_status()
    png(http.get("/v1/frame", params={"format": "png"}))  # a good state, rendered
    service, restarts, pid = server.service, server.service.restarts, server.service.pid
    pump, deadline = server.runtime.pump, time.monotonic() + 10
    while pump.subscribers or server.runtime.gateway.in_flight:  # a stream left by an earlier test is gone
        assert time.monotonic() < deadline
        time.sleep(0.05)
    # a state that hangs the renderer: its render overruns the time limit while the process runs (a
    # frame big enough to take more than the limit's 0.1 ms however warm the renderer)
    revision = int(http.patch("/v1/state", json={"camera": {"heading": 10.0, "width": 1280, "height": 720}}
                              ).headers["x-ig-revision"])
    service.render_timeout_s = 1e-4
    try:
        answer = http.get("/v1/frame")
    finally:
        service.render_timeout_s = 3.0
    assert answer.status_code == 503 and answer.json()["kind"] == "render_unavailable", (
        answer.status_code, answer.headers, server.runtime.pump.subscribers)
    assert "time limit" in answer.json()["detail"]
    ready = http.get("/v1/ready").json()
    assert ready["fault"]["revision"] == revision
    # the hung state is not rendered again: the accepted state is the last one that rendered
    assert http.get("/v1/state").json()["camera"]["heading"] == 0.0
    assert http.get("/v1/state").json()["camera"]["width"] == W
    wait_until_ready(http, 60)
    assert service.restarts == restarts + 1 and service.pid != pid
    assert http.get("/v1/frame").status_code == 200
    assert http.get("/v1/ready").json()["fault"] is None  # recovered: nothing is wrong now


def stop_while_rendering(server, http, patch: dict) -> tuple[threading.Thread, dict, int]:
    """Accept ``patch`` and SIGSTOP the render process while it renders that state for a GET /v1/frame
    (running in the returned thread; its answer lands in the dict). Returns the stopped pid."""
    service = server.service
    for _ in range(10):
        wait_until_ready(http, 60)
        http.patch("/v1/state", json=patch).raise_for_status()
        result: dict = {}
        getter = threading.Thread(target=lambda: result.update(r=http.get("/v1/frame")))
        getter.start()
        deadline = time.monotonic() + 5
        while service.rendering_since is None and getter.is_alive() and time.monotonic() < deadline:
            time.sleep(0.0005)
        if service.rendering_since is not None:
            pid = service.pid
            os.kill(pid, signal.SIGSTOP)
            return getter, result, pid
        getter.join()
        patch = {"camera": {"heading": patch["camera"]["heading"] + 0.5}}  # a new state: rendered again
    pytest.skip("could not catch a render in flight")


def test_a_state_rendering_when_the_process_is_stopped_is_kept_and_rendered_after_restart(server, http):
    http.patch("/v1/clock", json={"paused": True})
    http.patch("/v1/state", json={"camera": {"heading": 0.0}}).raise_for_status()
    png(http.get("/v1/frame", params={"format": "png"}))
    restarts = server.service.restarts
    getter, result, pid = stop_while_rendering(server, http, {"camera": {"heading": 44.0}})
    heading = http.get("/v1/state").json()["camera"]["heading"]
    try:
        getter.join(30)  # the watchdog restarts a process stopped longer than the render time limit (3 s)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGCONT)
    assert result["r"].status_code == 200, result["r"].text  # rendered by the new process
    assert server.service.restarts == restarts + 1 and server.service.pid != pid
    assert http.get("/v1/state").json()["camera"]["heading"] == heading  # the valid state was kept
    wait_until_ready(http, 60)
    assert http.get("/v1/ready").json()["fault"] is None


def test_watchdog_notices_a_stopped_render_process(server, http):
    service = server.service
    wait_until_ready(http, 60)  # a restart left by an earlier test is over
    pid = service.pid
    os.kill(pid, signal.SIGSTOP)
    try:
        deadline = time.monotonic() + 5
        while http.get("/v1/ready").status_code == 200:
            assert time.monotonic() < deadline, "the watchdog did not notice"
            time.sleep(0.05)
        ready = http.get("/v1/ready").json()
        assert "stopped" in ready["unresponsive"]
        t0 = time.perf_counter()
        http.patch("/v1/state", json={"camera": {"pitch": 5.0}})
        answer = http.get("/v1/frame")
        assert answer.status_code == 503 and time.perf_counter() - t0 < 2.0  # at once, not after the stop
    finally:
        os.kill(pid, signal.SIGCONT)
    wait_until_ready(http, 10)
    assert service.pid == pid  # resumed in time: no restart needed


# --------------------------------------------------------------------------- 2c, 2d. frame memory

def deleted_shm_mappings(pid: int) -> list[str]:
    with open(f"/proc/{pid}/maps") as f:
        # psm_: SharedMemory ring slots (pym-: multiprocessing's own 4 KB heap for the heartbeat, unlinked by design)
        return [line for line in f if "/dev/shm/psm_" in line and "(deleted)" in line]


def shm_mappings(pid: int) -> set[str]:
    with open(f"/proc/{pid}/maps") as f:
        return {line.split()[-1] for line in f if "/dev/shm/psm_" in line and "(deleted)" not in line}


def test_old_ring_slots_are_unmapped_in_both_processes(server, http):
    http.patch("/v1/clock", json={"paused": True})
    for width, height in ((160, 90), (96, 54), (128, 72), (W, H)):
        http.patch("/v1/state", json={"camera": {"width": width, "height": height}}).raise_for_status()
        assert http.get("/v1/frame").status_code == 200
    render_pid = server.service.pid
    assert deleted_shm_mappings(render_pid) == [] and deleted_shm_mappings(os.getpid()) == []
    assert len(shm_mappings(render_pid)) <= RING_SLOTS


def test_raw_frames_are_bounded(server, http):
    http.patch("/v1/state", json={"camera": {"width": 2 * W, "height": 2 * H}}).raise_for_status()
    try:
        response = http.get("/v1/frame", params={"format": "raw"})
        assert response.status_code == 413 and response.json()["errors"][0]["pointer"] == "#/format"
        with connect(server.url.replace("http", "ws") + "/v1/ws", compression=None) as ws:
            ws.send(msgpack.packb({"type": "hello", "format": "raw", "id": 1}))
            reply = msgpack.unpackb(ws.recv(10), raw=False)
            assert reply["type"] == "error" and reply["problem"]["kind"] == "limits"
        assert http.get("/v1/frame", params={"format": "png"}).status_code == 200
    finally:
        http.patch("/v1/state", json={"camera": {"width": W, "height": H}}).raise_for_status()


# --------------------------------------------------------------------------- 5. readiness, shutdown

def test_ready_only_after_the_first_frame_with_precompute_progress(tmp_path, monkeypatch):
    # a fresh table cache: the first frame must precompute (low table quality keeps it to seconds)
    monkeypatch.setenv("IGSERVER_CACHE", str(tmp_path))
    scene = Scene.model_validate({"camera": {"width": W, "height": H},
                                  "atmosphere": {"model": "precomputed", "quality": "low", "visibility": 23456.0}})
    srv = LoopbackServer(scene, ServerSettings(keepalive_s=0.25))
    srv.thread.start()
    seen = []
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                response = httpx.get(srv.url + "/v1/ready", timeout=10)
            except httpx.TransportError:
                time.sleep(0.05)
                continue
            seen.append((response.status_code, response.json()))
            if response.status_code == 200:
                break
            assert time.monotonic() < deadline
            time.sleep(0.02)
        body = seen[-1][1]
        assert body["frames"] >= 1  # ready comes after the first frame, not when the process is up
        # the precompute's end is reported with the frame it preceded; on a loaded machine the answer
        # that carries it may be read a moment after readiness turned true
        until = time.monotonic() + 10.0
        while body["last_precompute"] is None and time.monotonic() < until:
            time.sleep(0.05)
            body = httpx.get(srv.url + "/v1/ready", timeout=10).json()
        assert body["last_precompute"] and body["last_precompute"]["phase"] == "atmosphere tables", (body, seen[-3:])
        assert body["last_precompute"]["elapsed_s"] > 0
        assert any(code == 503 for code, _ in seen)
        # the first frame after ready comes in normal frame time (the tables are resident)
        t0 = time.perf_counter()
        assert httpx.get(srv.url + "/v1/frame", timeout=30).status_code == 200
        assert time.perf_counter() - t0 < 5.0
    finally:
        srv.stop()
        srv.service.stop()


def test_first_start_shows_a_simplified_sky_while_the_tables_compute(tmp_path, monkeypatch, caplog):
    import logging

    monkeypatch.setenv("IGSERVER_CACHE", str(tmp_path))  # nothing cached: a first start
    scene = Scene.model_validate({"camera": {"width": W, "height": H},
                                  "atmosphere": {"model": "precomputed", "quality": "low", "visibility": 12345.0}})
    srv = LoopbackServer(scene, ServerSettings(keepalive_s=0.25))
    caplog.set_level(logging.INFO, logger="igserver")
    srv.thread.start()
    try:
        deadline = time.monotonic() + 120
        preview = None
        while not srv.runtime.ready():
            latest = srv.runtime.pump.latest
            if latest is not None and latest.revision == -1 and preview is None:
                preview = httpx.get(srv.url + "/v1/ready", timeout=10).json()
            assert time.monotonic() < deadline and srv.thread.is_alive()
            time.sleep(0.01)
        assert preview is not None, "no picture before the tables were ready"
        assert preview["ready"] is False and "simplified sky" in preview["error"]
        assert httpx.get(srv.url + "/v1/ready", timeout=10).status_code == 200
        assert srv.runtime.pump.latest.revision == srv.runtime.store.revision  # the scene itself now
        assert "precomputing" in caplog.text
    finally:
        srv.stop()
        srv.service.stop()
    # a second start finds the tables cached: no preview, and the log does not say it precomputes
    caplog.clear()
    with LoopbackServer(scene, ServerSettings(keepalive_s=0.25)) as again:
        assert not again.runtime.provisional and again.service.last_progress is None
    assert "precomputing" not in caplog.text


class _FirstFrameLandsMidRequest:
    """A render service whose first frame completes between two reads of one /v1/ready request: the
    first ``info()`` sees no frame yet, everything read after it sees the frame counted and warm."""

    render_timeout_s = 10.0
    alive = True
    progress = None
    last_progress = {"phase": "atmosphere tables", "elapsed_s": 1.0}

    def __init__(self):
        self.ig_frame, self.warm = 0, False

    def info(self) -> dict:
        frames = self.ig_frame
        self.ig_frame, self.warm = 1, True  # the executor thread's frame lands here
        return {"ready": True, "restarts": 0, "pid": 1, "frames": frames}

    def unresponsive_reason(self):
        return None

    def set_state(self, scene):
        pass


def test_ready_never_reports_a_frame_count_older_than_its_answer():
    # CI once read ready=true with frames=0: the report read the frame count before deciding readiness,
    # and the first frame landed in between
    import asyncio

    from igserver.protocol.routers.health import ready
    from igserver.protocol.runtime import IGRuntime

    runtime = IGRuntime(_FirstFrameLandsMidRequest(), Scene(), ServerSettings())
    try:
        response = asyncio.run(ready(runtime))
    finally:
        runtime.gateway.executor.shutdown()
    body = json.loads(response.body)
    assert response.status_code == 200 and body["ready"] and body["frames"] >= 1


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sigterm_exits_within_5_s_with_open_streams(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text(f'[camera]\nwidth = {W}\nheight = {H}\n[atmosphere]\nmodel = "gradient"\n')
    port = free_port()
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    server = subprocess.Popen([sys.executable, "-m", "igserver.protocol", "--scene", str(scene), "--port", str(port)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                if httpx.get(url + "/v1/ready", timeout=5).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert server.poll() is None and time.monotonic() < deadline
            time.sleep(0.1)
        with httpx.Client(timeout=30) as client, client.stream("GET", url + "/v1/stream.mjpg") as stream, \
                connect(f"ws://127.0.0.1:{port}/v1/ws", compression=None) as ws:
            ws.send(msgpack.packb({"type": "hello", "credits": 2}))
            ws.recv(10)  # a frame: the WebSocket stream is open
            chunks = stream.iter_bytes()
            next(chunks)  # the MJPEG stream is open and sending
            t0 = time.perf_counter()
            server.send_signal(signal.SIGTERM)
            server.wait(10)
            elapsed = time.perf_counter() - t0
        print(f"SIGTERM to exit with an open MJPEG and WebSocket stream: {elapsed:.2f} s")
        assert elapsed < 5.0
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()


def test_clock_arithmetic_with_a_fake_monotonic_clock():
    from igserver.protocol.clock import ClockChange, IGClock

    now = [1000.0]
    clock = IGClock(sim_time=10.0, now=lambda: now[0])
    now[0] += 2.0
    assert clock.sim_time() == 12.0 and clock.running
    clock.change(ClockChange(rate=0.5))  # from this instant on at half speed; the past is kept
    now[0] += 2.0
    assert clock.sim_time() == 13.0
    clock.change(ClockChange(paused=True))
    now[0] += 5.0
    assert clock.sim_time() == 13.0 and not clock.running
    clock.change(ClockChange(paused=False, sim_time=100.0))
    now[0] += 1.0
    assert clock.sim_time() == 100.5
    clock.host_sent(42.0)
    now[0] += 3.0
    assert clock.mode == "host" and clock.sim_time() == 42.0 and not clock.running
    clock.change(ClockChange(mode="free"))
    now[0] += 2.0
    assert clock.sim_time() == 43.0  # runs on from the host's value at the rate set before


def test_render_process_memory_is_flat_over_frames(server, http):
    """The render process holds what the first frames of a scene need (programs and their JIT code, tables,
    models: docs/operations.md, memory) and nothing more per frame: a leak or an unbounded cache shows here."""
    from igserver.scene.files import load_scene

    demo = load_scene("demo").model_dump(mode="json")
    demo["camera"].update(width=W, height=H)
    demo["atmosphere"]["model"] = "gradient"  # no table precompute under this server's 3 s render limit
    http.put("/v1/state", json=demo).raise_for_status()

    def rss_mb() -> float:
        with open(f"/proc/{server.service.pid}/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024

    def frames(n: int) -> None:
        for i in range(n):  # a new sim_time each: every frame is drawn
            http.patch("/v1/state", json={"time": {"sim_time": 100.0 + i * 0.37}}).raise_for_status()
            assert http.get("/v1/frame").status_code == 200

    frames(5)
    warm = rss_mb()
    frames(40)
    grown = rss_mb() - warm
    print(f"render process: {warm:.0f} MB after 5 demo frames, {grown:+.1f} MB after 40 more")
    assert grown < 8.0
