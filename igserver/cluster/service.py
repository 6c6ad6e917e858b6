"""``ClusterService``: the render service of a front server whose channels render on Ray actors.

It answers what the server asks of ``RenderService`` (render/worker.py: start, stop, set_state, render,
info, the watchdog's questions), so the same FastAPI app, WebSocket and CIGI listener front it: the
host talks to one address. One frame:

1. its number n and the state's revision; the state's channels split over the workers (config.assign);
2. every worker that is free gets (n, revision, its part of the state: the scene with its channels,
   the one exposure of every worker: cluster/exposure.py) — the state only when it does not hold that
   revision;
3. the barrier: the frame waits for every worker until ``barrier_timeout_ms``; a worker still drawing
   then is reported (``igserver_cluster_barrier_misses_total``) and the frame goes without its channels
   (``Frame.missing``; the WebSocket lists them in ``missing``). The late frame is dropped when it comes;
   the worker gets the next frame after it;
4. the frame: every channel delivered with the one frame number n and the state's host_frame; the
   spread of the channels' completion times is frame lock (``igserver_cluster_frame_spread_seconds``).

A worker that dies is restarted by Ray (``max_restarts``) with an empty state: it answers ``need_state``
and is re-sent the state at once, within the same barrier when there is time.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from ..render.worker import Frame, RenderError
from ..scene.channels import mosaic_layout
from ..scene.model import Scene
from .config import ClusterConfig, assign
from .exposure import SharedExposure
from .metrics import ClusterMetrics

log = logging.getLogger("igserver.cluster")


class ClusterUnavailable(RuntimeError):
    """No worker delivered a frame in time (late, restarting): the state stays; the server answers 503."""


@dataclass
class _Worker:
    """One actor as the front sees it."""

    index: int
    actor: object
    pid: int | None = None
    node: str = ""
    revision: tuple | None = None  # (revision, channel ids) of the part it holds (None: unknown, send it)
    pending: object = None  # the ObjectRef of a frame it has not answered yet
    restarts: int = 0
    missed: int = 0  # frames missed in a row (logged when the streak starts and when it ends)
    dead: bool = False  # Ray will not restart it: its channels are spread over the others
    hello: dict = field(default_factory=dict)


class ClusterService:
    def __init__(self, config: ClusterConfig, scene: Scene | None = None, render_timeout_s: float = 30.0):
        self.config = config
        self._state = scene if scene is not None else config.start_scene()
        self.render_timeout_s = render_timeout_s  # the server sets it; frames are bounded by the barrier
        self.metrics = ClusterMetrics()
        self.exposure = SharedExposure()  # one exposure for every worker's channels
        self.metrics.workers.set(config.workers or 0)
        self._lock = threading.RLock()
        self._workers: list[_Worker] = []
        self._owns_ray = False
        self._revision = 0
        self._revision_scene: Scene | None = None
        self._parts: dict[tuple, Scene] = {}  # (revision, channel ids) -> a worker's part of the state
        self._render_failed = False  # a worker's render raised during this frame  # (revision, worker) -> the worker's part of the state
        self.use_gpu = False
        self.ig_frame = 0
        self.restarts = 0
        self.ready = False
        self.warm = False
        self.rendering_since: float | None = None
        self.progress: dict | None = None
        self.last_progress: dict | None = None

    # -- lifecycle
    def start(self) -> "ClusterService":
        with self._lock:
            if self.ready:
                return self
            import ray

            from .worker import ChannelWorker

            if not ray.is_initialized():
                if self.config.address == "local":
                    ray.init(include_dashboard=False, log_to_driver=False)
                    self._owns_ray = True
                else:
                    ray.init(address=self.config.address, log_to_driver=False)
            gpus = ray.cluster_resources().get("GPU", 0.0)
            self.use_gpu = gpus >= 1 if self.config.gpus == "auto" else bool(self.config.gpus)
            remote = ray.remote(ChannelWorker)
            cpus = self.config.cpus_per_worker
            options = {"num_cpus": cpus, "num_gpus": 1 if self.use_gpu else 0,
                       "max_restarts": self.config.max_restarts, "max_task_retries": 0}
            self._workers = [_Worker(i, remote.options(**options).remote(i, cpus, self.use_gpu))
                             for i in range(self.config.workers or 1)]
            try:
                hellos = ray.get([w.actor.hello.remote() for w in self._workers], timeout=self.config.start_timeout_s)
            except Exception as exc:
                self._kill_all(no_restart=True)
                raise RenderError(f"cluster workers did not start: {type(exc).__name__}: {exc}") from exc
            for w, hello in zip(self._workers, hellos):
                w.pid, w.node, w.hello = hello["pid"], hello["node"], hello
                self.metrics.misses.labels(worker=str(w.index))
                self.metrics.restarts.labels(worker=str(w.index))
                log.info("cluster worker %d: pid %d on %s, %s", w.index, w.pid, w.node, hello["caps"].get("renderer"))
            self.metrics.workers_alive.set(len(self._workers))
            self.ready = True
            return self

    def stop(self) -> None:
        with self._lock:
            self._kill_all(no_restart=True)
            self._workers = []
            self.ready = False
            if self._owns_ray:
                import ray

                ray.shutdown()
                self._owns_ray = False

    def __enter__(self) -> "ClusterService":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _kill_all(self, no_restart: bool) -> None:
        import ray

        for w in self._workers:
            try:
                ray.kill(w.actor, no_restart=no_restart)
            except Exception as exc:  # noqa: BLE001 - already gone
                log.debug("worker %d: %s", w.index, exc)

    @property
    def alive(self) -> bool:
        return self.ready

    @property
    def pid(self) -> int | None:
        return None  # the workers are Ray's processes (info()["cluster"] lists them)

    def kill(self) -> None:
        """Kill every worker (the watchdog's cure): Ray restarts them and they are re-sent the state."""
        with self._lock:
            self._kill_all(no_restart=False)

    def restart(self) -> None:
        self.kill()

    def ensure_started(self) -> None:
        self.start()

    def unresponsive_reason(self) -> str | None:
        return None if self.ready else "cluster workers are not running"

    def os_state(self) -> str | None:
        return None

    def rehearse(self, scene: Scene | None = None) -> dict:
        """Every worker compiles ahead what a fire, lights or precipitation in ``scene`` (default: the
        current state) would need (render/rehearsal.py), all at once. Returns the slowest worker's
        {"scenes", "programs", "seconds"}."""
        import ray

        with self._lock:
            scene = scene or self._state
            self.rendering_since = time.monotonic()
            try:
                done = ray.get([w.actor.rehearse.remote(scene) for w in self._workers if not w.dead],
                               timeout=self.config.start_timeout_s)
            finally:
                self.rendering_since = None
        return max(done, key=lambda d: d["seconds"], default={"scenes": 0, "programs": 0, "seconds": 0.0})

    # -- state
    @property
    def state(self) -> Scene:
        return self._state

    def set_state(self, scene: Scene) -> None:
        with self._lock:
            self._state = scene

    @property
    def workers(self) -> list[_Worker]:
        return list(self._workers)

    def register_metrics(self, service_metrics) -> None:
        """Add the cluster's metrics to the server's /metrics (protocol/runtime.py calls it)."""
        self.metrics.register(service_metrics.registry)

    def info(self) -> dict:
        caps = self._workers[0].hello.get("caps", {}) if self._workers else {}
        return {**caps, "ready": self.ready, "restarts": self.restarts, "pid": None, "frames": self.ig_frame,
                "cluster": {"address": self.config.address, "gpus": self.use_gpu,
                            "workers": [{"index": w.index, "pid": w.pid, "node": w.node, "restarts": w.restarts}
                                        for w in self._workers]}}

    @property
    def in_flight(self) -> int:
        return 0

    # -- frames
    def _revision_of(self, scene: Scene) -> int:
        if scene is not self._revision_scene:
            self._revision += 1
            self._revision_scene = scene
            self._parts.clear()
        return self._revision

    def _part(self, scene: Scene, revision: int, ids: list[str]) -> Scene:
        """A worker's part of the state: the scene with the channels ``ids`` (the state itself when it has no
        channels: the implicit camera channel)."""
        key = (revision, tuple(ids))
        if key not in self._parts:
            chosen = [c for c in scene.channels if c.id in ids]
            self._parts[key] = scene.model_copy(update={"channels": chosen}) if scene.channels else scene
        return self._parts[key]

    def _send(self, w: _Worker, frame: int, revision: int, scene: Scene, ids: list[str], timed: bool, exposure):
        held = (revision, tuple(ids))  # channels move when a worker dies for good: the same revision, new part
        part = self._part(scene, revision, ids) if w.revision != held else None
        w.revision = held  # optimistic: a restarted worker answers need_state
        return w.actor.render.remote(frame, revision, part, timed, exposure)

    def _answer(self, w: _Worker, ref) -> dict | None:
        """The worker's answer to ``ref`` (None: it failed); a new pid is a worker Ray restarted."""
        import ray

        try:
            out = ray.get(ref, timeout=0)
        except Exception as exc:  # noqa: BLE001 - RayActorError (died), RayTaskError (render failed)
            log.warning("cluster worker %d: frame failed: %s", w.index, str(exc).splitlines()[0])
            w.revision = None
            # the render raised (the state's fault, as in one render process), not a worker that went away
            self._render_failed |= isinstance(exc, ray.exceptions.RayTaskError) and not isinstance(
                exc, (ray.exceptions.RayActorError, ray.exceptions.ActorUnavailableError))
            if isinstance(exc, ray.exceptions.ActorDiedError):  # a worker Ray restarts is ActorUnavailableError
                w.dead = True  # Ray will not restart it (max_restarts spent, killed for good)
                self.metrics.workers_alive.set(sum(not x.dead for x in self._workers))
                log.error("cluster worker %d is dead for good: its channels go to the other workers", w.index)
            return None
        if out["pid"] != w.pid:
            if w.pid is not None:
                w.restarts += 1
                self.restarts += 1
                self.metrics.restarts.labels(worker=str(w.index)).inc()
                log.warning("cluster worker %d restarted (pid %s -> %s): state re-sent", w.index, w.pid, out["pid"])
            w.pid = out["pid"]
        if out.get("need_state"):
            w.revision = None
        return out

    def _drain(self) -> None:
        """Answers of frames that went without their worker: dropped, but their news (restart, lost state) kept."""
        import ray

        for w in self._workers:
            if w.pending is not None and ray.wait([w.pending], timeout=0)[0]:
                self._answer(w, w.pending)
                w.pending = None

    def render(self, scene: Scene | None = None, timed: bool = False) -> Frame:
        with self._lock:
            if not self.ready:
                raise RenderError("cluster workers are not running")
            scene = scene or self._state
            revision = self._revision_of(scene)
            frame_no = self.ig_frame + 1
            ids = [c.id for c in scene.channels] or [""]
            parts = assign(ids, self.config, frozenset(w.index for w in self._workers if w.dead))
            self._drain()
            self._render_failed = False
            self.rendering_since = time.monotonic()
            try:
                shared = self.exposure.applies(scene, parts)
                answers = self._round(scene, revision, frame_no, parts, timed,
                                      self.exposure.current if shared else None)
                if shared and answers and self.exposure.update(scene, [a.get("cells") for a in answers.values()]):
                    self.metrics.redraws.inc()  # the first frame, or a jump: drawn again with the new exposure
                    redrawn = self._round(scene, revision, frame_no, parts, timed, self.exposure.current)
                    if len(redrawn) >= len(answers):  # else the first draw: fewer channels, not two exposures
                        answers = redrawn
            finally:
                self.rendering_since = None
            self._report(frame_no, parts, answers)
            return self._gather(scene, frame_no, parts, answers)

    def _round(self, scene: Scene, revision: int, frame_no: int, parts: list[list[str]], timed: bool,
               exposure) -> dict[int, dict]:
        """Send the frame to every free worker with channels in it and wait at the barrier: {worker: answer}."""
        import ray

        deadline = time.monotonic() + self.config.barrier_timeout_ms / 1e3
        calls: dict = {}
        for w, wanted in zip(self._workers, parts):
            if wanted and w.pending is None:  # a worker still drawing an older frame is not queued behind it
                calls[self._send(w, frame_no, revision, scene, wanted, timed, exposure)] = (w, wanted)
        answers: dict[int, dict] = {}
        while calls:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            done, _ = ray.wait(list(calls), num_returns=1, timeout=remaining)
            for ref in done:
                w, wanted = calls.pop(ref)
                out = self._answer(w, ref)
                if out is not None and out.get("need_state"):  # restarted: the state again, same barrier
                    calls[self._send(w, frame_no, revision, scene, wanted, timed, exposure)] = (w, wanted)
                elif out is not None:
                    answers[w.index] = out
        for ref, (w, _) in calls.items():  # missed the barrier: its answer is dropped when it comes
            w.pending = ref
        return answers

    def _report(self, frame_no: int, parts: list[list[str]], answers: dict[int, dict]) -> None:
        """Count every worker that had channels in this frame and delivered none; log streaks, not frames."""
        for w, wanted in zip(self._workers, parts):
            if wanted and w.index not in answers:
                self.metrics.misses.labels(worker=str(w.index)).inc()
                if w.missed == 0:
                    log.warning("frame %d: worker %d missed the barrier (%g ms): frames go without its channels %s "
                                "until it answers", frame_no, w.index, self.config.barrier_timeout_ms, wanted)
                w.missed += 1
            elif w.missed:
                log.warning("frame %d: worker %d is back after %d frames without it", frame_no, w.index, w.missed)
                w.missed = 0

    def _gather(self, scene: Scene, frame_no: int, parts: list[list[str]], answers: dict[int, dict]) -> Frame:
        """One frame of the delivered channels, in the scene's order, with one frame number."""
        if not answers and self._render_failed:  # the server falls back to the last state that rendered
            raise RenderError(f"render of frame {frame_no} failed on the cluster workers")
        if not answers:  # late or restarting workers: not the state's fault, so not a RenderError (that falls back)
            raise ClusterUnavailable(f"no cluster worker delivered frame {frame_no} within the barrier "
                                     f"({self.config.barrier_timeout_ms:g} ms)")
        owner = {cid: i for i, wanted in enumerate(parts) for cid in wanted}
        images = {cid: answers[owner[cid]]["channels"][cid] for cid in owner if owner[cid] in answers}
        done = [answers[owner[cid]]["done"] for cid in images]
        first = answers[min(answers)]
        slowest = max(answers.values(), key=lambda a: a["render_ms"])
        self.ig_frame = frame_no
        self.warm = True
        self.metrics.frames.inc()
        if len(answers) > 1:
            self.metrics.observe_spread(max(done) - min(done))
        missing = [cid for cid in owner if cid not in images]
        if missing:
            self.metrics.incomplete.inc()

        def make(rgba: np.ndarray) -> Frame:
            return Frame(rgba, frame_no, scene.host_frame, slowest["render_ms"], slowest["pass_ms"],
                         slowest["passes"], first["sim_time"], first["ev100"], first["illuminance_lux"], None,
                         first["overload"])

        if not scene.channels:
            return make(images[""])
        size, layout = mosaic_layout(scene)
        mosaic = np.zeros((size.height, size.width, 4), np.uint8)
        channels = {}
        for cid, x, width, height in layout:
            if cid in images:
                mosaic[:height, x:x + width] = images[cid]
                channels[cid] = make(images[cid])
        frame = make(mosaic)
        frame.channels = channels
        frame.missing = missing
        return frame
