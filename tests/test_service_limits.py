"""The service's resource limits, through a real uvicorn server on loopback with a GL-free render service:
connection deadlines and counts, concurrent queries, WebSocket clients and what each may hold, and
profile images. Every limit is a setting; hitting it gives a problem answer or a close code."""

from __future__ import annotations

import contextlib
import socket
import threading
import time

import httpx
import msgpack
import numpy as np
import pytest
import uvicorn
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from igserver.protocol.app import create_app, uvicorn_config
from igserver.protocol.settings import ServerSettings
from igserver.render.worker import Frame
from igserver.scene import Scene

W, H = 64, 36
SCENE = {"camera": {"width": W, "height": H}, "atmosphere": {"model": "gradient"}}


class FakeRenderService:
    """``RenderService``'s face to the protocol, without a process or GL: a frame is the camera's size in
    one grey; ``delay_s`` makes each render take that long."""

    def __init__(self, scene: Scene):
        self.state = scene
        self.render_timeout_s = 30.0
        self.restarts = 0
        self.ready = self.alive = self.warm = False
        self.progress = self.last_progress = None
        self.ig_frame = 0
        self.delay_s = 0.0
        self._lock = threading.Lock()

    def start(self):
        self.ready = self.alive = True
        return self

    def stop(self):
        self.ready = self.alive = False

    def ensure_started(self):
        self.start()

    def kill(self):
        self.alive = False

    def set_state(self, scene):
        self.state = scene

    def unresponsive_reason(self):
        return None if self.alive else "render process is not running"

    def info(self):
        return {"ready": self.ready and self.alive, "restarts": self.restarts, "pid": 1, "frames": self.ig_frame}

    def render(self, scene=None, timed=False):
        scene = scene or self.state
        time.sleep(self.delay_s)
        with self._lock:
            self.ig_frame += 1
            frame = self.ig_frame
        self.warm = True
        rgba = np.full((scene.camera.height, scene.camera.width, 4), 128, np.uint8)
        return Frame(rgba, frame, scene.host_frame, 1.0, sim_time=scene.time.sim_time)


class FakeServer:
    """uvicorn in a thread around the real app and a ``FakeRenderService``."""

    def __init__(self, settings: ServerSettings, scene: dict = SCENE):
        self.service = FakeRenderService(Scene.model_validate(scene))
        self.app = create_app(self.service, self.service.state, settings)
        self.runtime = self.app.state.runtime
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_STREAM, socket.IPPROTO_TCP)
        self.socket.bind(("127.0.0.1", 0))
        self.port = self.socket.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}"
        self.server = uvicorn.Server(uvicorn_config(self.app, "127.0.0.1", self.port))
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.socket]}, daemon=True)

    def __enter__(self) -> "FakeServer":
        self.thread.start()
        deadline = time.monotonic() + 30
        while not (self.server.started and self.runtime.ready()):
            assert time.monotonic() < deadline, "fake server not ready"
            time.sleep(0.02)
        return self

    def __exit__(self, *exc) -> None:
        self.server.should_exit = True
        self.thread.join(30)
        self.socket.close()


def raw_connection(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=5)
    return sock


def closed_by_server(sock: socket.socket, within_s: float) -> bool:
    """True once the server closes ``sock`` (EOF or reset) within ``within_s``."""
    sock.settimeout(within_s)
    try:
        while True:
            data = sock.recv(4096)
            if not data:
                return True
    except (ConnectionResetError, BrokenPipeError):
        return True
    except socket.timeout:
        return False


