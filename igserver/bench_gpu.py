"""GPU milliseconds per pass, measured on the work the GPU does rather than on the host's pace.

A GL timer query (``ctx.query(time=True)``) counts from the moment the GPU reaches its begin to the
moment it reaches its end. If the host issues a pass's commands more slowly than the GPU executes
them, the GPU idles between commands and the query counts the idling too: a pass with 6 ms of host
work and 2 ms of GPU work reads close to 6 ms. Such a figure says how long the GPU was *occupied*,
not how much GPU time the pass needs, and it shrinks by itself as the host gets faster.

The **head start** removes the host from the measurement. Before each timed frame the GPU is given
a job of known length (``common/gpu_busy.comp.glsl``: one work group running a dependent chain) that
outlasts the host's work for the frame. While the GPU runs it, the frame's commands queue up behind
it; when the GPU reaches the first pass, every command of the frame is already there, and the
queries measure execution alone. Whether the head start was long enough is checked on every frame,
not assumed: a timestamp query records when the GPU finished the busy job, and the GPU clock is read
as the driver receives the end of each pass (``glGetInteger64v(GL_TIMESTAMP)``: both on the GPU's
clock). A frame whose last pass reached the driver after the GPU had finished the busy job is drawn
again with twice the head start.
"""

from __future__ import annotations

import ctypes
import statistics
import time

from .render import gl_calls
from .render.bindings import STORAGE
from .render.shaders import set_uniforms

GL_TIMESTAMP = 0x8E28
GL_QUERY_RESULT = 0x8866
LONGEST_HEAD_START_MS = 1000.0


def timer_queries_unusable(renderer) -> str | None:
    """Why GL timer queries cannot time passes on this renderer, or None when they can."""
    if "llvmpipe" in renderer.caps.renderer.lower():
        return "llvmpipe has no GPU clock"
    ctx = renderer.ctx
    try:  # a query around a clear must read some nanoseconds where the driver implements them
        texture = ctx.texture((64, 64), 4)
        fbo = ctx.framebuffer([texture])
        query = ctx.query(time=True)
        with query:
            fbo.use()
            fbo.clear(0.5, 0.5, 0.5, 1.0)
        elapsed = query.elapsed
        for obj in (fbo, texture):  # moderngl 5's Query has no release: it lives with the context
            obj.release()
    except Exception as exc:  # no timer query extension
        return f"timer queries failed ({type(exc).__name__})"
    return None if elapsed > 0 else "timer queries read 0"


class PassTimers:
    """Each pass's ``execute`` bracketed by a GL timer query while the block runs (one query per pass,
    made once and kept: moderngl 5 cannot release a query); ``read()`` after a frame gives GPU ms per
    pass (waits for the GPU to finish them). ``clock``, when given, is read as each pass has been
    issued; ``issued_ns`` is its last reading (the head start's check)."""

    def __init__(self, renderer, clock=None):
        self.renderer = renderer
        self.queries: dict = {}
        self.clock = clock
        self.issued_ns = 0
        self._ran: list[str] = []

    def __enter__(self) -> "PassTimers":
        for name, p in self.renderer.graph.passes.items():
            p.execute = self._timed(name, p.execute)  # instance attribute: shadows the class's method
        return self

    def _timed(self, name: str, execute):
        def timed(*args, **kwargs):
            query = self.queries.get(name) or self.queries.setdefault(name, self.renderer.ctx.query(time=True))
            with query:
                result = execute(*args, **kwargs)
            if self.clock is not None:
                self.issued_ns = self.clock()
            self._ran.append(name)
            return result

        return timed

    def read(self) -> dict[str, float]:
        ran, self._ran = self._ran, []
        return {name: self.queries[name].elapsed / 1e6 for name in ran}  # ns -> ms

    def __exit__(self, *exc) -> None:
        for p in self.renderer.graph.passes.values():
            p.__dict__.pop("execute", None)


