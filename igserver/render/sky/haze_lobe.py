"""The fog/haze layer's lobe table (sky/haze_lobe.glsl): the clear sky's light that reaches the layer
straight through it, scattered toward the eye by the layer's phase function rather than
isotropically (sky/haze_lobe.glsl haze_sky_lobe, the maths), for every view direction on the
sky-view map. The sky, the sea's tables and the surfaces' aerial table read it with one lookup
(haze_lobe) where evaluating the lobe's 82 taps in every texel of their own tables would cost
~100 ms per change on llvmpipe. Bound on the frame-wide unit HAZE_LOBE.

Refilled when the sky-view table refills, the layer changes (its uniforms: an easing visibility
moves them every frame of its transition) or the camera's height above the layer's base moves as
the sky-view table counts a move (0.1 m under 500 m, 3 significant figures above). Not filled
while the camera is high above the layer (haze_lobe_weight() is 0 there: the shaders then skip
the lookup, so what the texture holds is never read)."""

from __future__ import annotations

import weakref

import moderngl

from ..bindings import FRAME_UNITS, use_texture
from ..resident import resident
from ..shaders import ProgramCache, set_uniforms
from .haze import HazeLayer
from .sky_view import SkyView

HAZE_LOBE_UNIT = FRAME_UNITS["HAZE_LOBE"]
HAZE_LOBE_SIZE = (32, 64)  # (azimuth from the sun over 0..180 deg, elevation) on the sky-view map


def lobe_weight(haze: HazeLayer, height_m: float) -> float:
    """The mirror of haze_lobe_weight(): 1 up to the layer's top plus one edge, 0 from two edges
    above that (smoothstep)."""
    x = min(max((height_m - haze.top - haze.edge) / (2.0 * haze.edge), 0.0), 1.0)
    return 1.0 - x * x * (3.0 - 2.0 * x)


class HazeLobe:
    """Resident lobe texture for one GL context."""

    _resident: "weakref.WeakKeyDictionary[moderngl.Context, HazeLobe]" = weakref.WeakKeyDictionary()

    def __init__(self, ctx: moderngl.Context, size=HAZE_LOBE_SIZE):
        self.ctx = ctx
        self.size = tuple(size)
        self.programs = ProgramCache(ctx)
        self.texture = ctx.texture(self.size, 4, dtype="f4")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = False
        self._key = None
        self.fills = 0

    @classmethod
    def get(cls, ctx: moderngl.Context, size=HAZE_LOBE_SIZE) -> "HazeLobe":
        return resident(cls, ctx, size)

    def update(self, sky_view: SkyView, uniforms: dict, haze: HazeLayer, altitude_m: float, height_m: float) -> None:
        """Fill for this frame's sky-view table (bound), layer and camera; ``uniforms`` the frame's
        sky uniforms (the layer's, the sky-view map's), ``altitude_m`` the camera's above sea level,
        ``height_m`` above the layer's base."""
        use_texture(self.texture, HAZE_LOBE_UNIT)
        if haze.beta[1] <= 0.0 or lobe_weight(haze, height_m) <= 0.0:
            return
        key = (id(sky_view), sky_view._key, sky_view.fills, haze.key, float(uniforms["u_haze_base"]),
               round(altitude_m, 1) if altitude_m < 500 else float(f"{altitude_m:.3g}"))
        if key == self._key:
            return
        prog = self.programs.compute("sky/haze_lobe.glsl")
        set_uniforms(prog, {**uniforms, "u_camera_altitude": altitude_m})
        self.texture.bind_to_image(0, read=False, write=True)
        prog.run((self.size[0] + 7) // 8, (self.size[1] + 7) // 8, 1)
        self.ctx.memory_barrier()
        self._key = key
        self.fills += 1

    def uniforms(self) -> dict:
        return {"u_haze_lobe": HAZE_LOBE_UNIT}

    def release(self) -> None:
        self.texture.release()
