"""Headless EGL context: an NVIDIA GPU when one is present, else Mesa llvmpipe.

The context must be created in the thread (and process) that uses it: the render worker does this.

The one rule for GL contexts: **make the owning context current before every use** (``make_current``).
GL calls go to whichever context is current in the calling thread, and creating a context makes it
current; moderngl never switches back. So where more than one context can exist in a process (the
quality tools, the tests, a tool that makes a scratch context), a context created and released after
another one has been used leaves *no* context current, and the first context's draws, reads and even
its ``release()`` calls silently go nowhere (or to the wrong context's objects): blank frames, then a
crash. ``Renderer`` follows the rule in every public method and in its ``ctx`` property; code that
holds a raw ``moderngl.Context`` calls ``make_current(ctx)`` first. It costs ~2 us (eglMakeCurrent
with the context already current).
"""

from __future__ import annotations

import ctypes.util
import os
from dataclasses import dataclass

import moderngl

REQUIRED_GL = 450
MESA_PACKAGES = "libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri"


class ContextError(RuntimeError):
    pass


@dataclass(frozen=True)
class Capabilities:
    renderer: str
    vendor: str
    version: str
    max_texture_size: int
    max_3d_texture_size: int
    software: bool

    def as_dict(self) -> dict:
        return self.__dict__.copy()


def _nvidia_egl_present() -> bool:
    return any(
        os.path.exists(p)
        for p in (
            "/usr/share/glvnd/egl_vendor.d/10_nvidia.json",
            "/etc/glvnd/egl_vendor.d/10_nvidia.json",
            "/dev/nvidia0",
        )
    )


def create_context(device_index: int | None = None) -> moderngl.Context:
    """Create a GL 4.5 core context through EGL.

    ``device_index`` picks an EGL device (GPU) explicitly; by default the NVIDIA device when its
    driver is installed, otherwise Mesa llvmpipe with ``LP_NUM_THREADS`` = the cores available.
    """
    os.environ.setdefault("LP_NUM_THREADS", str(len(os.sched_getaffinity(0))))
    if device_index is None and os.environ.get("IGSERVER_EGL_DEVICE"):
        device_index = int(os.environ["IGSERVER_EGL_DEVICE"])
    if ctypes.util.find_library("EGL") is None:
        raise ContextError(
            f"libEGL not found: install the Mesa EGL packages ({MESA_PACKAGES}) "
            "or run scripts/bootstrap.sh as root"
        )
    kwargs: dict = {"backend": "egl", "require": REQUIRED_GL}
    if device_index is not None:
        kwargs["device_index"] = device_index
    elif not _nvidia_egl_present():
        os.environ.setdefault("EGL_PLATFORM", "surfaceless")
    try:
        return moderngl.create_standalone_context(**kwargs)
    except Exception as exc:  # glcontext raises bare Exceptions
        raise ContextError(
            f"could not create an EGL OpenGL {REQUIRED_GL // 100}.{REQUIRED_GL % 100 // 10} context ({exc}); "
            f"on Debian/Ubuntu install: {MESA_PACKAGES} (or the NVIDIA driver's EGL for a GPU)"
        ) from exc


def make_current(ctx: moderngl.Context) -> moderngl.Context:
    """Make ``ctx`` the calling thread's current GL context and return it.

    ``moderngl.Context.__enter__`` without the matching ``__exit__``: ``__exit__`` would restore the
    previously current context, which may be one that has since been released.
    """
    ctx.__enter__()
    return ctx


def release_context(ctx: moderngl.Context) -> None:
    """Release ``ctx`` with itself current, so its objects are deleted from it and not from another."""
    make_current(ctx).release()


def capabilities(ctx: moderngl.Context) -> Capabilities:
    info = ctx.info
    renderer = str(info.get("GL_RENDERER", "?"))
    return Capabilities(
        renderer=renderer,
        vendor=str(info.get("GL_VENDOR", "?")),
        version=str(info.get("GL_VERSION", "?")),
        max_texture_size=int(info.get("GL_MAX_TEXTURE_SIZE", 0)),
        max_3d_texture_size=int(info.get("GL_MAX_3D_TEXTURE_SIZE", 0)),
        software="llvmpipe" in renderer or "softpipe" in renderer,
    )


EGL_EXTENSIONS = 0x3055
EGL_CUDA_DEVICE_NV = 0x323A


def egl_devices_cuda() -> list[int | None]:
    """Per EGL device (in ``eglQueryDevicesEXT`` order, the order glcontext's ``device_index`` counts), its
    CUDA device ordinal (``EGL_NV_device_cuda``), None for a device that is not an NVIDIA GPU (Mesa's
    software device). Empty when EGL cannot enumerate devices."""
    import ctypes

    try:  # find_library needs the unversioned name (a -dev package) or ldconfig's cache; the runtime has .so.1
        egl = ctypes.CDLL(ctypes.util.find_library("EGL") or "libEGL.so.1")
    except OSError:
        return []
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]

    def proc(symbol: bytes, restype, *argtypes):
        address = egl.eglGetProcAddress(symbol)
        return ctypes.CFUNCTYPE(restype, *argtypes)(address) if address else None

    query_devices = proc(b"eglQueryDevicesEXT", ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                         ctypes.POINTER(ctypes.c_int))
    query_string = proc(b"eglQueryDeviceStringEXT", ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)
    query_attrib = proc(b"eglQueryDeviceAttribEXT", ctypes.c_uint, ctypes.c_void_p, ctypes.c_int,
                        ctypes.POINTER(ctypes.c_ssize_t))
    if query_devices is None:
        return []
    devices = (ctypes.c_void_p * 32)()
    count = ctypes.c_int(0)
    if not query_devices(32, devices, ctypes.byref(count)):
        return []
    out: list[int | None] = []
    for i in range(count.value):
        extensions = (query_string(devices[i], EGL_EXTENSIONS) or b"") if query_string else b""
        ordinal = ctypes.c_ssize_t(-1)
        if b"EGL_NV_device_cuda" in extensions and query_attrib is not None \
                and query_attrib(devices[i], EGL_CUDA_DEVICE_NV, ctypes.byref(ordinal)):
            out.append(int(ordinal.value))
        else:
            out.append(None)
    return out


def egl_device_for_visible_gpu(visible: str | None, devices: list[int | None] | None = None) -> int | None:
    """The EGL device index of the first GPU in ``CUDA_VISIBLE_DEVICES`` (what Ray sets for an actor with
    ``num_gpus=1``: the physical GPU's index). EGL enumerates every GPU whatever that variable says, so the
    index is mapped: the EGL device whose CUDA ordinal is that index, else the k-th NVIDIA EGL device, else
    the only one. None when nothing is visible or no NVIDIA EGL device exists (the default device then)."""
    first = (visible or "").split(",")[0].strip()
    if not first or first.startswith("-"):
        return None
    devices = egl_devices_cuda() if devices is None else devices
    nvidia = [i for i, ordinal in enumerate(devices) if ordinal is not None]
    if not nvidia:
        return None
    if first.isdigit():
        physical = int(first)
        for i, ordinal in enumerate(devices):
            if ordinal == physical:
                return i
        if physical < len(nvidia):
            return nvidia[physical]
    return nvidia[0]
