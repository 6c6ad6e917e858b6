"""The sea's per-frame tables: the sky reflection and the aerial perspective over the sea
(sea_tables.glsl), filled from the shared atmosphere functions."""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ..bindings import PASS_UNITS, use_texture
from ..shaders import set_uniforms

SKY_REFLECT_UNIT = PASS_UNITS["SEA_SKY_REFLECT"]
AIR_T_UNIT = PASS_UNITS["SEA_AIR_T"]
AIR_S_UNIT = PASS_UNITS["SEA_AIR_S"]
SKY_REFLECT_SIZE = (128, 128)  # the upper hemisphere on a disk (sea_tables.glsl): 0.45 deg per texel at the horizon
AIR_SIZE = (64, 96)  # azimuth x log distance: 5.6 deg, ~10 % distance steps past AIR_D0
AIR_D0 = 10.0  # m


class SeaTables:
    """The per-frame sky reflection and aerial perspective tables of the sea (sea_tables.glsl), filled
    from the shared atmosphere functions; the sky-view table (sky/sky_view.py) underneath them is the
    atmosphere's per-frame evaluation, these two only add the fog layer and the sea's geometry."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.sky = ctx.texture(SKY_REFLECT_SIZE, 4, dtype="f4")
        self.air = [ctx.texture(AIR_SIZE, 4, dtype="f4") for _ in range(2)]
        for tex in (self.sky, *self.air):
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x, tex.repeat_y = True, False  # azimuth wraps, the other axis clamps
        self.sky.repeat_x = False  # the stereographic disk: clamped
        self.sky_fbo = ctx.framebuffer(color_attachments=[self.sky])
        self.air_fbo = ctx.framebuffer(color_attachments=self.air)
        self._key = None
        self.fills = 0

    # Frame uniforms the tables do not depend on (the view, the display, local lights, the cirrus):
    # everything else (sun, moon, fog, the atmosphere's parameters and tier, the camera's altitude) is
    # part of the key, so a state the tables could depend on refills them.
    VIEW_ONLY = ("u_camera_", "u_frustum_tangents", "u_view_proj", "u_inv_view_proj", "u_resolution", "u_exposure",
                 "u_view_pixel_angle", "u_light_", "u_cirrus_", "u_adaptation_")

    def key(self, frame, level_z: float, air_map: tuple[float, float]) -> tuple:
        sky_view, tables = frame.resources.get("sky_view"), frame.resources.get("atmosphere_tables")
        state = tuple(sorted((k, v.tobytes() if isinstance(v, np.ndarray) else v)  # arrays compare as bytes
                             for k, v in frame.uniforms.items() if not k.startswith(self.VIEW_ONLY)))
        return (state, level_z, air_map, id(tables), getattr(tables, "key", None), id(sky_view),
                getattr(sky_view, "fills", None))

    @staticmethod
    def air_map(reach: float) -> tuple[float, float]:
        """(d0, 1 / log(1 + d_max / d0)) of the distance axis for sea out to ``reach`` m."""
        return AIR_D0, 1.0 / math.log1p(max(reach, 10.0 * AIR_D0) / AIR_D0)

    def fill(self, water, frame, level_z: float, reach: float) -> dict:
        """Fill both tables for this frame (unless nothing they depend on changed since the last
        fill); returns the sampler/map uniforms of sea_tables.glsl."""
        # The distance axis in 1/8 octaves of the reach, so a moving camera does not refill for it.
        air_map = self.air_map(2.0 ** (math.ceil(8.0 * math.log2(max(reach, 1.0))) / 8.0))
        key = self.key(frame, round(level_z, 2), air_map)
        if key != self._key:
            sky_view = frame.resources.get("sky_view")
            if sky_view is not None:  # units 9..11 may have been taken by an earlier pass this frame
                sky_view.bind()
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            for fbo, defines in ((self.sky_fbo, {"SEA_TABLE_SKY": 1}), (self.air_fbo, {})):
                program = water.programs.program("common/fullscreen.vert.glsl", "water/sea_tables.frag.glsl", defines)
                set_uniforms(program, frame.uniforms)
                set_uniforms(program, {"u_sea_air_map": air_map, "u_level_z": level_z})
                fbo.use()
                water.fullscreen(program)
            self._key = key
            self.fills += 1
        use_texture(self.sky, SKY_REFLECT_UNIT)
        use_texture(self.air[0], AIR_T_UNIT)
        use_texture(self.air[1], AIR_S_UNIT)
        return {"u_sky_reflect": SKY_REFLECT_UNIT, "u_sea_air_t": AIR_T_UNIT, "u_sea_air_s": AIR_S_UNIT,
                "u_sea_air_map": air_map}
