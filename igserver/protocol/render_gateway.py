"""Render gateway: the async face of the blocking ``RenderService``, metrics on every frame.

All calls into ``RenderService`` go through one executor thread: they are blocking, and one thread
keeps their order (set_state before the render that follows it) without extra locking.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import time

from ..render.worker import RenderError, RenderTimeout
from ..scene.model import Scene
from .channels import frame_parts
from .encoded_frame import EncodedFrame
from .metrics import ServiceMetrics
from .state import StateStore

log = logging.getLogger("igserver.protocol")

TIMED_EVERY = 30  # frames per frame whose passes are timed for /metrics


class RenderGateway:
    """Async face of the blocking ``RenderService``: one executor thread, metrics on every frame.

    A render that fails (overran its time limit, or crashed the process twice) makes the store fall back
    to the last state that rendered; the failure is kept in ``fault`` for /v1/ready and the caller gets a
    problem. The render process is restarted and warmed up with the good state in the background.
    """

    def __init__(self, service, metrics: ServiceMetrics, timed: bool = True):
        self.service = service
        self.metrics = metrics
        # Per-pass times for /metrics, on one frame in TIMED_EVERY: timing a pass waits for it to finish
        # (ctx.finish), which keeps the next pass from overlapping it and, on a GPU, the CPU from running
        # ahead; sampled, the histograms fill while the other frames run unsynchronised.
        self.timed = timed
        self._frames_asked = 0
        self.executor = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="igserver-render")
        self.busy_since: float | None = None
        self.store: StateStore | None = None  # set by the runtime: falls back on a failed render
        self.fault: dict | None = None  # the last abandoned state: {"revision", "detail", "fallback_revision"}
        self.recovering = False  # restarting the render process after an abandoned render
        self.rendered_revision = -1  # the newest revision a frame came back for
        # frames in flight when the service has them (the render process's does; test doubles may not)
        self.pipelined = callable(getattr(service, "submit", None))

    async def call(self, fn, *args):
        return await asyncio.get_running_loop().run_in_executor(self.executor, fn, *args)

    def push_state(self, scene: Scene) -> None:
        """Hand the accepted state to the service (what a restarted render process gets). Not awaited:
        the executor keeps it ordered before any later render."""
        self.executor.submit(self.service.set_state, scene)

    async def render(self, scene: Scene, revision: int, accepted_at: float) -> EncodedFrame:
        reason = self.service.unresponsive_reason() if self.service.alive else None
        if reason is not None:  # answer at once instead of queueing behind a stopped process
            raise RenderError(reason)

        def blocking():
            self.busy_since = time.perf_counter()
            try:
                return self.service.render(scene, timed=self._timed_now())
            finally:
                self.busy_since = None

        t0 = time.perf_counter()
        try:
            frame = await self.call(blocking)
        except RenderError as exc:
            self.metrics.render_errors.inc()
            self._abandon(revision, exc)
            raise
        except Exception:
            self.metrics.render_errors.inc()
            raise
        return self._delivered(frame, revision, accepted_at, t0)

    def _timed_now(self) -> bool:
        self._frames_asked += 1
        return self.timed and self._frames_asked % TIMED_EVERY == 1

    @property
    def in_flight(self) -> int:
        """Frames submitted whose pixels have not come back yet."""
        return self.service.in_flight if self.pipelined else 0

    async def submit(self, scene: Scene, revision: int, accepted_at: float) -> EncodedFrame | None:
        """Draw ``scene`` and return the frame submitted before it (None when none was in flight). Each
        frame keeps the revision and host_frame of its own state, whatever was submitted after it."""
        reason = self.service.unresponsive_reason() if self.service.alive else None
        if reason is not None:
            raise RenderError(reason)
        frame = await self._pipelined_call(self.service.submit, scene, self._timed_now(),
                                           (revision, accepted_at, time.perf_counter()))
        return None if frame is None else self._delivered(frame, *frame.tag)

    async def collect(self) -> EncodedFrame | None:
        """The frame in flight (None if none): taken when no new state is due."""
        frame = await self._pipelined_call(self.service.collect)
        return None if frame is None or frame.tag is None else self._delivered(frame, *frame.tag)

    async def _pipelined_call(self, fn, *args):
        def blocking():
            self.busy_since = time.perf_counter()
            try:
                return fn(*args)
            finally:
                self.busy_since = None

        try:
            return await self.call(blocking)
        except RenderError as exc:
            self.metrics.render_errors.inc()
            if args:  # the submitted state failed to draw
                self._abandon(args[2][0], exc)
            raise
        except Exception:
            self.metrics.render_errors.inc()
            raise

    def _delivered(self, frame, revision: int, accepted_at: float, t0: float) -> EncodedFrame:
        """Metrics of a frame that came back, the store told its revision rendered. ``t0``: perf_counter s
        when it was asked for (its render_call_ms includes the time it spent in flight)."""
        call_ms = (time.perf_counter() - t0) * 1e3
        self.metrics.frames_rendered.inc()
        self.metrics.observe_channels(list(frame_parts(frame)))
        self.metrics.frame_ms.observe(frame.render_ms)
        self.metrics.observe_quality(getattr(frame, "overload", None))
        for name, ms in (frame.pass_ms or {}).items():
            self.metrics.pass_ms.observe(ms, **{"pass": name})
        if self.store is not None:
            self.store.mark_rendered(revision)
        self.rendered_revision = max(self.rendered_revision, revision)
        if self.fault is not None and self.fault["revision"] == revision:
            self.fault = None  # it rendered after all: no longer a fault to report
        return EncodedFrame(frame, revision, accepted_at, call_ms)

    def _abandon(self, revision: int, exc: RenderError) -> None:
        """Fall back from a state that cannot render, and get the render process back in the background."""
        if revision == self.rendered_revision:
            # this state has rendered: the process failed, not the state (it was killed, stopped, starved of
            # memory by something else): the state stays, the process is restarted if it is gone
            log.error("render of revision %d failed (%s); it had rendered, so it stays", revision, exc)
            if isinstance(exc, RenderTimeout) or not self.service.alive:
                self.recover_in_background()
            return
        fallback = self.store.fall_back(revision) if self.store is not None else None
        if fallback is None and not isinstance(exc, RenderTimeout):
            return  # nothing better to show, and the process is up: keep the state, report the error
        self.fault = {"revision": revision, "detail": str(exc), "fallback_revision": fallback}
        log.error("state revision %d abandoned (%s); falling back to revision %s", revision, exc, fallback)
        self.recover_in_background()

    def recover_in_background(self, kill: bool = False) -> None:
        """Restart the render process (``kill``: first kill a hung one) and render one frame of the current
        state, in the executor; ``recovering`` is true until then (/v1/ready answers not ready)."""
        self.recovering = True
        scene = self.store.scene if self.store is not None else None
        if kill:
            self.service.kill()

        def recover():
            try:
                self.service.ensure_started()
                if scene is not None:  # warm up: ready means the next frame comes in normal frame time
                    self.service.render(scene, timed=False)
                self.fault = None  # recovered: /v1/ready reports what is wrong now, the log what was
            except Exception as error:  # the next render retries the start
                log.error("render process recovery failed: %s", error)
            finally:
                self.recovering = False

        self.executor.submit(recover)

    def shutdown(self) -> None:
        self.executor.shutdown(wait=False, cancel_futures=True)
