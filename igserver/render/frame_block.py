"""The frame's uniform block: per-frame and per-view constants written once a frame, read by every pass.

Every draw program of a frame reads the camera, the exposure, the sun and moon and the point/spot
lights. As plain uniforms they would be written into each program separately (a dozen programs a
frame, the lights' arrays 3 KB each time); as one std140 uniform block they are packed into one
buffer once a frame, bound once to the binding point ``BLOCK_FRAME`` (render/bindings.py), and
every program that declares the block reads them from there.

The fields are declared once, here, with their GLSL types; the GLSL declaration is generated from
this table (``glsl()``, included by common/frame.glsl as ``generated/frame_block.glsl``) and the
byte layout follows the std140 rules, so the two sides cannot disagree. A program compiled with
``FRAME_BLOCK`` 0 (the tables' compute programs, which fill with their own camera or sun and are
not run every frame) gets the same names as plain uniforms instead.

std140, the parts used here: a scalar is aligned to 4 bytes, a vec2 to 8, a vec3 and a vec4 to 16
(a vec3 occupies 12, so a scalar may follow in its last 4), a mat4 is four vec4 columns; every
array element is aligned to and padded to 16 bytes.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from .bindings import BLOCKS, write_buffer
from .light_tiles import LIGHT_TILE_PX, LightTiles
from .resident import resident

MAX_LIGHTS = 64  # point/spot lights per frame (bits of a tile's light mask: light_tiles.py)


@dataclass(frozen=True)
class Field:
    name: str
    glsl: str          # float, int, vec2, vec3, vec4, mat4
    count: int = 0     # array length (0: not an array)
    doc: str = ""      # unit and meaning, copied into the generated GLSL

    @property
    def components(self) -> int:
        return {"float": 1, "int": 1, "vec2": 2, "vec3": 3, "vec4": 4, "mat4": 16}[self.glsl]

    @property
    def align(self) -> int:
        if self.count:
            return 16
        return {"float": 4, "int": 4, "vec2": 8, "vec3": 16, "vec4": 16, "mat4": 16}[self.glsl]

    @property
    def size(self) -> int:
        if self.count:
            return 16 * self.count * (4 if self.glsl == "mat4" else 1)
        return 4 * self.components


FIELDS = (
    Field("u_view_proj", "mat4", doc="camera-relative world -> clip (reversed-Z, far plane at infinity)"),
    Field("u_inv_view_proj", "mat4", doc="clip -> camera-relative world; finite depths only (view rays: view_ray())"),
    Field("u_camera_right", "vec3", doc="unit camera basis in the camera-relative world frame"),
    Field("u_camera_altitude", "float", doc="m above mean sea level (origin altitude + camera z)"),
    Field("u_camera_up", "vec3"),
    Field("u_exposure", "float", doc="1 / (1.2 * 2^EV100): cd/m^2 -> display-referred"),
    Field("u_camera_forward", "vec3"),
    Field("u_light_count", "int", doc="point/spot lights in the arrays below"),
    Field("u_frustum_tangents", "vec4", doc="tan of the frustum half-angles: left, right, bottom, top (signed)"),
    Field("u_sun_dir", "vec3", doc="unit, toward the sun"),
    Field("u_sun_illuminance", "vec3", doc="lux per channel at the camera, after the atmosphere"),
    Field("u_moon_dir", "vec3", doc="unit, toward the moon"),
    Field("u_moon_illuminance", "vec3", doc="lux per channel"),
    Field("u_sky_ambient", "vec3", doc="cd/m^2, cosine-weighted mean sky radiance (irradiance / pi)"),
    Field("u_resolution", "vec2", doc="px"),
    Field("u_light_pos", "vec4", MAX_LIGHTS, "xyz camera-relative m, w = range m"),
    Field("u_light_color", "vec4", MAX_LIGHTS, "rgb = colour * intensity (cd), w = 1 spot / 0 point"),
    Field("u_light_dir", "vec4", MAX_LIGHTS, "xyz spot axis, w = cos(outer cone)"),
    Field("u_light_cos_inner", "float", MAX_LIGHTS, "cos of the spot's inner cone (full intensity inside)"),
)
NAMES = frozenset(f.name for f in FIELDS)


def _layout() -> tuple[dict[str, int], int]:
    offsets, at = {}, 0
    for f in FIELDS:
        at = -(-at // f.align) * f.align
        offsets[f.name] = at
        at += f.size
    return offsets, -(-at // 16) * 16


OFFSETS, SIZE = _layout()


def glsl() -> str:
    """The fields' GLSL declaration: the std140 block, or plain uniforms where FRAME_BLOCK is 0."""
    decls = []
    for f in FIELDS:
        array = f"[{f.count}]" if f.count else ""
        doc = f"  // {f.doc}" if f.doc else ""
        decls.append(f"{f.glsl} {f.name}{array};{doc}")
    body = "\n".join("    " + d for d in decls)
    plain = "\n".join("uniform " + d for d in decls)
    return (f"// Generated from igserver/render/frame_block.py (std140, {SIZE} bytes).\n"
            '#include "generated/bindings.glsl"\n'
            f"#define MAX_LIGHTS {MAX_LIGHTS}\n"
            f"#define LIGHT_TILE_PX {LIGHT_TILE_PX}\n"
            "#if defined(FRAME_BLOCK) && FRAME_BLOCK\n"
            "layout(std140, binding = BLOCK_FRAME) uniform FrameBlock {\n" + body + "\n};\n"
            f"#else\n{plain}\n#endif\n")


