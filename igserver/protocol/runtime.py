"""Everything one running server holds: settings, accepted state, the render gateway, the frame pump."""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import signal
import threading
import time

import anyio.to_thread

from ..render.memory import release_free_memory
from ..scene.model import Scene
from .frame_pump import FramePump
from .limits import Gate, guard_accept_loop
from .metrics import ServiceMetrics
from .render_gateway import RenderGateway
from .settings import ServerSettings  # noqa: F401  (re-exported: settings live in settings.py)
from .state import StateStore

log = logging.getLogger("igserver.protocol")


def atmosphere_tables_cached(scene: Scene) -> bool:
    """Whether the render process will load ``scene``'s atmosphere tables from the disk cache (True when
    that cannot be told: then no preview is drawn)."""
    try:
        from ..render.shaders import expand
        from ..render.sky.frame_sky import scene_atmosphere
        from ..render.sky.tables import PRECOMPUTE_SHADER, cache_dir

        return (cache_dir() / f"{scene_atmosphere(scene).key(expand(PRECOMPUTE_SHADER))}.npz").is_file()
    except Exception:  # noqa: BLE001 - a preview is optional
        return True


def _ensure_log_output() -> None:
    """Operators see start-up, precompute progress, watchdog and abandoned renders on stderr even when the
    embedding program configured no logging (``igserver serve``); a configured root logger is left alone."""
    package = logging.getLogger("igserver")
    if not logging.getLogger().handlers and not package.handlers:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("%(asctime)s igserver %(levelname)s %(message)s"))
        package.addHandler(handler)
        package.setLevel(logging.INFO)


