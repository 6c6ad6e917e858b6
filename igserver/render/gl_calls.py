"""The few GL entry points moderngl lacks, looked up through EGL (the context is an EGL one).

Clip control and float depth storage (depth.py) and ``flush``: moderngl only has ``finish``, which
waits for the driver to complete everything queued. ``flush`` hands the queued work to the driver
without waiting. On Mesa llvmpipe that is what lets the two kinds of work in a frame overlap:
vertex shading, triangle setup and binning run in the calling thread, rasterisation and fragment
shading on the worker threads, and a batch of binned work reaches the workers only when it is
flushed (or when something waits for it). The renderer flushes after each pass, so the workers
shade one pass while this thread sets up the next (quiet machine, frame time with / without:
demo 0.98, sea from 1 km 0.95, from 2 m 0.97, night_fire 1.00). Flushing inside the water pass
every ~64 blocks as well measured no gain and was not kept.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging

log = logging.getLogger(__name__)


class GLFunctions:
    """Function pointers from eglGetProcAddress for the current context's library."""

    def __init__(self):
        name = ctypes.util.find_library("EGL") or "libEGL.so.1"
        egl = ctypes.CDLL(name)
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        egl.eglGetCurrentContext.restype = ctypes.c_void_p
        if not egl.eglGetCurrentContext():
            raise OSError("no current EGL context")

        def fn(symbol: str, restype, *argtypes):
            address = egl.eglGetProcAddress(symbol.encode())
            if not address:
                raise OSError(f"{symbol} not available")
            return ctypes.CFUNCTYPE(restype, *argtypes)(address)

        u, i = ctypes.c_uint, ctypes.c_int
        self.clip_control = fn("glClipControl", None, u, u)
        self.get_integerv = fn("glGetIntegerv", None, u, ctypes.POINTER(i))
        self.active_texture = fn("glActiveTexture", None, u)
        self.bind_texture = fn("glBindTexture", None, u, u)
        self.tex_image_2d = fn("glTexImage2D", None, u, i, i, i, i, i, u, u, ctypes.c_void_p)
        self.get_tex_level_parameteriv = fn("glGetTexLevelParameteriv", None, u, i, u, ctypes.POINTER(i))
        self.flush = fn("glFlush", None)
        # Timestamps on the GPU's clock (the bench's GPU head start, bench_gpu.py): a query that records
        # when the GPU reaches it, and the clock's reading as the driver receives a command.
        u64 = ctypes.c_uint64
        self.gen_queries = fn("glGenQueries", None, i, ctypes.POINTER(u))
        self.query_counter = fn("glQueryCounter", None, u, u)
        self.get_query_object_ui64v = fn("glGetQueryObjectui64v", None, u, u, ctypes.POINTER(u64))
        self.get_integer64v = fn("glGetInteger64v", None, u, ctypes.POINTER(ctypes.c_int64))

    def integer(self, pname: int) -> int:
        value = ctypes.c_int(0)
        self.get_integerv(pname, ctypes.byref(value))
        return value.value


_functions: GLFunctions | None = None


def functions() -> GLFunctions | None:
    """The entry points (looked up once, with a context current), or None where EGL lacks them."""
    global _functions
    if _functions is None:
        try:
            _functions = GLFunctions()
        except (OSError, AttributeError) as exc:
            log.warning("GL entry points through EGL unavailable (%s): conventional clip range, no flush", exc)
            return None
    return _functions


def flush() -> None:
    """glFlush: start the driver on what is queued, without waiting for it (no-op without EGL)."""
    gl = functions()
    if gl is not None:
        gl.flush()
