"""Screen-tile light lists: for each LIGHT_TILE_PX x LIGHT_TILE_PX tile of the view, which point and
spot lights can reach a point seen in it (docs/design.md#surfaces-materials-lights-shadows).

A light contributes exactly 0 beyond its range (common/lights.glsl range_window), so the lights whose
range sphere misses a tile's frustum slice are left out of its list and a pixel's light loop runs over
its tile's lights only; the sum over the rest is the same sum in the same order (ascending index).

The tile grid lives on the image plane, in the same tangents as view_ray(): pixel column x spans the
tangents left + (x, x + 1) / width * (right - left). A tile's slice is the pyramid between four planes
through the camera: p is right of the boundary tangent a when dot(p, right - a * forward) >= 0 (p in
front of the camera). A sphere (centre c, radius r) can reach that side when the signed distance of c
to the plane, dot(c, n) / |n| with n = right - a * forward, is >= -r. A light is listed for a tile when
it reaches the inner side of all four of the tile's planes (the column's slab and the row's slab): a
superset of the lights that touch the pyramid, so no light that can reach a pixel is dropped. The
shader finds the tile from the point it shades (not from gl_FragCoord), so a list is right for any
point of the view whatever target it is drawn into; a point outside the grid takes every light.

Lists are bit masks (bit i: light i, MAX_LIGHTS = 64 bits as two uint32), one RG32UI texel per tile, on
the frame-wide unit LIGHT_TILES. They pay only where some tile lists fewer lights than the frame has:
a camera inside every light's sphere (fires, whose range is where they fall to 0.02 lux, reach a
kilometre) puts every light in every tile, and the frame's shaders then keep the plain loop
(``LIGHT_TILES`` 0, frame.local_light_defines): the lookup would cost without saving. The lists are
built for ranges rounded up to a quarter octave (a larger sphere: still every light that can reach), so
a flickering fire, whose range follows its intensity, does not rebuild them every frame; each view's
lists are kept for the next frame (channels drawn in turn each find theirs).
"""

from __future__ import annotations

import weakref
from collections import OrderedDict

import moderngl
import numpy as np

from .bindings import FRAME_UNITS, use_texture

LIGHT_TILE_PX = 16  # px; the shaders read it as LIGHT_TILE_PX (generated/frame_block.glsl)
# Tangent margin, in pixels, around each tile: float32 rounding of the shader's tangent (and of the
# camera basis it reads) is ~1e-6 of a tangent, far below a pixel at any supported size.
MARGIN_PX = 0.25
RANGE_STEPS = 4  # range rounding steps per octave (quantized_ranges)
HELD_VIEWS = 8  # lists kept per context, the most recently used: a frame's views (channels) and a few more


