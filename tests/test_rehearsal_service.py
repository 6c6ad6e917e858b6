"""The server rehearses its start scene (render/rehearsal.py) after the first frame and before /v1/ready,
once, and not at all with ``rehearse`` off: through a real uvicorn server and a GL-free render service."""

from __future__ import annotations

import threading
import time

import httpx
import uvicorn

from igserver.protocol.app import create_app, uvicorn_config
from igserver.protocol.settings import ServerSettings
from test_service_limits import FakeRenderService, FakeServer


class RehearsingService(FakeRenderService):
    """Its rehearsal waits for ``go`` (so a test can look at the server meanwhile) and counts."""

    def __init__(self, scene):
        super().__init__(scene)
        self.go = threading.Event()
        self.rehearsed: list = []

    def rehearse(self, scene=None):
        assert self.warm, "rehearsed before the first frame"
        self.go.wait(30)
        self.rehearsed.append(scene)
        return {"scenes": 4, "programs": 20, "seconds": 0.1}


class RehearsingServer(FakeServer):
    def __init__(self, settings: ServerSettings):
        super().__init__(settings)
        self.service = RehearsingService(self.service.state)  # the app built again around this service
        self.app = create_app(self.service, self.service.state, settings)
        self.runtime = self.app.state.runtime
        self.server = uvicorn.Server(uvicorn_config(self.app, "127.0.0.1", self.port))
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.socket]}, daemon=True)


def serve(rehearse: bool) -> RehearsingServer:
    server = RehearsingServer(ServerSettings(rehearse=rehearse))
    server.thread.start()
    return server


def ready(server) -> tuple[int, dict]:
    reply = httpx.get(f"{server.url}/v1/ready", timeout=5)
    return reply.status_code, reply.json()


def wait_for(condition, within_s: float = 30.0):
    deadline = time.monotonic() + within_s
    while not condition():
        assert time.monotonic() < deadline
        time.sleep(0.02)


def test_ready_waits_for_the_rehearsal_and_says_so():
    server = serve(rehearse=True)
    try:
        wait_for(lambda: server.server.started and server.service.warm)
        status, body = ready(server)
        assert status == 503 and "compiling ahead" in str(body), body
        server.service.go.set()
        wait_for(server.runtime.ready)
        assert ready(server)[0] == 200
        assert len(server.service.rehearsed) == 1
        assert server.service.rehearsed[0].camera == server.service.state.camera  # the start scene
    finally:
        server.service.go.set()
        server.__exit__()


def test_with_rehearse_off_the_server_is_ready_without_one():
    server = serve(rehearse=False)
    try:
        wait_for(lambda: server.server.started and server.runtime.ready())
        assert ready(server)[0] == 200
        assert server.service.rehearsed == []
    finally:
        server.service.go.set()
        server.__exit__()