def pack(values: dict) -> bytes:
    """The block's bytes from the frame's uniform values (tuples, numbers, or the float32 bytes the
    plain uniforms take: matrices column-major, arrays tightly packed)."""
    return Packer().pack(values)


class Packer:
    """pack() that keeps the last bytes and the value of each field they hold: a frame writes only
    the fields whose value changed (the lights' colours and the exposure in a stream), the rest of
    the block is the last frame's bytes."""

    def __init__(self):
        self._out = np.zeros(SIZE // 4, np.float32)
        self._held: dict[str, object] = {}

    def pack(self, values: dict) -> bytes:
        out, held = self._out, self._held
        ints = out.view(np.int32)
        for f in FIELDS:
            value = values[f.name]
            last = held.get(f.name, _UNSET)
            if last is value or _same(last, value):
                continue
            at = OFFSETS[f.name] // 4
            if f.glsl == "int":
                ints[at] = int(value)
            else:
                data = (np.frombuffer(value, np.float32) if isinstance(value, bytes)
                        else np.asarray(value, np.float32).ravel())
                if f.count and f.components < 4:  # array elements padded to 16 bytes
                    padded = out[at: at + 4 * f.count].reshape(f.count, 4)
                    padded[:, : f.components] = data.reshape(f.count, f.components)
                else:
                    out[at: at + data.size] = data
            held[f.name] = value.copy() if isinstance(value, np.ndarray) else value
        return out.tobytes()


_UNSET = object()


def _same(a, b) -> bool:
    """Whether the value ``b`` packs to the bytes ``a`` did: equal numbers (bytes, tuples) of the
    same type, a zero of the same sign (0.0 == -0.0, and a shader may tell them apart). Arrays are
    never the same (they are packed anew)."""
    if type(a) is not type(b) or isinstance(b, np.ndarray) or not a == b:
        return False
    if isinstance(b, float):
        return b != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b)
    if isinstance(b, tuple) and 0.0 in b:
        return all(_same(x, y) for x, y in zip(a, b))
    return True


class FrameBlock:
    """The block's buffer for one context (``FrameBlock.get(ctx)``): ``update(values)`` writes it
    (when its bytes changed) and keeps it bound to its binding point."""

    _resident: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()

    def __init__(self, ctx, size=(SIZE,)):
        self.ctx = ctx
        self.size = tuple(size)
        self.buffer = ctx.buffer(reserve=SIZE, dynamic=True)
        self.writes = 0
        self._packer = Packer()

    @classmethod
    def get(cls, ctx) -> "FrameBlock":
        return resident(cls, ctx, (SIZE,))

    def release(self) -> None:
        self.buffer.release()

    def update(self, values: dict) -> None:
        if write_buffer(self.buffer, self._packer.pack(values)):
            self.writes += 1
        # Bound every frame (one call): a binding point is context state that other code on the
        # context (a probe, a test) may have used since.
        self.buffer.bind_to_uniform_block(BLOCKS["FRAME"])
        # The view's tile light lists (light_tiles.py) go with the block's lights and view.
        LightTiles.get(self.ctx).update(values)
