"""A channel render worker: one Ray actor, one GL context, the channels of the state it is given.

The class is plain Python; the service wraps it with ``ray.remote`` when it starts (so importing this
module needs no Ray). Every frame call names the state revision it draws; the state itself is sent
only when the worker has not got that revision (a new state, or a worker restarted by Ray, which
comes back empty and answers ``need_state``: the service re-sends the state at once).
"""

from __future__ import annotations

import os
import socket
import time

import numpy as np

from ..scene.model import Scene


class ChannelWorker:
    def __init__(self, index: int, cpus: int = 1, use_gpu: bool = False):
        # llvmpipe's rasteriser threads: the CPUs Ray gave this actor, not every core of the node
        os.environ["LP_NUM_THREADS"] = str(max(int(cpus), 1))
        from ..render.context import egl_device_for_visible_gpu
        from ..render.renderer import Renderer

        self.index = index
        # Ray sets CUDA_VISIBLE_DEVICES to this actor's GPU; EGL counts devices its own way
        self.device = egl_device_for_visible_gpu(os.environ.get("CUDA_VISIBLE_DEVICES")) if use_gpu else None
        self.renderer = Renderer(device_index=self.device)
        self.started = time.time()
        self.revision: int | None = None
        self.scene: Scene | None = None

    def hello(self) -> dict:
        """Who this worker is: its process (a new pid after Ray restarted it), node and GL renderer."""
        return {"index": self.index, "pid": os.getpid(), "node": socket.gethostname(), "device": self.device,
                "started": self.started, "caps": self.renderer.caps.as_dict()}

    def render(self, frame: int, revision: int, scene: Scene | None, timed: bool = False,
               exposure: tuple[float, float] | None = None) -> dict:
        """Draw revision ``revision`` (``scene``: that state, channels = this worker's; None: the one held) as
        frame ``frame``, with ``exposure`` (EV100, metered luminance cd/m^2: the front's one exposure for
        every worker; None: this worker's own meter). Returns the channels' pixels, the meter cells and the
        completion time (s since the epoch, this node's clock), or ``{"need_state": True}`` when the
        revision is not held (the worker was restarted)."""
        if scene is not None:
            self.scene, self.revision = scene, revision
        elif self.revision != revision or self.scene is None:
            return {"frame": frame, "pid": os.getpid(), "need_state": True}
        self.renderer.exposure_override, self.renderer.meter_cells = exposure, None
        result = self.renderer.render(self.scene, timed=timed)
        done = time.time()
        cells = self.renderer.meter_cells
        parts = result.channels if result.channels is not None else {"": result}
        return {
            "frame": frame, "pid": os.getpid(), "done": done, "render_ms": result.total_ms,
            "channels": {cid: part.rgba for cid, part in parts.items()},
            "pass_ms": result.pass_ms, "passes": result.passes, "ev100": result.ev100,
            "illuminance_lux": result.illuminance_lux, "host_frame": result.host_frame, "sim_time": result.sim_time,
            "overload": result.overload, "cells": None if cells is None else cells.astype(np.float32),
        }

    def rehearse(self, scene: Scene) -> dict:
        """Compile ahead what a fire, lights or precipitation in ``scene`` would need (render/rehearsal.py);
        the frames this worker draws are unchanged by it."""
        return self.renderer.rehearse(scene)

    def pid(self) -> int:
        return os.getpid()
