"""The render process: the spawned side of ``RenderService`` (render/worker.py).

It creates the GL context and a ``Renderer`` once and keeps them for its whole life, answering the
commands that come over its pipe - ``render``, ``submit``, ``collect`` (a frame's pixels go into a
shared-memory slot the client names; a small metadata tuple comes back), ``rehearse`` (compile ahead:
render/rehearsal.py) and ``stop`` - and proving itself alive meanwhile: a heartbeat on a shared clock
between commands, progress messages during a long table precompute.
"""

from __future__ import annotations

import signal
import threading
import time
import traceback
from multiprocessing import shared_memory

import numpy as np

from .memory import release_free_memory

HEARTBEAT_S = 0.25  # the render process stamps a shared clock this often while it waits for work
REHEARSAL_PHASE = "compiling ahead"  # the progress messages' phase during a rehearsal
# submit(): frames drawn and not yet returned. One lets the render process read frame N while it draws
# N+1 and the server encode N meanwhile, for one frame interval more from a state to its frame.
FRAMES_IN_FLIGHT = 1


def _attach(name: str) -> shared_memory.SharedMemory:
    """Attach to a slot the parent created (and will unlink). A spawned child shares the parent's
    resource tracker, so attaching here registers nothing new and leaks nothing."""
    return shared_memory.SharedMemory(name=name)


def _heartbeat(stamp) -> None:
    """Stamp ``time.monotonic()`` while the process runs Python; a stopped (SIGSTOP) process stops stamping.
    During a GL call the GIL is held, so the parent judges the heartbeat only between renders."""
    while True:
        stamp.value = time.monotonic()
        time.sleep(HEARTBEAT_S)


def _report_table_progress(conn) -> None:
    """Send ("progress", phase, fraction, elapsed_s) while the atmosphere tables are precomputed.

    The precompute runs 3 compute stages plus 3 per scattering order above one; counting the
    dispatches gives the fraction done (an estimate that cannot pass 1). The messages also prove the
    process alive, so a long first precompute is not mistaken for a hang.
    """
    import moderngl

    from .sky import tables

    original_init = tables.AtmosphereTables.__init__
    original_run = moderngl.ComputeShader.run
    current: dict = {}

    def counted_run(self, *args, **kwargs):
        if current and not current["done"]:  # the first dispatch: the tables are computed, not loaded
            conn.send(("progress", "atmosphere tables", 0.0, 0.0))
        result = original_run(self, *args, **kwargs)
        if current:
            current["done"] += 1
            fraction = min(current["done"] / current["total"], 0.99)
            conn.send(("progress", "atmosphere tables", fraction, time.perf_counter() - current["t0"]))
        return result

    def reporting_init(self, ctx, params):
        orders = getattr(getattr(params, "sizes", None), "orders", 4)
        current.update(done=0, total=3 + 3 * max(int(orders) - 1, 0), t0=time.perf_counter())
        try:
            original_init(self, ctx, params)
        finally:
            elapsed, computed = time.perf_counter() - current["t0"], current["done"] > 0
            current.clear()
            if computed:  # loaded from the disk cache: nothing was precomputed, nothing to report
                conn.send(("progress", "atmosphere tables", 1.0, elapsed))

    tables.AtmosphereTables.__init__ = reporting_init
    moderngl.ComputeShader.run = counted_run


def render_process_main(conn, device_index: int | None, stamp=None) -> None:
    """Entry point of the spawned render process: owns the GL context for its whole life."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when we stop
    if stamp is not None:
        threading.Thread(target=_heartbeat, args=(stamp,), daemon=True, name="heartbeat").start()
    from .renderer import Renderer

    try:
        renderer = Renderer(device_index=device_index, frames_in_flight=FRAMES_IN_FLIGHT)
    except Exception as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}", traceback.format_exc(limit=8)))
        return
    _report_table_progress(conn)
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
        if kind == "rehearse":  # (scene,) -> what the rehearsal compiled (render/rehearsal.py); no frame
            t0 = time.perf_counter()

            def report(done: int, total: int) -> None:  # each scene drawn proves the process alive
                if done < total:
                    conn.send(("progress", REHEARSAL_PHASE, done / total, time.perf_counter() - t0))

            try:
                conn.send(("rehearsed", renderer.rehearse(message[1], report)))
            except Exception as exc:
                conn.send(("error", f"rehearsal failed ({type(exc).__name__})", traceback.format_exc(limit=8)))
            continue
        if kind not in ("render", "submit", "collect"):
            conn.send(("error", f"unknown command {kind!r}", ""))
            continue
        # render: (scene, timed, slot, ring) -> that scene's frame. submit: (scene, timed, slot, ring) -> the
        # frame in flight before it, or none yet (slot: where that frame goes). collect: (slot, ring) -> the
        # frame in flight, or none.
        *args, shm_name, ring_names = message[1:]
        # the parent replaced its ring (frame size changed): unmap the slots it has unlinked
        stale = [n for n in attached if n not in ring_names]
        for name in stale:
            attached.pop(name).close()
        try:
            if kind == "render":
                result = renderer.render(*args)
            elif kind == "submit":
                result = renderer.submit(*args)
            else:
                result = renderer.collect()
            if result is None:
                conn.send(("none",))
                continue
            if shm_name not in attached:
                attached[shm_name] = _attach(shm_name)
            np.ndarray(result.rgba.shape, np.uint8, buffer=attached[shm_name].buf)[...] = result.rgba
            # host_frame and sim_time from the scene the frame was drawn from: exact with frames in flight
            conn.send(("frame", result.rgba.shape, result.total_ms, result.pass_ms, result.passes,
                       result.ev100, result.illuminance_lux, result.host_frame, result.sim_time, result.overload))
            if stale:  # the frame size changed: the old ring and render targets are free now, after the frame
                release_free_memory()
        except Exception as exc:
            # the client gets the kind of failure; the traceback (with server paths) goes to the log
            conn.send(("error", f"render failed ({type(exc).__name__})", traceback.format_exc(limit=8)))
    for shm in attached.values():
        shm.close()
