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
