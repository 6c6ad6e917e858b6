"""Everything one running server holds: settings, accepted state, the render gateway, the frame pump."""

from __future__ import annotations

import asyncio
import logging
import time

from ..scene.model import Scene
from .frames import FramePump, RenderGateway
from .metrics import ServiceMetrics
from .settings import ServerSettings  # noqa: F401  (re-exported: settings live in settings.py)
from .state import StateStore

log = logging.getLogger("igserver.protocol")


class IGRuntime:
    def __init__(self, service, scene: Scene | None = None, settings: ServerSettings | None = None):
        self.settings = settings or ServerSettings()
        self.service = service
        self.metrics = ServiceMetrics()
        self.gateway = RenderGateway(service, self.metrics, timed=self.settings.timed_passes)
        self.store = StateStore(scene or service.state, on_accept=self.gateway.push_state)
        self.pump = FramePump(
            self.store, self.gateway, self.metrics,
            max_fps=self.settings.max_fps, keepalive_s=self.settings.keepalive_s,
            jpeg_quality=self.settings.jpeg_quality,
        )
        self.started_at = time.time()
        self.stream_clients = {"mjpeg": 0, "ws": 0}
        self.start_error: str | None = None
        self._register_gauges()

    def _register_gauges(self) -> None:
        m = self.metrics
        m.gauge("igserver_render_process_restarts", "Render-process restarts since the server started",
                lambda: self.service.restarts)
        m.gauge("igserver_render_ready", "1 when the render process is up", lambda: float(self.ready()))
        m.gauge("igserver_stream_clients_mjpeg", "Connected MJPEG clients", lambda: self.stream_clients["mjpeg"])
        m.gauge("igserver_stream_clients_ws", "Connected WebSocket clients", lambda: self.stream_clients["ws"])
        m.gauge("igserver_state_revision", "Accepted state revision", lambda: self.store.revision)

    def ready(self) -> bool:
        return bool(self.service.info().get("ready"))

    async def start(self) -> None:
        """Start the render process in the background: /v1/health answers at once, /v1/ready once it is up."""
        self.gateway.push_state(self.store.scene)

        async def start_render_process():
            try:
                await self.gateway.call(self.service.start)
            except Exception as exc:  # ready stays false; the next render retries the start
                self.start_error = f"{type(exc).__name__}: {exc}"
                log.error("render process failed to start: %s", self.start_error)

        asyncio.get_running_loop().create_task(start_render_process())
        self.pump.start()

    async def stop(self) -> None:
        await self.pump.stop()
        await asyncio.to_thread(self.service.stop)
        self.gateway.shutdown()