class IGRuntime:
    def __init__(self, service, scene: Scene | None = None, settings: ServerSettings | None = None):
        self.settings = settings or ServerSettings()
        self.service = service
        self.metrics = ServiceMetrics()
        service.render_timeout_s = self.settings.render_timeout_s
        register = getattr(service, "register_metrics", None)
        if callable(register):  # a service with metrics of its own (igserver/cluster: frame lock, restarts)
            register(self.metrics)
        self.gateway = RenderGateway(service, self.metrics, timed=self.settings.timed_passes)
        self.store = StateStore(scene or service.state, on_accept=self.gateway.push_state)
        self.clock = self.store.clock
        self.gateway.store = self.store
        self.pump = FramePump(
            self.store, self.gateway, self.metrics,
            max_fps=self.settings.max_fps, keepalive_s=self.settings.keepalive_s,
            jpeg_quality=self.settings.jpeg_quality, animation_fps=self.settings.animation_fps,
        )
        self.started_at = time.time()
        self.stream_clients = {"mjpeg": 0, "ws": 0}
        self.start_error: str | None = None
        self.cigi = None  # the CIGI listener (igserver/cigi) when settings.cigi
        self.unresponsive: str | None = None  # the watchdog's finding, None while the render process answers
        self._watchdog_task: asyncio.Task | None = None
        self.stopping = asyncio.Event()  # set at shutdown: open streams end so the server can exit
        self.provisional = False  # the picture shown is the start preview (simplified sky), not the scene
        # Rehearsals (render/rehearsal.py) asked for and not finished: the start's, database loads'.
        self._rehearsals = 0
        self._background: set[asyncio.Task] = set()  # compile_ahead's tasks (held: the loop keeps weak references)
        self.queries = Gate(self.settings.max_concurrent_queries, "water-height queries")
        # queries run on threads of their own, as many as may run at once: each thread that allocates
        # gets a malloc arena of its own, which keeps what it freed; a bounded pool bounds the arenas
        self._query_executor = concurrent.futures.ThreadPoolExecutor(
            max_workers=self.settings.max_concurrent_queries, thread_name_prefix="igserver-query")
        self._register_gauges()

    async def run_query(self, fn, *args):
        """``fn(*args)`` on a query thread. When the last query in progress ends, freed heap goes back to
        the OS: a burst of big queries leaves no lasting growth."""
        try:
            return await asyncio.get_running_loop().run_in_executor(self._query_executor, fn, *args)
        finally:
            if self.queries.held <= 1:
                self._query_executor.submit(release_free_memory)

    async def _show_a_first_picture_while_tables_compute(self, t0: float) -> None:
        """On a first start (no cached atmosphere tables for the start scene) the precompute takes a minute
        or more on a CPU renderer: show the scene with the simple gradient sky first, so the viewer has a
        picture within seconds. It is published as revision -1, never the current state's frame, and
        /v1/ready stays not ready (saying so) until the real first frame."""
        scene = self.store.scene
        if scene.atmosphere.model != "precomputed" or atmosphere_tables_cached(scene):
            return
        coarse = scene.model_copy(update={"atmosphere": scene.atmosphere.model_copy(update={"model": "gradient"})})
        try:
            encoded = await self.gateway.render(coarse, -1, self.store.accepted_at)
        except Exception as exc:  # only a preview: the real frame follows anyway
            log.warning("no preview frame: %s", exc)
            return
        self.provisional = True
        self.pump.publish(encoded)
        log.info("first picture (simplified sky) %.1f s after start; precomputing the atmosphere tables",
                 time.perf_counter() - t0)

    @property
    def rehearsing(self) -> bool:
        """Compiling ahead (or about to): /v1/ready says so and is not ready meanwhile."""
        return self._rehearsals > 0

    def _ask_rehearsal(self) -> bool:
        """Count a rehearsal as asked for, when the settings and the service allow one: ``rehearsing``
        holds from now, before it begins (the start asks before its first frame: the render process says
        it is warm from another thread as that frame ends, and /v1/ready must not see a ready moment
        between). Each rehearsal asked for is run by ``_rehearse``, which ends it."""
        if not (self.settings.rehearse and callable(getattr(self.service, "rehearse", None))):
            return False
        self._rehearsals += 1
        return True

    async def _rehearse(self, scene) -> None:
        """Compile ahead what a fire, lights, precipitation or the sea's states would need
        (render/rehearsal.py), before /v1/ready: a host that starts one at once gets a frame, not a
        frozen stream. Runs a rehearsal ``_ask_rehearsal`` counted."""
        try:
            done = await self.gateway.call(self.service.rehearse, scene)
            log.info("rehearsed %d scenes unseen in %.1f s: %d programs compiled ahead",
                     done["scenes"], done["seconds"], done["programs"])
        except Exception as exc:  # only ahead of time: a program not compiled now is compiled when needed
            log.warning("no rehearsal: %s", exc)
        finally:
            self._rehearsals -= 1

    def compile_ahead(self, scene) -> bool:
        """A database load (CIGI's IG Control) replaced the whole scene: compile ahead what the new scene
        may come to need, as at the start (the stream waits meanwhile, as a real IG's does while it loads,
        and /v1/ready and CIGI's IG mode say so). Returns whether a rehearsal was started. A host's
        whole-state message over protocol v1 does not start one: hosts may send every frame that way."""
        if not self._ask_rehearsal():
            return False
        task = asyncio.get_running_loop().create_task(self._rehearse(scene), name="igserver-compile-ahead")
        self._background.add(task)
        task.add_done_callback(self._background.discard)
        return True

    def _register_gauges(self) -> None:
        m = self.metrics
        m.gauge("igserver_render_process_restarts", "Render-process restarts since the server started",
                lambda: self.service.restarts)
        m.gauge("igserver_render_ready", "1 when the render process is up", lambda: float(self.ready()))
        m.gauge("igserver_stream_clients_mjpeg", "Connected MJPEG clients", lambda: self.stream_clients["mjpeg"])
        m.gauge("igserver_stream_clients_ws", "Connected WebSocket clients", lambda: self.stream_clients["ws"])
        m.gauge("igserver_state_revision", "Accepted state revision", lambda: self.store.revision)

    def not_ready_reason(self) -> str | None:
        """None when a frame can be served within the normal frame time; else why not (for /v1/ready)."""
        info = self.service.info()
        if self.start_error and not info.get("ready"):
            return self.start_error
        if not info.get("ready"):
            return "render process starting"
        unresponsive = self.unresponsive_now()
        if unresponsive:
            return unresponsive
        if self.gateway.recovering:
            return "render process restarting after an abandoned render"
        if not self.service.warm or self.provisional:  # the preview warmed the process, not the scene
            progress = self.service.progress
            shown = "; the picture shows a simplified sky until then" if self.provisional else ""
            if progress:
                return f"precomputing {progress['phase']} ({progress['fraction']:.0%}){shown}"
            if self.provisional:
                return "precomputing the atmosphere tables" + shown
            return "rendering the first frame"
        if self.rehearsing:
            progress = self.service.progress
            done = f" ({progress['fraction']:.0%})" if progress else ""
            return f"compiling ahead the programs of fires, lights, rain, snow and the sea's states{done}"
        return None

    def unresponsive_now(self) -> str | None:
        """The watchdog's finding, or a fresher one (the watchdog looks every watchdog_interval_s)."""
        return self.unresponsive or self.service.unresponsive_reason()

    def ready(self) -> bool:
        return self.not_ready_reason() is None

    async def start(self) -> None:
        """Start the render process in the background: /v1/health answers at once, /v1/ready once the first
        frame (with its table precompute) has rendered, so that ready means "a frame in normal frame time"."""
        self.gateway.push_state(self.store.scene)

        async def start_render_process():
            try:
                t0 = time.perf_counter()
                await self.gateway.call(self.service.start)
                log.info("render process up in %.1f s; rendering the first frame", time.perf_counter() - t0)
                store = self.store
                asked = self._ask_rehearsal()  # see _ask_rehearsal
                try:
                    await self._show_a_first_picture_while_tables_compute(t0)
                    encoded = await self.gateway.render(store.scene, store.revision, store.accepted_at)
                    self.provisional = False
                    self.pump.publish(encoded)
                except Exception:
                    self._rehearsals -= asked  # never run
                    raise
                if asked:
                    await self._rehearse(store.scene)
                log.info("ready: first frame rendered %.1f s after start", time.perf_counter() - t0)
            except Exception as exc:  # ready stays false; the next render retries the start
                self.start_error = f"{type(exc).__name__}: {exc}"
                log.error("render process failed to start: %s", self.start_error)

        _ensure_log_output()
        # anyio loads its event-loop backend on the first sync dependency a request runs; a request that
        # arrives while the descriptors are spent could not open that module's file and would fail with a
        # 500, so the backend (and the threadpool's first worker) is brought up now, while files open
        await anyio.to_thread.run_sync(int)
        loop = asyncio.get_running_loop()
        guard_accept_loop(loop)  # the lifespan starts before uvicorn listens: the accept loop is the guarded one
        self._end_streams_on_exit_signal(loop)
        loop.create_task(start_render_process())
        self._watchdog_task = loop.create_task(self._watchdog(), name="igserver-watchdog")
        self.pump.start()
        if self.settings.cigi:
            from ..cigi.listener import start_cigi

            self.cigi = await start_cigi(self)

    def _end_streams_on_exit_signal(self, loop: asyncio.AbstractEventLoop) -> None:
        """SIGTERM/SIGINT: end the open MJPEG streams at once. uvicorn waits for open responses before it
        runs the app's shutdown, and an MJPEG response never ends by itself (``docker stop`` would end in
        SIGKILL). uvicorn's own handler still runs after ours."""
        if threading.current_thread() is not threading.main_thread():
            return  # a server in a test thread: its owner stops it
        for signum in (signal.SIGTERM, signal.SIGINT):
            previous = signal.getsignal(signum)
            if not callable(previous):
                continue

            def handler(num, frame, previous=previous):
                loop.call_soon_threadsafe(self.stopping.set)
                previous(num, frame)

            signal.signal(signum, handler)

    async def _watchdog(self) -> None:
        """Notice a render process that stops answering (stopped by the OS, heartbeat gone): /v1/ready says
        so at once and renders fail fast; one that stays so past the render time limit is restarted."""
        since: float | None = None
        while True:
            await asyncio.sleep(self.settings.watchdog_interval_s)
            service = self.service
            reason = service.unresponsive_reason() if service.alive and service.ready else None
            now = time.monotonic()
            if reason and since is None:
                since = now
                log.warning("watchdog: %s", reason)
            elif not reason and since is not None:
                log.info("watchdog: render process answers again after %.1f s", now - since)
                since = None
            self.unresponsive = reason
            if reason and now - since > self.settings.render_timeout_s and not self.gateway.recovering:
                log.error("watchdog: render process unresponsive for %.0f s: restarting it", now - since)
                self.gateway.recover_in_background(kill=True)
                since = None

    async def stop(self) -> None:
        self.stopping.set()
        if self.cigi is not None:
            self.cigi.close()
        if self._watchdog_task is not None:
            self._watchdog_task.cancel()
        await self.pump.stop()
        await asyncio.to_thread(self.service.stop)
        self.gateway.shutdown()
        self._query_executor.shutdown(wait=False, cancel_futures=True)
