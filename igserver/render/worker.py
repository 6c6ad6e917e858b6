"""The client of the render process (render/render_process.py), ``RenderService``.

One spawned process creates the EGL context and keeps every pipeline resident. Commands go in
over a pipe; finished pixels come back through a ring of ``multiprocessing.shared_memory`` slots
(only a small metadata tuple crosses the pipe). If the process dies it is restarted and given the
current accepted state again, so no accepted state is lost. Moderngl never releases the GIL: keeping
GL out of the server process keeps its event loop free of render-sized stalls.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from multiprocessing import shared_memory

import numpy as np

from ..scene.channels import mosaic_layout
from ..scene.model import Scene
from .memory import release_free_memory
from .render_process import FRAMES_IN_FLIGHT, HEARTBEAT_S, render_process_main

RING_SLOTS = 3
START_TIMEOUT_S = 300.0  # first start compiles shaders (tables are built by the first render, with progress)
RENDER_TIMEOUT_S = 30.0  # a frame silent for this long (no frame, no progress message) is abandoned
STALL_S = 2.0  # an idle render process whose heartbeat is this old is not responding

log = logging.getLogger("igserver.render")


class RenderError(RuntimeError):
    """A render failed; the message is safe for a client (no traceback, no server paths)."""


class RenderTimeout(RenderError):
    """A render overran the time limit: the process was killed; the state that caused it is not retried."""


@dataclass
class Frame:
    rgba: np.ndarray  # (height, width, 4) uint8, top row first
    ig_frame: int
    host_frame: int
    render_ms: float
    pass_ms: dict[str, float] = field(default_factory=dict)
    passes: list[str] = field(default_factory=list)
    sim_time: float = 0.0
    ev100: float = 0.0  # exposure used (photometric read-out)
    illuminance_lux: float = 0.0  # natural horizontal illuminance at the camera
    tag: object = None  # what the submitter passed with the scene (frames in flight come back later)
    # the frame's operating point (render/overload.py: scale, rungs, error, target_fps, met; target 0
    # when the scene holds no frame rate)
    overload: dict | None = None
    # A scene with channels (docs/channels.md): each channel's frame by id, in the scene's order, with
    # this frame's ig_frame, host_frame, sim_time, exposure and tag; ``rgba`` is then the channels side
    # by side (scene/channels.py mosaic_layout). None for a scene without channels.
    channels: dict[str, "Frame"] | None = None
    # channels of the scene the frame went without: a cluster worker missed the frame's barrier
    # (igserver/cluster/service.py); always empty from the render process
    missing: list[str] = field(default_factory=list)

    @property
    def width(self) -> int:
        return int(self.rgba.shape[1])

    @property
    def height(self) -> int:
        return int(self.rgba.shape[0])


# --------------------------------------------------------------------------- client side

class RenderService:
    """Thread-safe handle on the render process. The CLI, the service and the tests all use it.

    Liveness: a render that sends nothing (neither its frame nor a progress message) for
    ``render_timeout_s`` is abandoned: the process is killed and ``RenderTimeout`` raised, and the
    scene is not re-sent (the caller falls back to its last good state). ``responsive()`` is the
    watchdog's view: the process exists, is not stopped by the OS, and stamps its heartbeat.
    """

    def __init__(self, scene: Scene | None = None, device_index: int | None = None,
                 render_timeout_s: float = RENDER_TIMEOUT_S):
        self._state = scene or Scene()
        self._device_index = device_index
        self.render_timeout_s = render_timeout_s
        self._lock = threading.RLock()
        self._mp = mp.get_context("spawn")
        self._process = None
        self._conn = None
        self._caps: dict = {}
        self._ring: list[shared_memory.SharedMemory] = []
        self._next_slot = 0
        self._in_flight: list[tuple[Scene, object]] = []  # submitted to the render process, oldest first
        self._collected: list[Frame] = []  # frames in flight taken out before a render(); returned next
        self._heartbeat = self._mp.Value("d", 0.0, lock=False)
        self.ig_frame = 0
        self.restarts = 0
        self.ready = False
        self.warm = False  # a frame has rendered since the process started (tables built, shaders linked)
        self.rendering_since: float | None = None  # monotonic start of the render in flight
        self.progress: dict | None = None  # {"phase", "fraction", "elapsed_s"} while tables are precomputed
        self.last_progress: dict | None = None  # the last finished phase (for /v1/ready)

    # -- lifecycle
    def start(self) -> "RenderService":
        with self._lock:
            if self.alive:
                return self
            parent, child = self._mp.Pipe()
            self._heartbeat.value = time.monotonic()
            self._process = self._mp.Process(
                target=render_process_main, args=(child, self._device_index, self._heartbeat), daemon=True,
                name="igserver-render",
            )
            self._process.start()
            child.close()
            self._conn = parent
            if not parent.poll(START_TIMEOUT_S):
                self._terminate()
                raise RenderError("render process did not start in time")
            try:
                reply = parent.recv()
            except EOFError as exc:
                self._terminate()
                raise RenderError("render process exited during start") from exc
            if reply[0] != "ready":
                self._terminate()
                if len(reply) > 2 and reply[2]:  # the message says what to do; the traceback is for debugging
                    log.debug("render process failed to start:\n%s", reply[2])
                raise RenderError(f"render process failed to start: {reply[1]}")
            self._caps = reply[1]
            self.warm = False
            self.ready = True
            return self

    def stop(self) -> None:
        with self._lock:
            if self._conn is not None and self.alive:
                try:
                    self._conn.send(("stop",))
                    self._process.join(5)
                except (OSError, BrokenPipeError):
                    pass
            self._terminate()
            self._release_ring()

    def __enter__(self) -> "RenderService":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def alive(self) -> bool:
        return self._process is not None and self._process.is_alive()

    @property
    def pid(self) -> int | None:
        return self._process.pid if self._process is not None else None

    def kill(self) -> None:
        """SIGKILL the render process (the watchdog's cure for a hung one): the next render restarts it."""
        if self._process is not None and self._process.pid:
            os.kill(self._process.pid, signal.SIGKILL)
            self._process.join(5)

    def _terminate(self) -> None:
        self.ready = False
        self.progress = None
        self._in_flight.clear()  # they went with the process
        if self._process is not None and self._process.is_alive():
            self._process.kill()
            self._process.join(5)
        if self._conn is not None:
            self._conn.close()
        self._process, self._conn = None, None

    def restart(self) -> None:
        with self._lock:
            self._terminate()
            self.restarts += 1
            self.start()

    def ensure_started(self) -> None:
        """Start the process if it is down (after an abandoned render); counts as a restart."""
        with self._lock:
            if not self.alive:
                self.restart()

    # -- watchdog
    def os_state(self) -> str | None:
        """The kernel's one-letter process state (R, S, D, T = stopped, Z = zombie); None if unknown."""
        pid = self.pid
        if pid is None:
            return None
        try:
            with open(f"/proc/{pid}/stat", "rb") as f:
                # "pid (comm) S ...": comm may hold spaces and parentheses; the state follows the last ')'
                return f.read().rsplit(b")", 1)[1].split()[0].decode()
        except (OSError, IndexError):
            return None

    def unresponsive_reason(self) -> str | None:
        """Why the render process cannot serve a frame now, or None when it can (cheap, lock-free)."""
        if not self.alive:
            return "render process is not running"
        if self.os_state() in ("T", "t"):
            return "render process is stopped by the operating system (SIGSTOP)"
        if self.rendering_since is None and time.monotonic() - self._heartbeat.value > STALL_S:
            return "render process is not responding (no heartbeat)"
        return None

    # -- state
    @property
    def state(self) -> Scene:
        return self._state

    def set_state(self, scene: Scene) -> None:
        """Accept a validated state; it is what a restarted render process is given again."""
        with self._lock:
            self._state = scene

    def info(self) -> dict:
        return {**self._caps, "ready": self.ready and self.alive, "restarts": self.restarts,
                "pid": self.pid, "frames": self.ig_frame}

    # -- frames
    def _release_ring(self) -> None:
        for shm in self._ring:
            shm.close()
            shm.unlink()
        self._ring = []

    def _slot_for(self, nbytes: int) -> shared_memory.SharedMemory:
        # a new size gets a new ring (also when it shrinks: memory goes back after a big frame); the
        # render process unmaps the old slots when it sees the new ring's names
        if not self._ring or not nbytes <= self._ring[0].size <= 2 * nbytes:
            if self._ring:
                self._release_ring()
                release_free_memory()
            self._ring = [shared_memory.SharedMemory(create=True, size=nbytes) for _ in range(RING_SLOTS)]
        slot = self._ring[self._next_slot % len(self._ring)]
        self._next_slot += 1
        return slot

    def render(self, scene: Scene | None = None, timed: bool = False) -> Frame:
        """Render ``scene`` (default: the current state) and return its frame. A crashed render process is
        restarted once and the scene re-sent; a render that timed out is not re-sent (``RenderTimeout``).
        Frames in flight are taken out first, so frame numbers follow the order frames were drawn in;
        the next ``submit``/``collect`` returns them."""
        with self._lock:
            scene = scene or self._state
            return self._with_restart(self._render_once, scene, timed)

    def submit(self, scene: Scene | None = None, timed: bool = False, tag=None) -> Frame | None:
        """Draw ``scene`` (default: the current state) and return the frame drawn before it, if any: its
        pixels were copied out while this one was drawn. ``tag`` comes back on this scene's frame. A crashed
        render process is restarted and the scene re-sent; the frames it had in flight are lost."""
        with self._lock:
            scene = scene or self._state
            if self._collected:  # taken out by a render() meanwhile: nothing is in flight, deliver it now
                self._with_restart(self._exchange, "submit", scene, timed, tag)
                return self._collected.pop(0)
            return self._with_restart(self._exchange, "submit", scene, timed, tag)

    def collect(self) -> Frame | None:
        """The oldest frame in flight (None if none): a stream takes it when no new state is due."""
        with self._lock:
            if self._collected:
                return self._collected.pop(0)
            if not self._in_flight:
                return None
            return self._with_restart(self._exchange, "collect", None, False, None)

    def rehearse(self, scene: Scene | None = None) -> dict:
        """Compile ahead, in the render process, the programs a stream of ``scene`` (default: the current
        state) would need when a fire, lights or precipitation appear (render/rehearsal.py): nothing is
        shown, the stream's state is kept. Returns {"scenes", "programs", "seconds"}."""
        with self._lock:
            return self._with_restart(self._rehearse_once, scene or self._state)

    def _rehearse_once(self, scene: Scene) -> dict:
        if not self.alive:
            raise _Dead()
        # a progress message after each scene: render_timeout_s bounds one scene
        return self._request(("rehearse", scene), "rehearsal")[1]

    def _request(self, message: tuple, what: str) -> tuple:
        """Send ``message`` to the render process and await its reply (timed as a render: the watchdog
        and ``render_timeout_s``); an error reply raises RenderError, its traceback logged."""
        self._conn.send(message)
        self.rendering_since = time.monotonic()
        try:
            reply = self._await_reply()
        finally:
            self.rendering_since = None
            self.progress = None
        if reply[0] == "error":
            if len(reply) > 2 and reply[2]:
                log.error("%s failed:\n%s", what, reply[2])
            raise RenderError(reply[1])
        return reply

    @property
    def in_flight(self) -> int:
        """Frames submitted and not yet returned."""
        return len(self._in_flight) + len(self._collected)

    def _with_restart(self, fn, *args):
        try:
            return fn(*args)
        except (EOFError, BrokenPipeError, ConnectionResetError, OSError, _Dead):
            self.restart()
            return fn(*args)

    def _render_once(self, scene: Scene, timed: bool) -> Frame:
        while self._in_flight:
            frame = self._exchange("collect", None, False, None)
            if frame is not None:
                self._collected.append(frame)
        return self._exchange("render", scene, timed, None)

    def _exchange(self, kind: str, scene: Scene | None, timed: bool, tag) -> Frame | None:
        """One command to the render process and its frame: render (``scene``'s), submit (the one in flight
        before ``scene``, or None), collect (the one in flight)."""
        if not self.alive:
            raise _Dead()
        if kind == "collect" and not self._in_flight:  # e.g. lost with a process restarted meanwhile
            return None
        if kind == "render":
            delivered = scene
        elif kind == "submit" and len(self._in_flight) < FRAMES_IN_FLIGHT:
            delivered = None
        else:
            delivered = self._in_flight[0][0]
        cam = delivered.camera if delivered is not None else None
        if delivered is not None and delivered.channels:  # the channels side by side cross as one image
            cam = mosaic_layout(delivered)[0]
        slot = self._slot_for(cam.width * cam.height * 4) if cam is not None else None
        ring = [shm.name for shm in self._ring]
        slot_name = slot.name if slot is not None else None
        args = (scene, timed) if kind != "collect" else ()
        reply = self._request((kind, *args, slot_name, ring), "render")
        if kind == "submit":
            self._in_flight.append((scene, tag))
        if reply[0] == "none":
            if kind == "collect":
                self._in_flight.clear()  # the process had nothing in flight (it was restarted)
            return None
        taken_tag = self._in_flight.pop(0)[1] if kind != "render" else tag
        _, shape, total_ms, pass_ms, passes, ev100, illuminance, host_frame, sim_time, overload = reply
        rgba = np.ndarray(shape, dtype=np.uint8, buffer=slot.buf).copy()
        self.ig_frame += 1
        self.warm = True  # after the count: /v1/ready (another thread) never sees warm with no frame counted
        if delivered is not None and delivered.channels:
            return with_channels(Frame(rgba, self.ig_frame, host_frame, total_ms, pass_ms, passes, sim_time, ev100,
                                       illuminance, taken_tag, overload), delivered)
        return Frame(rgba, self.ig_frame, host_frame, total_ms, pass_ms, passes, sim_time, ev100, illuminance,
                     taken_tag, overload)

    def _await_reply(self):
        """The render's reply; progress messages on the way extend the deadline (the process is alive)."""
        deadline = time.monotonic() + self.render_timeout_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining > 0 and self._conn.poll(min(remaining, HEARTBEAT_S)):
                pass
            elif self.os_state() in ("T", "t"):
                # stopped by the OS (SIGSTOP, a debugger): not the render's time, nor its state's fault; the
                # watchdog kills a process stopped too long, and the render is sent again to the new one
                deadline = time.monotonic() + self.render_timeout_s
                continue
            elif remaining > HEARTBEAT_S:
                continue  # one slice of the wait, not all of it
            else:
                waited = time.monotonic() - self.rendering_since
                log.error("render abandoned after %.1f s without an answer: killing the render process", waited)
                self._terminate()
                raise RenderTimeout(f"the render exceeded its time limit ({self.render_timeout_s:g} s) and was "
                                    "abandoned; the render process is restarting")
            reply = self._conn.recv()
            if reply[0] != "progress":
                return reply
            _, phase, fraction, elapsed = reply
            self.progress = {"phase": phase, "fraction": round(float(fraction), 3), "elapsed_s": round(elapsed, 2)}
            if fraction >= 1.0:
                self.last_progress = self.progress
                log.info("%s ready in %.1f s", phase, elapsed)
            elif fraction == 0.0:
                log.info("%s: precomputing (first use of these atmosphere parameters)", phase)
            deadline = time.monotonic() + self.render_timeout_s


def with_channels(frame: Frame, scene: Scene) -> Frame:
    """``frame`` (the mosaic of ``scene``'s channels) with each channel's frame cut from it."""
    frame.channels = {}
    for cid, x, width, height in mosaic_layout(scene)[1]:
        part = np.ascontiguousarray(frame.rgba[:height, x:x + width])
        frame.channels[cid] = Frame(part, frame.ig_frame, frame.host_frame, frame.render_ms, frame.pass_ms,
                                    frame.passes, frame.sim_time, frame.ev100, frame.illuminance_lux, frame.tag,
                                    frame.overload)
    return frame


class _Dead(Exception):
    """The render process is gone."""