class ServerProcess:
    """A ``FakeServer`` in a process of its own (its memory and descriptors apart from the test's):
    ``settings`` and ``scene`` are Python expressions; ``rlimit_nofile`` caps its descriptors."""

    SCRIPT = """
import logging, resource, sys
sys.path.insert(0, {tests!r})
if {nofile}:
    resource.setrlimit(resource.RLIMIT_NOFILE, ({nofile}, {nofile}))
logging.basicConfig(level=logging.WARNING, format="%(name)s %(message)s")
from test_service_limits import SCENE, SEA, FakeServer
from igserver.protocol.settings import ServerSettings
with FakeServer(ServerSettings({settings}), {scene}) as srv:
    print(srv.port, flush=True)
    sys.stdin.readline()
"""

    def __init__(self, settings: str, scene: str = "SCENE", rlimit_nofile: int = 0, stderr=None):
        import os
        import subprocess
        import sys

        script = self.SCRIPT.format(tests=os.path.dirname(__file__), nofile=rlimit_nofile, settings=settings,
                                    scene=scene)
        self.process = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=stderr or subprocess.DEVNULL, text=True)
        self.port = int(self.process.stdout.readline())

    def rss_mb(self) -> float:
        with open(f"/proc/{self.process.pid}/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024

    def settled_rss_mb(self, at_least_s: float = 1.0, within_s: float = 10.0) -> float:
        """The resident size once it stops moving (two reads 0.5 s apart within 1 MB): a busy machine
        delays the server's work, not what it holds in the end."""
        time.sleep(at_least_s)
        deadline, last = time.monotonic() + within_s, self.rss_mb()
        while time.monotonic() < deadline:
            time.sleep(0.5)
            now = self.rss_mb()
            if abs(now - last) < 1.0:
                return now
            last = now
        return last

    def __enter__(self) -> "ServerProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.process.stdin.close()
        self.process.wait(30)


# --------------------------------------------------------------------------- connections


def test_silent_trickling_and_stalled_connections_are_closed_after_the_idle_timeout():
    with FakeServer(ServerSettings(idle_timeout_s=0.5)) as srv:
        silent = raw_connection(srv.port)
        trickle = raw_connection(srv.port)
        stalled = raw_connection(srv.port)
        stalled.sendall(b"PUT /v1/state HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                        b"Content-Length: 1000\r\n\r\n{")
        t0 = time.monotonic()
        # a head sent a byte every 0.2 s never completes: the deadline counts from the connection's start
        head = b"GET /v1/health HTTP/1.1\r\nHost: 127.0.0.1\r\n"
        trickle.settimeout(0.2)
        closed = False
        for byte in head:
            try:
                trickle.sendall(bytes([byte]))
                if trickle.recv(1) == b"":
                    closed = True
                    break
            except socket.timeout:
                continue
            except OSError:
                closed = True
                break
            if time.monotonic() - t0 > 5:
                break
        assert closed and time.monotonic() - t0 < 3.0
        assert closed_by_server(silent, 3.0)
        assert closed_by_server(stalled, 3.0)
        # a kept-alive connection is closed after the same silence; a normal request is unaffected
        with httpx.Client(base_url=srv.url) as http:
            assert http.get("/v1/health").status_code == 200
        for sock in (silent, trickle, stalled):
            sock.close()


def test_a_long_response_stream_is_not_cut_by_the_idle_timeout():
    with FakeServer(ServerSettings(idle_timeout_s=0.3, keepalive_s=0.1)) as srv:
        with httpx.Client(timeout=10) as http, http.stream("GET", srv.url + "/v1/stream.mjpg") as stream:
            t0, parts = time.monotonic(), 0
            for chunk in stream.iter_bytes():
                parts += chunk.count(b"--")
                if time.monotonic() - t0 > 1.2:
                    break
            assert time.monotonic() - t0 > 1.2 and parts >= 3


def test_connections_over_the_bound_are_answered_503():
    with FakeServer(ServerSettings(max_connections=4, idle_timeout_s=30)) as srv:
        held = [raw_connection(srv.port) for _ in range(4)]
        time.sleep(0.2)
        try:
            answer = httpx.get(srv.url + "/v1/health", timeout=5)
            assert answer.status_code == 503
        finally:
            for sock in held:
                sock.close()
        deadline = time.monotonic() + 5
        while httpx.get(srv.url + "/v1/health", timeout=5).status_code != 200:
            assert time.monotonic() < deadline
            time.sleep(0.05)


def test_running_out_of_descriptors_logs_one_line_and_recovers(tmp_path):
    log_path = tmp_path / "server.log"
    with open(log_path, "w") as log_file, \
            ServerProcess("idle_timeout_s=1.0", rlimit_nofile=96, stderr=log_file) as server:
        held = []
        for _ in range(200):  # far more than the server's 96 descriptors
            with contextlib.suppress(OSError):
                held.append(socket.create_connection(("127.0.0.1", server.port), timeout=2))
        time.sleep(1.5)
        # the idle ones are closed after 1 s; the server accepts again
        deadline = time.monotonic() + 10
        while True:
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"http://127.0.0.1:{server.port}/v1/health", timeout=2).status_code == 200:
                    break
            assert time.monotonic() < deadline, "the server did not recover"
        for sock in held:
            sock.close()
    text = log_path.read_text()
    assert "Traceback" not in text and text.count("\n") < 10, text[:2000]
    assert "cannot accept connections" in text


FIRST_REQUEST_IMPORTS = """
import socket, sys, time
sys.path.insert(0, {tests!r})
from test_service_limits import SCENE, FakeServer
from igserver.protocol.settings import ServerSettings
with FakeServer(ServerSettings(), SCENE) as srv:
    time.sleep(0.5)
    with socket.create_connection(("127.0.0.1", srv.port), timeout=10) as sock:
        before = set(sys.modules)  # after the client's own name lookup
        sock.sendall(b"GET /v1/health HTTP/1.1\\r\\nHost: 127.0.0.1\\r\\nConnection: close\\r\\n\\r\\n")
        answer = b""
        while chunk := sock.recv(4096):
            answer += chunk
    print(answer.split(b"\\r\\n")[0].decode(), sorted(set(sys.modules) - before))
"""


def test_the_first_request_opens_no_module_file():
    """A request served while the descriptors are spent must not need to open a file: nothing the app
    imports lazily may wait for the first request (anyio's backend did, and answered 500)."""
    import os
    import subprocess
    import sys

    script = FIRST_REQUEST_IMPORTS.format(tests=os.path.dirname(__file__))
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "HTTP/1.1 200 OK []", out.stdout + out.stderr[-2000:]


# --------------------------------------------------------------------------- water-height queries

SEA = {**SCENE, "ocean": {"enabled": True}, "weather": {"wind_speed": 11.0}}


def test_queries_over_the_bound_are_refused_503_with_retry_after_over_rest_and_websocket():
    with FakeServer(ServerSettings(max_concurrent_queries=2), SEA) as srv:
        gate = srv.runtime.queries
        body = {"points": [[0.0, 0.0]]}
        assert httpx.post(srv.url + "/v1/query/water-height", json=body).status_code == 200
        gate.held = 2  # two queries in progress
        try:
            answer = httpx.post(srv.url + "/v1/query/water-height", json=body)
            assert answer.status_code == 503 and answer.headers["retry-after"] == "1"
            assert answer.json()["kind"] == "overloaded"
            with connect(f"ws://127.0.0.1:{srv.port}/v1/ws", compression=None) as ws:
                ws.send(msgpack.packb({"type": "hello", "credits": 0}))
                ws.send(msgpack.packb({"type": "query", "query": "water-height", "id": 5, **body}))
                reply = msgpack.unpackb(ws.recv(5))
                assert reply["type"] == "error" and reply["id"] == 5 and reply["problem"]["kind"] == "overloaded"
        finally:
            gate.held = 0
        assert httpx.post(srv.url + "/v1/query/water-height", json=body).status_code == 200
        assert gate.refused == 2


def test_bursts_of_big_queries_leave_no_lasting_memory_growth():
    from concurrent.futures import ThreadPoolExecutor

    with ServerProcess("max_concurrent_queries=2", "SEA") as server:
        url = f"http://127.0.0.1:{server.port}/v1/query/water-height"
        body = {"points": np.random.default_rng(1).uniform(-1e3, 1e3, (10_000, 2)).tolist()}

        def query(_):
            with httpx.Client(timeout=120) as http:
                return http.post(url, json=body).status_code

        after = []
        with ThreadPoolExecutor(24) as pool:
            for _ in range(6):
                codes = list(pool.map(query, range(24)))
                assert set(codes) <= {200, 503} and 200 in codes and 503 in codes
                after.append(server.settled_rss_mb(at_least_s=0.5))  # what stays, not what a reply holds
    print("server RSS after each burst (MB):", [round(a) for a in after])
    # The first burst brings up the server's threads, each with a malloc arena of its own (measured: the
    # resident size then settles 0-13 MB higher and stays); the growth after it is what is bounded (a
    # server that kept each accepted query's answer grew ~17 MB a burst).
    assert max(after[2:]) < after[1] + 8


# --------------------------------------------------------------------------- WebSocket clients


def ws_hello(port: int, hello: dict) -> socket.socket:
    """A WebSocket client that sends its hello and then never reads (the handshake by hand)."""
    import base64
    import os
    import struct

    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(f"GET /v1/ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                 f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode())
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    payload = msgpack.packb(hello)
    mask = os.urandom(4)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    sock.sendall(struct.pack("!BB", 0x82, 0x80 | len(payload)) + mask + masked)
    return sock


def test_websocket_clients_over_the_bound_are_closed_1013():
    with FakeServer(ServerSettings(max_ws_clients=2)) as srv:
        url = f"ws://127.0.0.1:{srv.port}/v1/ws"
        with connect(url, compression=None) as first, connect(url, compression=None) as second:
            for ws in (first, second):
                ws.send(msgpack.packb({"type": "hello", "credits": 1}))
                assert msgpack.unpackb(ws.recv(5))["type"] == "frame"
            with connect(url, compression=None) as third:
                with pytest.raises(ConnectionClosed) as closed:
                    third.recv(5)
                assert closed.value.rcvd.code == 1013 and "max_ws_clients" in closed.value.rcvd.reason
        deadline = time.monotonic() + 5
        while srv.runtime.stream_clients["ws"]:
            assert time.monotonic() < deadline
            time.sleep(0.02)
        with connect(url, compression=None) as again:  # room again once they left
            again.send(msgpack.packb({"type": "hello", "credits": 1}))
            assert msgpack.unpackb(again.recv(5))["type"] == "frame"


RAW_FRAME_MB = 1920 * 1080 * 4 / 2**20


def test_websocket_clients_that_do_not_read_hold_one_frame_each_and_free_it_when_they_close():
    scene = '{**SCENE, "camera": {"width": 1920, "height": 1080}}'
    with ServerProcess("keepalive_s=0.05, max_fps=20", scene) as server:
        hello = {"type": "hello", "format": "raw", "credits": 16}
        # the baseline: one such client, so that the frame pump runs (rendering, encoding)
        first = ws_hello(server.port, hello)
        base = server.settled_rss_mb(2.0)
        clients = [ws_hello(server.port, hello) for _ in range(6)]
        # each client's socket buffers are full: what is left waits in the server
        held = server.settled_rss_mb(2.0) - base
        for sock in clients:
            sock.close()
        left = server.settled_rss_mb() - base
        first.close()
    print(f"6 stalled raw clients: +{held:.0f} MB ({held / 6 / RAW_FRAME_MB:.2f} frames each); "
          f"after they closed: {left:+.0f} MB")
    assert held < 6 * 1.5 * RAW_FRAME_MB
    assert left < 2 * RAW_FRAME_MB


SERVE = """
import sys
sys.path.insert(0, {tests!r})
from test_service_limits import SCENE, FakeRenderService
from igserver.protocol.app import serve
from igserver.protocol.settings import ServerSettings
from igserver.scene import Scene
scene = Scene.model_validate({{**SCENE, "camera": {{"width": 640, "height": 360}}}})
sys.exit(serve(None, settings=ServerSettings(port={port}), service=FakeRenderService(scene)))
"""


def test_sigterm_with_a_half_closed_websocket_client_exits_0_without_a_traceback():
    import os
    import signal
    import struct
    import subprocess
    import sys

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-c", SERVE.format(tests=os.path.dirname(__file__), port=port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while True:
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"http://127.0.0.1:{port}/v1/ready", timeout=2).status_code == 200:
                    break
            assert server.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        client = ws_hello(port, {"type": "hello", "format": "raw", "credits": 16})
        time.sleep(0.3)  # frames are waiting for the client, which does not read
        mask = os.urandom(4)
        payload = bytes(b ^ mask[i % 4] for i, b in enumerate(struct.pack("!H", 1000)))
        client.sendall(struct.pack("!BB", 0x88, 0x80 | len(payload)) + mask + payload)  # close; never reads
        time.sleep(0.3)
        server.send_signal(signal.SIGTERM)
        assert server.wait(10) == 0
        log = server.stderr.read()
        assert "Traceback" not in log, log
        client.close()
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()


# --------------------------------------------------------------------------- profile images


def png_header_only(width: int, height: int) -> bytes:
    """A PNG that announces ``width`` x ``height`` in a few bytes (a decompression bomb's header)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def test_profile_images_over_the_pixel_bound_are_refused_at_validation(tmp_path, monkeypatch):
    from PIL import Image

    profiles = tmp_path / "profiles"
    profiles.mkdir()
    (profiles / "bomb.png").write_bytes(png_header_only(20000, 10000))
    Image.new("RGBA", (64, 65), (255, 200, 120, 255)).save(profiles / "over.png")
    Image.new("RGBA", (64, 64), (255, 200, 120, 255)).save(profiles / "fits.png")
    (profiles / "text.png").write_text("not an image")
    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    with FakeServer(ServerSettings(max_profile_pixels=64 * 64)) as srv, httpx.Client(base_url=srv.url) as http:
        before = http.get("/v1/state")
        for name, detail in (("bomb", "20000 x 10000 px"), ("over", "64 x 65 px"), ("text", "not a PNG")):
            answer = http.put("/v1/state", json={**SCENE, "effects": [{"id": "f", "profile": name}]})
            assert answer.status_code == 422, answer.text
            error = answer.json()["errors"][0]
            assert error["pointer"] == "#/effects/0/profile" and detail in error["detail"]
            assert http.get("/v1/state").headers["x-ig-revision"] == before.headers["x-ig-revision"]
        assert http.put("/v1/state", json={**SCENE, "effects": [{"id": "f", "profile": "fits"}]}).status_code == 200
        assert http.get("/v1/frame").status_code == 200


def test_the_default_profile_bound_is_1024_by_1024(tmp_path, monkeypatch):
    from igserver.assets.images import DEFAULT_MAX_PROFILE_PIXELS
    from igserver.scene.model import Effect

    assert ServerSettings().max_profile_pixels == DEFAULT_MAX_PROFILE_PIXELS == 1024 * 1024
    profiles = tmp_path / "profiles"
    profiles.mkdir()
    (profiles / "big.png").write_bytes(png_header_only(1024, 1025))
    (profiles / "max.png").write_bytes(png_header_only(1024, 1024))
    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    create_app(FakeRenderService(Scene()), settings=ServerSettings())  # the app sets the bound the model checks
    Effect(id="f", profile="max")
    with pytest.raises(ValueError, match="1024 x 1025 px"):
        Effect(id="f", profile="big")
