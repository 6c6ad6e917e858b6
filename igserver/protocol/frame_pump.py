"""Frames for streams: one render loop shared by every stream client, latest-frame-wins delivery.

The pump renders the latest accepted state whenever it changed (at most ``max_fps``) while anybody is
watching, and once per ``keepalive_s`` otherwise so a static scene still shows a live picture. Each
stream client waits for "a frame newer than the one I sent last" and takes whatever is newest then:
a slow client skips frames instead of building a backlog, and never slows the others down.

Frames in flight: the pump submits a state and gets the frame drawn before it back (``submit``), so
the render process draws frame N+1 while frame N's pixels are copied out and the server encodes and
sends N; the stream's rate is set by the slowest of those, not by their sum. Whenever the pump would
wait instead of drawing (no new state, or the ``max_fps`` cap) it takes the frame in flight at once
(``collect``): a host that waits for each frame sees the same latency as before, and a saturated
stream at most one frame interval more.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time

from ..scene.model import Scene
from .encoded_frame import EncodedFrame
from .metrics import ServiceMetrics
from .render_gateway import RenderGateway
from .state import StateStore

log = logging.getLogger("igserver.protocol")


class FramePump:
    def __init__(
        self,
        store: StateStore,
        gateway: RenderGateway,
        metrics: ServiceMetrics,
        max_fps: float = 60.0,
        keepalive_s: float = 1.0,
        jpeg_quality: int = 85,
        animation_fps: float = 30.0,
    ):
        self.store = store
        self.gateway = gateway
        self.metrics = metrics
        self.min_interval = 1.0 / max_fps
        # while the IG clock runs, sim_time moves every instant: frames are re-rendered at this rate
        self.animation_interval = 1.0 / animation_fps
        self.keepalive_s = keepalive_s
        self.jpeg_quality = jpeg_quality
        self.latest: EncodedFrame | None = None
        self.subscribers = 0
        self.last_error: str | None = None
        self._published = asyncio.Event()
        self._published_at = 0.0  # perf_counter s of the latest frame's publication
        self._wake = asyncio.Event()
        self._task: asyncio.Task | None = None
        self._submitted_revision: int | None = None  # the state of the newest frame submitted
        self._encodes: set[asyncio.Task] = set()  # stream encodings running beside the next draw

    # -- lifecycle
    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run(), name="igserver-frame-pump")

    async def stop(self) -> None:
        for task in list(self._encodes):
            task.cancel()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task

    @contextlib.contextmanager
    def subscription(self):
        """While held, the pump keeps rendering. Stream handlers hold one per connected client."""
        self.subscribers += 1
        self._wake.set()
        try:
            yield self
        finally:
            self.subscribers -= 1

    # -- frames
    def publish(self, encoded: EncodedFrame) -> None:
        """Make a frame the latest (also used by /v1/render and /v1/frame: streams show it too)."""
        if self.latest is not None and encoded.ig_frame <= self.latest.ig_frame:
            return
        self.latest = encoded
        self._published_at = time.perf_counter()
        event, self._published = self._published, asyncio.Event()
        event.set()

    async def next_frame(self, after: EncodedFrame | None, timeout: float | None = None) -> EncodedFrame | None:
        """The newest frame newer than ``after``; None on timeout."""
        deadline = None if timeout is None else time.perf_counter() + timeout
        while self.latest is None or (after is not None and self.latest.ig_frame <= after.ig_frame):
            remaining = None if deadline is None else deadline - time.perf_counter()
            if remaining is not None and remaining <= 0:
                return None
            try:
                await asyncio.wait_for(self._published.wait(), remaining)
            except asyncio.TimeoutError:
                return None
        return self.latest

    async def frame_of_current_state(self) -> EncodedFrame:
        """A frame of the latest accepted state: the pump's if it shows that revision, else render one."""
        latest = self.latest
        # a frame that went without a cluster worker's channels (Frame.missing, igserver/cluster) is drawn again
        if latest is not None and latest.revision == self.store.revision and not getattr(
                latest.frame, "missing", None) and (
                not self.store.clock.running
                or time.perf_counter() - latest.rendered_at < self._animation_interval(self.store.scene)):
            return latest
        encoded = await self.gateway.render(self.store.scene, self.store.revision, self.store.accepted_at)
        self.publish(encoded)
        return encoded

    async def _run(self) -> None:
        last_render = 0.0
        while True:
            gateway = self.gateway
            if self.subscribers == 0:
                if gateway.in_flight:  # nobody waits for it, but /v1/frame may: finish it before sleeping
                    await self._take(gateway.collect())
                    continue
                self._wake.clear()
                await self._wake.wait()
                continue
            latest = self.latest
            # the newest state drawn: the one in flight, else the one shown
            shown = self._submitted_revision if gateway.in_flight else (latest.revision if latest else None)
            stale = shown is None or shown != self.store.revision
            since = time.perf_counter() - last_render
            # a running clock animates the scene (fades, flicker, waves): render at the animation rate, or
            # at the frame rate the scene asks the IG to hold when that is higher (quality.target_fps)
            wait = self._animation_interval(self.store.scene) if self.store.clock.running else self.keepalive_s
            if not stale and since < wait:
                if gateway.in_flight:  # nothing new to draw: show the frame in flight now, not a frame later,
                    # unless the clock animates a state the host has left alone for a frame interval and the
                    # frame before went out under half an interval ago: two frames at once and then none for
                    # two intervals read as a dropped frame, so the frame in flight goes out half an interval
                    # after its predecessor (or with the next draw, if that comes first). A host's new state
                    # is never held back.
                    now = time.perf_counter()
                    hold = 0.5 * wait - (now - self._published_at)
                    if hold > 0.0 and now - self.store.accepted_at > wait:
                        await asyncio.sleep(min(hold, wait - since))
                        continue
                    await self._take(gateway.collect())
                    continue
                # nothing new to show: sleep until the state changes or the next frame is due
                await self.store.wait_for_change(latest.revision, wait - since)
                continue
            if since < self.min_interval:
                if gateway.in_flight:  # a frame waits in flight only while the next one draws, not for the cap
                    await self._take(gateway.collect())
                    continue
                await asyncio.sleep(self.min_interval - since)
            scene, revision, accepted_at = self.store.scene, self.store.revision, self.store.accepted_at
            last_render = time.perf_counter()
            if gateway.pipelined:
                if await self._take(gateway.submit(scene, revision, accepted_at)):
                    self._submitted_revision = revision
            else:
                await self._take(gateway.render(scene, revision, accepted_at))

    def _animation_interval(self, scene: Scene) -> float:
        target = scene.quality.target_fps
        return min(self.animation_interval, 1.0 / target) if target > 0 else self.animation_interval

    async def _take(self, call) -> bool:
        """Await a gateway call; publish the frame it returns and encode it for the streams beside the next
        draw. False when it failed (the loop goes on after a pause)."""
        try:
            encoded = await call
            self.last_error = None
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # render process failed twice in a row: keep the loop, retry soon
            self.last_error = f"{type(exc).__name__}: {exc}"
            log.warning("render failed: %s", self.last_error)
            await asyncio.sleep(0.5)
            return False
        if encoded is not None:
            # the stream format is known: encode once, off the event loop and off the render thread; a
            # client that asks for it meanwhile waits on the same encoding (EncodedFrame's lock)
            task = asyncio.get_running_loop().create_task(
                encoded.encoded_channels("jpeg", self.jpeg_quality, encoded.channel_ids, self.metrics))
            self._encodes.add(task)
            task.add_done_callback(self._encodes.discard)
            self.publish(encoded)
        return True
