"""The render process and its client, ``RenderService``.

One spawned process creates the EGL context and keeps every pipeline resident. Commands go in
over a pipe; finished pixels come back through a ring of ``multiprocessing.shared_memory`` slots
(only a small metadata tuple crosses the pipe). If the process dies it is restarted and given the
current accepted state again, so no accepted state is lost. Moderngl never releases the GIL: keeping
GL out of the server process keeps its event loop free of render-sized stalls.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import time
import traceback
from dataclasses import dataclass, field
from multiprocessing import shared_memory

import numpy as np

from ..scene.model import Scene

RING_SLOTS = 3
START_TIMEOUT_S = 300.0  # first start compiles shaders and may precompute atmosphere tables
RENDER_TIMEOUT_S = 300.0


class RenderError(RuntimeError):
    pass


@dataclass
class Frame:
    rgba: np.ndarray  # (height, width, 4) uint8, top row first
    ig_frame: int
    host_frame: int
    render_ms: float
    pass_ms: dict[str, float] = field(default_factory=dict)
    passes: list[str] = field(default_factory=list)
    ev100: float = 0.0  # exposure used (photometric read-out)
    illuminance_lux: float = 0.0  # natural horizontal illuminance at the camera

    @property
    def width(self) -> int:
        return int(self.rgba.shape[1])

    @property
    def height(self) -> int:
        return int(self.rgba.shape[0])


# --------------------------------------------------------------------------- render process side

def _attach(name: str) -> shared_memory.SharedMemory:
    """Attach to a slot the parent created (and will unlink). A spawned child shares the parent's
    resource tracker, so attaching here registers nothing new and leaks nothing."""
    return shared_memory.SharedMemory(name=name)


def _render_process_main(conn, device_index: int | None) -> None:
    """Entry point of the spawned render process: owns the GL context for its whole life."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when we stop
    from .renderer import Renderer

    try:
        renderer = Renderer(device_index=device_index)
    except Exception as exc:
        conn.send(("error", f"{exc}"))
        return
    attached: dict[str, shared_memory.SharedMemory] = {}
    conn.send(("ready", renderer.caps.as_dict()))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            break
        kind = message[0]
        if kind == "stop":
            break
        if kind != "render":
            conn.send(("error", f"unknown command {kind!r}"))
            continue
        _, scene, timed, shm_name = message
        try:
            result = renderer.render(scene, timed=timed)
            if shm_name not in attached:
                attached[shm_name] = _attach(shm_name)
            buf = attached[shm_name].buf
            flat = result.rgba.reshape(-1)
            buf[: flat.size] = flat.data
            conn.send(("frame", result.rgba.shape, result.total_ms, result.pass_ms, result.passes,
                       result.ev100, result.illuminance_lux))
        except Exception:
            conn.send(("error", traceback.format_exc(limit=8)))
    for shm in attached.values():
        shm.close()


# --------------------------------------------------------------------------- client side

class RenderService:
    """Thread-safe handle on the render process. The CLI, the service and the tests all use it."""

    def __init__(self, scene: Scene | None = None, device_index: int | None = None):
        self._state = scene or Scene()
        self._device_index = device_index
        self._lock = threading.RLock()
        self._mp = mp.get_context("spawn")
        self._process = None
        self._conn = None
        self._caps: dict = {}
        self._ring: list[shared_memory.SharedMemory] = []
        self._next_slot = 0
        self.ig_frame = 0
        self.restarts = 0
        self.ready = False

    # -- lifecycle
    def start(self) -> "RenderService":
        with self._lock:
            if self.alive:
                return self
            parent, child = self._mp.Pipe()
            self._process = self._mp.Process(
                target=_render_process_main, args=(child, self._device_index), daemon=True, name="igserver-render"
            )
            self._process.start()
            child.close()
            self._conn = parent
            if not parent.poll(START_TIMEOUT_S):
                self._terminate()
                raise RenderError("render process did not start in time")
            try:
                kind, payload = parent.recv()
            except EOFError as exc:
                self._terminate()
                raise RenderError("render process exited during start") from exc
            if kind != "ready":
                self._terminate()
                raise RenderError(f"render process failed to start: {payload}")
            self._caps = payload
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
            for shm in self._ring:
                shm.close()
                shm.unlink()
            self._ring = []

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

    def kill_for_test(self) -> None:
        """SIGKILL the render process (tests and chaos drills): the next render restarts it."""
        if self._process is not None and self._process.pid:
            os.kill(self._process.pid, signal.SIGKILL)
            self._process.join(5)

    def _terminate(self) -> None:
        self.ready = False
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
    def _slot_for(self, nbytes: int) -> shared_memory.SharedMemory:
        if not self._ring or self._ring[0].size < nbytes:
            for shm in self._ring:
                shm.close()
                shm.unlink()
            self._ring = [shared_memory.SharedMemory(create=True, size=nbytes) for _ in range(RING_SLOTS)]
        slot = self._ring[self._next_slot % len(self._ring)]
        self._next_slot += 1
        return slot

    def render(self, scene: Scene | None = None, timed: bool = False) -> Frame:
        """Render ``scene`` (default: the current state). A dead render process is restarted once."""
        with self._lock:
            scene = scene or self._state
            try:
                return self._render_once(scene, timed)
            except (EOFError, BrokenPipeError, ConnectionResetError, OSError, _Dead):
                self.restart()
                return self._render_once(scene, timed)

    def _render_once(self, scene: Scene, timed: bool) -> Frame:
        if not self.alive:
            raise _Dead()
        cam = scene.camera
        slot = self._slot_for(cam.width * cam.height * 4)
        self._conn.send(("render", scene, timed, slot.name))
        if not self._conn.poll(RENDER_TIMEOUT_S):
            raise _Dead()
        reply = self._conn.recv()
        if reply[0] == "error":
            raise RenderError(reply[1])
        _, shape, total_ms, pass_ms, passes, ev100, illuminance = reply
        rgba = np.ndarray(shape, dtype=np.uint8, buffer=slot.buf).copy()
        self.ig_frame += 1
        return Frame(rgba, self.ig_frame, scene.host_frame, total_ms, pass_ms, passes, ev100, illuminance)


class _Dead(Exception):
    """The render process is gone or hung."""