def tile_grid(width: int, height: int) -> tuple[int, int]:
    return -(-int(width) // LIGHT_TILE_PX), -(-int(height) // LIGHT_TILE_PX)


def tile_masks(right, up, forward, tangents, width: int, height: int, light_pos: np.ndarray,
               count: int) -> np.ndarray:
    """(tiles_y, tiles_x, 2) uint32: bit i of a tile's 64-bit mask (word i // 32) set when light i
    (``light_pos`` rows: camera-relative xyz, range) can reach a point seen in the tile. Row 0 is the
    bottom row of tiles (the shader's tangent grows upward, as texture rows do)."""
    right, up, forward = (np.asarray(v, np.float64) for v in (right, up, forward))
    lights = np.asarray(light_pos, np.float64)[:count]
    # ranges a hair larger: the shader's float32 distance may put a point at the range just inside it
    c, r = lights[:, :3], lights[:, 3] * (1.0 + 1e-5)
    nx, ny = tile_grid(width, height)
    left, right_t, bottom, top = tangents

    def slabs(axis, lo, hi, pixels, tiles):
        # boundary tangents of every tile edge, each tile grown by the margin on both sides
        px = np.arange(tiles + 1) * LIGHT_TILE_PX
        a = lo + px / pixels * (hi - lo)
        grow = MARGIN_PX / pixels * abs(hi - lo)
        n_lo = axis[None, :] - (a[:-1] - grow)[:, None] * forward  # inner side: p . n >= 0
        n_hi = (a[1:] + grow)[:, None] * forward - axis[None, :]
        d_lo = (n_lo @ c.T) / np.linalg.norm(n_lo, axis=1)[:, None]  # (tiles, lights) signed distance
        d_hi = (n_hi @ c.T) / np.linalg.norm(n_hi, axis=1)[:, None]
        return (d_lo >= -r) & (d_hi >= -r)

    cols = slabs(right, left, right_t, width, nx)  # (nx, lights)
    rows = slabs(up, bottom, top, height, ny)
    weights = np.uint64(1) << np.arange(count, dtype=np.uint64)
    col_bits = (cols * weights).sum(axis=1, dtype=np.uint64)
    row_bits = (rows * weights).sum(axis=1, dtype=np.uint64)
    masks = np.bitwise_and.outer(row_bits, col_bits)  # (ny, nx)
    return masks.view(np.uint32).reshape(ny, nx, 2)  # little-endian: low word first


def camera_in_every_range(centres: np.ndarray, ranges: np.ndarray) -> bool:
    """Whether the camera (the origin) is inside every light's sphere: then every tile's pyramid,
    which starts at the camera, meets every sphere."""
    return bool(np.all(np.einsum("ij,ij->i", centres, centres) < ranges * ranges))


def tile_lists(right, up, forward, tangents, width: int, height: int, centres: np.ndarray,
               ranges: np.ndarray) -> np.ndarray | None:
    """tile_masks for lights at ``centres`` (camera-relative) with ``ranges``, or None when every tile
    would list every light: the camera inside every sphere (each tile's pyramid starts there), or no
    tile's slice missing any sphere."""
    centres = np.asarray(centres, np.float64)
    count = len(centres)
    if camera_in_every_range(centres, ranges):
        return None
    masks = tile_masks(right, up, forward, tangents, width, height, np.column_stack([centres, ranges]), count)
    full = (1 << count) - 1
    if np.all(masks[..., 0] == np.uint32(full & 0xFFFFFFFF)) and np.all(masks[..., 1] == np.uint32(full >> 32)):
        return None
    return masks


_MISSING = object()


def quantized_ranges(ranges: np.ndarray) -> np.ndarray:
    """Ranges rounded up to the next 2^(k/4) m (at most 19 % larger)."""
    return np.exp2(np.ceil(np.log2(np.maximum(ranges, 1e-3)) * RANGE_STEPS) / RANGE_STEPS)


class LightTiles:
    """The tile lists of one context (``LightTiles.get(ctx)``). ``update(values)``, with the frame
    block's values, binds that view's lists and says whether it has any (the shaders' LIGHT_TILES)."""

    _resident: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()

    def __init__(self, ctx):
        self.ctx = ctx
        self._quantized: OrderedDict = OrderedDict()  # the block's exact values -> the lists' key
        self._lists: OrderedDict = OrderedDict()  # the lists' key -> texture, or None: every tile has every light
        self._spare: dict = {}  # size -> a texture whose lists were dropped, to be written again
        self.builds = 0

    @classmethod
    def get(cls, ctx) -> "LightTiles":
        held = cls._resident.get(ctx)
        if held is None:
            held = cls._resident[ctx] = cls(ctx)
        return held

    def update(self, values: dict) -> bool:
        count = int(values["u_light_count"])
        if count == 0:  # LOCAL_LIGHTS 0: no shader reads the lists
            return False
        exact = (values["u_light_pos"], count, values["u_camera_right"], values["u_camera_up"],
                 values["u_camera_forward"], values["u_frustum_tangents"], values["u_resolution"])
        key = _lookup(self._quantized, exact, _quantized_key)
        if key is None:
            return False
        texture = _lookup(self._lists, key, self._build, self._keep_spare)
        if texture is None:
            return False
        use_texture(texture, FRAME_UNITS["LIGHT_TILES"])
        return True

    def _keep_spare(self, dropped) -> None:
        """A dropped view's texture, kept to be written again by a view of its size."""
        if dropped is not None:
            self._spare.setdefault(dropped.size, dropped)

    def _build(self, key):
        positions, ranges, count, right, up, forward, tangents, width, height = key
        centres = np.frombuffer(positions, np.float32).reshape(count, 3)
        masks = tile_lists(right, up, forward, tangents, width, height, centres, np.frombuffer(ranges, np.float64))
        if masks is None:
            return None
        size = (masks.shape[1], masks.shape[0])
        texture = self._spare.pop(size, None)
        if texture is None:
            texture = self.ctx.texture(size, 2, dtype="u4")
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)  # integer texels: texelFetch only
        texture.write(np.ascontiguousarray(masks).tobytes())
        self.builds += 1
        return texture

    def release(self) -> None:
        for texture in [*self._lists.values(), *self._spare.values()]:
            if texture is not None:
                texture.release()
        self._lists.clear()
        self._spare.clear()
        self._quantized.clear()


def _quantized_key(exact: tuple) -> tuple | None:
    """The key of the lists for the frame block's values ``exact``, or None when the camera is inside
    every light's sphere (every tile lists every light: no lists), the common case of fires, found
    before any rounding (a larger sphere holds the camera too)."""
    light_pos, count, right, up, forward, tangents, resolution = exact
    pos = np.frombuffer(light_pos, np.float32).reshape(-1, 4)[:count]
    if camera_in_every_range(pos[:, :3], pos[:, 3]):
        return None
    ranges = quantized_ranges(pos[:, 3].astype(np.float64))
    return (np.ascontiguousarray(pos[:, :3]).tobytes(), ranges.tobytes(), count, right, up, forward, tangents,
            int(resolution[0]), int(resolution[1]))


def _lookup(held: OrderedDict, key, compute, dropped=lambda value: None):
    """``held[key]``, made by ``compute(key)`` when absent; the HELD_VIEWS most recently used kept (each
    one dropped handed to ``dropped``)."""
    value = held.get(key, _MISSING)
    if value is _MISSING:
        value = held[key] = compute(key)
        while len(held) > HELD_VIEWS:
            dropped(held.popitem(last=False)[1])
    else:
        held.move_to_end(key)
    return value
