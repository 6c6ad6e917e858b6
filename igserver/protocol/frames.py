"""Frames for streams: one render loop shared by every stream client, latest-frame-wins delivery.

The pump renders the latest accepted state whenever it changed (at most ``max_fps``) while anybody is
watching, and once per ``keepalive_s`` otherwise so a static scene still shows a live picture. Each
stream client waits for "a frame newer than the one I sent last" and takes whatever is newest then:
a slow client skips frames instead of building a backlog, and never slows the others down.

All calls into ``RenderService`` go through one executor thread: they are blocking, and one thread
keeps their order (set_state before the render that follows it) without extra locking.

Frames in flight: the pump submits a state and gets the frame drawn before it back (``submit``), so
the render process draws frame N+1 while frame N's pixels are copied out and the server encodes and
sends N; the stream's rate is set by the slowest of those, not by their sum. Whenever the pump would
wait instead of drawing (no new state, or the ``max_fps`` cap) it takes the frame in flight at once
(``collect``): a host that waits for each frame sees the same latency as before, and a saturated
stream at most one frame interval more.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import threading
import time
from dataclasses import dataclass, field

from ..render.overload import quality_header
from ..render.worker import RenderError, RenderTimeout
from ..scene.model import Scene
from .channels import frame_parts
from .imaging import encode_frame
from .metrics import ServiceMetrics
from .state import StateStore

log = logging.getLogger("igserver.protocol")


@dataclass
class EncodedFrame:
    """A rendered frame plus its encodings (made once, shared by every client that sends it)."""

    frame: object  # igserver.render.worker.Frame
    revision: int  # state revision it shows
    accepted_at: float  # perf_counter when that state was accepted
    render_call_ms: float  # wall time of RenderService.render in this process (render + IPC)
    rendered_at: float = field(default_factory=time.perf_counter)
    _encoded: dict = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def ig_frame(self) -> int:
        return self.frame.ig_frame

    @property
    def host_frame(self) -> int:
        return self.frame.host_frame

    def part(self, channel: str | None = None):
        """The Frame of one channel (None: the first; a scene without channels: the frame itself)."""
        parts = frame_parts(self.frame)
        return parts[next(iter(parts)) if channel is None else channel]

    @property
    def channel_ids(self) -> list[str]:
        return list(frame_parts(self.frame))

    def encoded(self, fmt: str, quality: int, metrics: ServiceMetrics | None = None,
                channel: str | None = None) -> tuple[bytes, float]:
        """(bytes, encode_ms) of one channel's image (None: the first), cached per (channel, format, quality).
        Blocking: call from a thread."""
        channel = self.channel_ids[0] if channel is None else channel
        key = (channel, fmt, quality if fmt == "jpeg" else 0)
        with self._lock:
            hit = self._encoded.get(key)
            if hit is None:
                t0 = time.perf_counter()
                data = encode_frame(self.part(channel).rgba, fmt, quality)
                hit = (data, (time.perf_counter() - t0) * 1e3)
                self._encoded[key] = hit
                if metrics is not None:
                    metrics.encode_ms.observe(hit[1], format=fmt)
        return hit

    async def encoded_async(self, fmt: str, quality: int, metrics: ServiceMetrics | None = None,
                            channel: str | None = None) -> tuple[bytes, float]:
        """``encoded`` off the event loop; a cached encoding is returned without a thread hop."""
        channel = self.channel_ids[0] if channel is None else channel
        hit = self._encoded.get((channel, fmt, quality if fmt == "jpeg" else 0))
        if hit is not None:
            return hit
        return await asyncio.to_thread(self.encoded, fmt, quality, metrics, channel)

    async def encoded_channels(self, fmt: str, quality: int, channels: list[str],
                               metrics: ServiceMetrics | None = None) -> dict[str, tuple[bytes, float]]:
        """{channel: (bytes, encode_ms)} of several channels, encoded side by side (the encoder releases the GIL)."""
        encodings = await asyncio.gather(*(self.encoded_async(fmt, quality, metrics, c) for c in channels))
        return dict(zip(channels, encodings))

    @property
    def sim_time(self) -> float:
        return self.frame.sim_time

    def headers(self, channel: str | None = None) -> dict[str, str]:
        """The frame's headers; X-IG-Width/Height are the channel's (None: the first), X-IG-Channel its id
        (empty: the camera of a scene without channels)."""
        part = self.part(channel)
        named = {"X-IG-Channel": self.channel_ids[0] if channel is None else channel}
        return {
            "X-IG-Host-Frame": str(self.host_frame),
            "X-IG-Frame": str(self.ig_frame),
            "X-IG-Sim-Time": f"{self.sim_time:.6f}",
            "X-IG-Render-Ms": f"{self.frame.render_ms:.3f}",
            "X-IG-Width": str(part.width),
            "X-IG-Height": str(part.height),
            "X-IG-EV100": f"{self.frame.ev100:.3f}",
            "X-IG-Illuminance-Lux": f"{self.frame.illuminance_lux:.6g}",
            **named,
            **quality_headers(self.frame),
        }


TIMED_EVERY = 30  # frames per frame whose passes are timed for /metrics


def quality_headers(frame) -> dict[str, str]:
    """``X-IG-Quality``: the frame's operating point (render/overload.py ``quality_header``)."""
    report = getattr(frame, "overload", None)
    return {"X-IG-Quality": quality_header(report)} if report else {}


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
