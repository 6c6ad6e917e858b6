"""Depth convention of every pass: reversed-Z, a float depth buffer and an infinite far plane.

Why: a conventional depth buffer (1 at the far plane, 24-bit fixed point) spends its precision
next to the near plane; with near 0.01 m and far 1e5 m two boxes 40 m apart at 5 km already fall
into one depth step, and the float32 inverse of such a projection puts the far point at w = 0.
Reversed-Z stores window depth = near / d (d: distance along the view axis, m): 1 at the near
plane, 0 at infinity. Stored as float32, whose relative step is 2^-24 everywhere, two surfaces
resolve when they are ~1e-7 of their distance apart, at 1 mm or at 10,000 km alike.

That needs the clip control of GL 4.5, glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE), so that NDC
z in [0, 1] reaches the depth buffer without the fixed-function 0.5 z + 0.5 (which would round
near / d to multiples of 2^-24 around 0.5). moderngl does not expose it: it is called through the
GL library, with the function pointer from eglGetProcAddress (the context is an EGL one), and read
back with glGetIntegerv(GL_CLIP_DEPTH_MODE). Where it is missing (no EGL, or a driver below 4.5),
the same reversed projection is written for NDC z in [-1, 1] (``zero_to_one`` False): the picture
is the same, only the far-field depth precision is that of the fixed-function mapping.

The passes never choose any of this themselves: the renderer clears depth to ``CLEAR_DEPTH`` and
sets ``NEAREST_WINS``; fullscreen passes place themselves at infinity (common/depth.glsl) and write
ray-cast depth with window_depth(rel) (common/frame.glsl); the sky pass draws where nothing else
did with ``AT_INFINITY``.
"""

from __future__ import annotations

import ctypes
import logging

import moderngl

from . import gl_calls

log = logging.getLogger(__name__)

CLEAR_DEPTH = 0.0  # window depth at infinity
NEAREST_WINS = ">"  # larger window depth = closer
AT_INFINITY = ">="  # for passes drawn at infinity (the sky) over the cleared depth
SAME_OR_NEARER = ">="  # a surface drawn again over itself (the ground's shadowed parts: the same depth)

GL_LOWER_LEFT = 0x8CA1
GL_ZERO_TO_ONE = 0x935F
GL_CLIP_DEPTH_MODE = 0x935D
GL_TEXTURE_2D = 0x0DE1
GL_TEXTURE0 = 0x84C0
GL_DEPTH_COMPONENT = 0x1902
GL_DEPTH_COMPONENT32F = 0x8CAC
GL_FLOAT = 0x1406
GL_TEXTURE_INTERNAL_FORMAT = 0x1003

# Per context: whether clip control is on (the projection and the shaders follow it).
_modes: dict[int, bool] = {}


def enable_reversed_z(ctx: moderngl.Context) -> bool:
    """Switch ``ctx`` (current) to clip depth [0, 1]; True when the driver confirms it."""
    gl = gl_calls.functions()
    ok = False
    if gl is not None:
        gl.clip_control(GL_LOWER_LEFT, GL_ZERO_TO_ONE)
        ok = gl.integer(GL_CLIP_DEPTH_MODE) == GL_ZERO_TO_ONE
        ctx.error  # noqa: B018 - reading clears the GL error flag the call may have raised
        if not ok:
            log.warning("glClipControl(GL_ZERO_TO_ONE) not in effect: conventional clip range")
    _modes[id(ctx)] = ok
    return ok


def zero_to_one(ctx: moderngl.Context | None) -> bool:
    """The context's clip depth range: [0, 1] (clip control on) or the conventional [-1, 1]."""
    return _modes.get(id(ctx), False) if ctx is not None else True


def shader_defines(ctx: moderngl.Context) -> dict[str, int]:
    return {"DEPTH_ZERO_TO_ONE": 1 if zero_to_one(ctx) else 0}


def float_depth_texture(ctx: moderngl.Context, size: tuple[int, int]) -> tuple[moderngl.Texture, bool]:
    """A depth texture stored as float32 (GL_DEPTH_COMPONENT32F); (texture, True when float).

    moderngl allocates depth textures as 24-bit fixed point; the storage is re-specified here
    (its texture is mutable, allocated with glTexImage2D) before any framebuffer uses it.
    """
    tex = ctx.depth_texture(size)
    gl = gl_calls.functions()
    if gl is None:
        return tex, False
    ctx.error  # noqa: B018 - clear a stale error flag: only this call's errors count below
    unit = ctx.default_texture_unit
    gl.active_texture(GL_TEXTURE0 + unit)
    gl.bind_texture(GL_TEXTURE_2D, tex.glo)
    gl.tex_image_2d(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, size[0], size[1], 0, GL_DEPTH_COMPONENT, GL_FLOAT, None)
    fmt = ctypes.c_int(0)
    gl.get_tex_level_parameteriv(GL_TEXTURE_2D, 0, GL_TEXTURE_INTERNAL_FORMAT, ctypes.byref(fmt))
    gl.bind_texture(GL_TEXTURE_2D, 0)
    error = ctx.error
    ok = fmt.value == GL_DEPTH_COMPONENT32F and error == "GL_NO_ERROR"
    if not ok:
        log.warning("float depth buffer unavailable (%s, format 0x%x): 24-bit depth", error, fmt.value)
    return tex, ok