class GPUHeadStart:
    """A busy job of a chosen length put on the GPU ahead of a frame (see the module's docstring)."""

    def __init__(self, renderer):
        self.ctx = renderer.ctx
        self.program = renderer.programs.compute("common/gpu_busy.comp.glsl")
        self.sink = self.ctx.buffer(reserve=64 * 4)
        self.gl = gl_calls.functions()
        if self.gl is None:
            raise OSError("no GL entry points through EGL: no GPU timestamps")
        query = ctypes.c_uint(0)
        self.gl.gen_queries(1, ctypes.byref(query))
        self.query = query.value
        self.iterations_per_ms = self._calibrate()

    def _run(self, iterations: int) -> None:
        set_uniforms(self.program, {"u_iterations": int(iterations)})
        self.sink.bind_to_storage_buffer(STORAGE["GPU_HEAD_START"])
        self.program.run(1)

    def _calibrate(self) -> float:
        """Iterations of the chain the GPU runs per millisecond, timed with a wall clock around
        ``finish`` (the job is long enough for the clock's overhead not to matter). A driver that caps
        a loop's trip count (Mesa's llvmpipe stops at 65,535) makes the time stop growing: refused."""
        iterations, last_ms = 4096, None
        while True:
            self.ctx.finish()
            start = time.perf_counter()
            self._run(iterations)
            self.ctx.finish()
            ms = (time.perf_counter() - start) * 1e3
            if ms >= 20.0:
                return iterations / ms
            if last_ms is not None and ms < 1.5 * last_ms and ms > 1.0:
                raise OSError(f"the busy job does not grow with its length ({last_ms:.2f} -> {ms:.2f} ms)")
            if iterations >= 1 << 28:
                raise OSError(f"the busy job stays short ({ms:.2f} ms at {iterations} steps)")
            last_ms, iterations = ms, iterations * 4

    def give(self, ms: float) -> None:
        """Queue ``ms`` of GPU work, mark when the GPU finishes it, and hand it to the GPU now."""
        self._run(max(1, round(ms * self.iterations_per_ms)))
        self.gl.query_counter(self.query, GL_TIMESTAMP)
        gl_calls.flush()

    def finished_ns(self) -> int:
        """When the GPU finished the last job given (GPU clock, ns; waits for it)."""
        value = ctypes.c_uint64(0)
        self.gl.get_query_object_ui64v(self.query, GL_QUERY_RESULT, ctypes.byref(value))
        return value.value

    def clock_ns(self) -> int:
        """The GPU clock as the driver receives this call (ns)."""
        value = ctypes.c_int64(0)
        self.gl.get_integer64v(GL_TIMESTAMP, ctypes.byref(value))
        return value.value

    def release(self) -> None:
        self.sink.release()


def gpu_pass_ms(renderer, scenes, host_ms: float) -> dict:
    """GPU ms per pass over ``scenes``: behind a head start where the GPU can be given one
    (``gpu_timing`` says so), else as the frames are issued, idling included (and ``gpu_timing`` says
    why)."""
    try:
        head = GPUHeadStart(renderer)
        try:
            return {**queued_gpu_pass_ms(renderer, scenes, host_ms, head), "gpu_timing": "queued behind a head start"}
        finally:
            head.release()
    except Exception as exc:  # a driver without what the head start needs: time the passes as issued
        reason = f"{type(exc).__name__}: {exc}" if not isinstance(exc, OSError) else str(exc)
    frames = []
    with PassTimers(renderer) as timers:
        for scene in scenes:
            renderer.render(scene)
            frames.append(timers.read())
    return {"gpu_pass_ms": _medians(frames), "gpu_timing": f"as issued, GPU idling included (no head start: {reason})"}


def queued_gpu_pass_ms(renderer, scenes, host_ms: float, head) -> dict:
    """GPU ms per pass (medians over ``scenes``), each frame drawn behind a head start (``head``,
    a GPUHeadStart) longer than its host work: 1.25 x ``host_ms`` + 2 ms, ``host_ms`` being the frame's
    wall time (GPU and readback included: an upper bound of the host's share), doubled for a frame the
    check finds it short for. Returns ``gpu_pass_ms``, the head start used last (``gpu_head_start_ms``),
    how many frames were drawn again because the head start was short (``gpu_frames_redrawn``) and how
    many were left unconfirmed after the longest (``gpu_frames_unconfirmed``)."""
    lead_ms = min(max(1.25 * host_ms + 2.0, 5.0), LONGEST_HEAD_START_MS)
    frames = []
    redrawn = unconfirmed = 0
    with PassTimers(renderer, clock=head.clock_ns) as timers:
        for scene in scenes:
            while True:
                head.give(lead_ms)
                renderer.render(scene)
                pass_ms = timers.read()
                if timers.issued_ns <= head.finished_ns():
                    break  # every pass was queued before the GPU reached the frame
                if lead_ms >= LONGEST_HEAD_START_MS:
                    unconfirmed += 1
                    break
                lead_ms = min(2.0 * lead_ms, LONGEST_HEAD_START_MS)
                redrawn += 1
            frames.append(pass_ms)
    return {"gpu_pass_ms": _medians(frames), "gpu_head_start_ms": lead_ms,
            "gpu_frames_redrawn": redrawn, "gpu_frames_unconfirmed": unconfirmed}


def _medians(frames: list[dict[str, float]]) -> dict[str, float]:
    """Each pass's median over the frames that drew it."""
    names = dict.fromkeys(name for frame in frames for name in frame)
    return {name: statistics.median(f[name] for f in frames if name in f) for name in names}
