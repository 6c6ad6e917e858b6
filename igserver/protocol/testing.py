"""A real uvicorn server on loopback in a background thread, for tests and tools.

Uses the real app and the real render process: only the thread differs from ``igserver serve``.
The listening socket is bound before uvicorn starts (port 0), so parallel test runs never race for a port.
"""

from __future__ import annotations

import socket
import threading
import time

from ..scene.model import Scene
from .app import create_app, uvicorn_config
from .runtime import IGRuntime, ServerSettings


class LoopbackServer:
    def __init__(self, scene: Scene | None = None, settings: ServerSettings | None = None, service=None):
        # service: the render service behind the app (None: the render process; igserver/cluster's)
        self.app = create_app(service, scene=scene or Scene(), settings=settings)
        self.runtime: IGRuntime = self.app.state.runtime
        # proto=IPPROTO_TCP matters: asyncio only sets TCP_NODELAY on accepted sockets whose proto says TCP,
        # and without it Nagle holds each response body for a delayed ACK (~40 ms per request)
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_STREAM, socket.IPPROTO_TCP)
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.socket.bind(("127.0.0.1", 0))
        self.port = self.socket.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}"
        import uvicorn

        self.server = uvicorn.Server(uvicorn_config(self.app, "127.0.0.1", self.port))
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.socket]},
                                       name="igserver-test-server", daemon=True)

    @property
    def service(self):
        return self.runtime.service

    def start(self, timeout: float = 300.0) -> "LoopbackServer":
        self.thread.start()
        deadline = time.monotonic() + timeout
        # ready as /v1/ready means it: the first frame (and its table precompute) has rendered
        while not (self.server.started and self.runtime.ready()):
            if not self.thread.is_alive():
                raise RuntimeError("test server exited during start")
            if self.runtime.start_error:
                raise RuntimeError(f"render process failed to start: {self.runtime.start_error}")
            if time.monotonic() > deadline:
                raise TimeoutError("test server not ready")
            time.sleep(0.05)
        return self

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(30)
        self.socket.close()

    def __enter__(self) -> "LoopbackServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
