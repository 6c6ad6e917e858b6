"""The per-frame sky-view table (sky/sky_view.glsl): clear-air sky radiance, whole-ray in-scattering
and optical depth for every view direction relative to the sun, filled once per frame from the 4D
tables and bound on units 9..11 for every pass (common/atmosphere.glsl reads it).

It is refilled only when what it depends on moved: the sun or moon direction (by more than
~0.003 deg), the moon's light, the camera's altitude (0.1 % or 0.5 m) or the tables. The luminance
of the table also feeds the exposure meter (frame.py), read back at the same time (a 64 KB read).
"""

from __future__ import annotations

import math
import weakref

import moderngl
import numpy as np

from ...photometry import LUMA
from ..bindings import FRAME_UNITS, use_texture
from ..shaders import ProgramCache, set_uniforms
from ..resident import resident
from .tables import AtmosphereTables

SKY_VIEW_UNITS = {"u_sky_view_radiance": FRAME_UNITS["SKY_VIEW_RADIANCE"],
                  "u_sky_view_inscatter": FRAME_UNITS["SKY_VIEW_INSCATTER"], "u_sky_view_tau": FRAME_UNITS["SKY_VIEW_TAU"]}
SKY_VIEW_SIZE = (64, 128)  # (azimuth from the sun over 0..180 deg, elevation), quality knob


def horizon_elevation(altitude_m: float, bottom_radius_km: float) -> float:
    """Elevation (rad, <= 0) of the geometric horizon seen from altitude_m."""
    r = bottom_radius_km + max(altitude_m, 1.0) * 1e-3
    return -math.acos(min(bottom_radius_km / r, 1.0))


def sun_horizontal(sun_dir: np.ndarray) -> tuple[float, float]:
    h = np.asarray(sun_dir[:2], dtype=np.float64)
    n = float(np.linalg.norm(h))
    return (float(h[0] / n), float(h[1] / n)) if n > 1e-9 else (0.0, 1.0)


class SkyView:
    """Resident sky-view textures for one GL context."""

    _resident: "weakref.WeakKeyDictionary[moderngl.Context, SkyView]" = weakref.WeakKeyDictionary()

    def __init__(self, ctx: moderngl.Context, size=SKY_VIEW_SIZE):
        self.ctx = ctx
        self.size = tuple(size)
        self.programs = ProgramCache(ctx)
        self.textures = {}
        for name in SKY_VIEW_UNITS:
            tex = ctx.texture(self.size, 4, dtype="f4")
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            self.textures[name] = tex
        self._key = None
        self._exact_key = None  # the exact inputs of the last update (a repeat returns at once)
        self.radiance_host: np.ndarray | None = None  # (H, W, 3) cd/m^2, for the exposure meter
        self.fills = 0

    @classmethod
    def get(cls, ctx: moderngl.Context, size=SKY_VIEW_SIZE) -> "SkyView":
        return resident(cls, ctx, size)

    def update(self, tables: AtmosphereTables, uniforms: dict, altitude_m: float, sun_dir, moon_dir,
               moon_scale) -> None:
        # The rounded key below is a function of these exact inputs: equal inputs, the same table.
        exact = (tables, tables.key, tuple(sun_dir), tuple(moon_dir), tuple(moon_scale), altitude_m)
        if exact == self._exact_key:
            return
        key = (id(tables), tables.key, tuple(np.round(np.asarray(sun_dir), 5)), tuple(np.round(np.asarray(moon_dir), 5)),
               tuple(np.round(np.asarray(moon_scale) * 1e12, 3)), round(altitude_m, 1) if altitude_m < 500 else
               float(f"{altitude_m:.3g}"))
        if key == self._key:
            self._exact_key = exact
            return
        prog = self.programs.compute("sky/sky_view.glsl")
        set_uniforms(prog, uniforms)
        tables.bind()
        for unit, name in enumerate(SKY_VIEW_UNITS):
            self.textures[name].bind_to_image(unit, read=False, write=True)
        prog.run((self.size[0] + 7) // 8, (self.size[1] + 7) // 8, 1)
        self.ctx.memory_barrier()
        data = np.frombuffer(self.textures["u_sky_view_radiance"].read(), dtype=np.float32)
        self.radiance_host = data.reshape(self.size[1], self.size[0], 4)[..., :3].astype(np.float64)
        self._key = key
        self._exact_key = exact
        self.fills += 1

    def bind(self) -> None:
        for name, unit in SKY_VIEW_UNITS.items():
            use_texture(self.textures[name], unit)

    def uniforms(self) -> dict:
        return dict(SKY_VIEW_UNITS)

    def luminance(self, dirs: np.ndarray, sun_h: tuple[float, float], horizon_el: float) -> np.ndarray:
        """Clear-sky luminance (cd/m^2) of unit directions from the read-back table (nearest texel),
        the CPU mirror of sky_view_uv_sized()."""
        w, h = self.size
        dirs = np.asarray(dirs, dtype=np.float64)
        lh = np.linalg.norm(dirs[:, :2], axis=1)
        cos_phi = np.where(lh > 1e-7, (dirs[:, 0] * sun_h[0] + dirs[:, 1] * sun_h[1]) / np.maximum(lh, 1e-12), 1.0)
        u = np.arccos(np.clip(cos_phi, -1, 1)) / math.pi
        e = np.arcsin(np.clip(dirs[:, 2], -1, 1))
        above = e >= horizon_el
        v = np.where(above, 0.5 + 0.5 * np.sqrt(np.clip((e - horizon_el) / (math.pi / 2 - horizon_el), 0, 1)),
                     0.5 - 0.5 * np.sqrt(np.clip((horizon_el - e) / (horizon_el + math.pi / 2), 0, 1)))
        i = np.clip((u * w).astype(int), 0, w - 1)
        j = np.clip((v * h).astype(int), 0, h - 1)
        return self.radiance_host[j, i] @ LUMA

    def release(self) -> None:
        for tex in self.textures.values():
            tex.release()
