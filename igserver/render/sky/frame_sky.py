"""Per-frame sky state: the clear-air tables for the scene's turbidity class (resident, units
12..15), the fog/haze layer for its visibility (eased, analytic), the per-frame sky-view table
(units 9..11), the light they imply, and the sky's own uniforms (moon disk, cirrus layer)."""

from __future__ import annotations

import math
import weakref
from functools import lru_cache
from dataclasses import dataclass, replace

import moderngl
import numpy as np

from ...photometry import LUMA
from ...astro.ephemeris import direction_enu, refraction_deg
from ...scene.model import Scene
from ...water.spectrum import cox_munk_mss
from ...weather import effective_visibility, wind_heading
from ..bindings import FRAME_UNITS, use_texture
from ..memo import Memo
from .atmosphere_model import (KOSCHMIEDER, PRESETS, SOLAR_ILLUMINANCE, AtmosphereParameters, atmosphere_parameters,
                               ground_extinction_550_per_m, turbidity_class)
from .daylight import Daylight, daylight
from .haze import GROUND_ALBEDO, HazeLayer, HazeTransition, haze_layer
from .haze_lobe import HazeLobe
from .lighting import (MOON_ANGULAR_RADIUS, MOON_SOLID_ANGLE, NIGHT_SKY_ILLUMINANCE, NIGHT_SKY_LUMINANCE,
                       clear_light, moon_illuminance_toa, precomputed_daylight)
from .sky_view import SkyView, horizon_elevation, sun_horizontal
from .tables import TABLE_UNITS, AtmosphereTables

CIRRUS_FEATURE_KM = 6.0     # noise lattice unit on the cirrus layer
CIRRUS_PERIOD_UNITS = 64.0  # noise period (lattice units) per horizontal axis: offsets wrap on it; x 11/32
# (cirrus.glsl CIRRUS_STREAK_X) must stay a whole number too, or the streaks jump at the wrap


def scene_atmosphere(scene: Scene) -> AtmosphereParameters:
    a = scene.atmosphere
    return _parameters(turbidity_class(a.turbidity), a.ozone, a.quality, a.scattering_orders)


@lru_cache(maxsize=64)
def _parameters(turbidity: float, ozone: bool, quality: str, orders: int) -> AtmosphereParameters:
    return atmosphere_parameters(turbidity, ozone, PRESETS[quality], orders)


_clear_light_cache: dict = {}
# sky_frame's light, horizontal illuminance, haze uniforms and haze light table per exact inputs.
_sky_light_cache: dict = {}


def cached_clear_light(params, tables: AtmosphereTables, altitude_m, sun_el, moon_el, moon_phase):
    """clear_light() memoised per frame inputs (its float64 integrals cost ~5 ms a call); the sky's
    light from the sun where the scattering air sees it (sky_sun_elevation)."""
    key = (tables.key, round(altitude_m, 2), round(sun_el, 6), round(moon_el, 5), round(moon_phase, 6))
    hit = _clear_light_cache.get(key)
    if hit is None:
        if len(_clear_light_cache) > 256:
            _clear_light_cache.clear()
        hit = _clear_light_cache[key] = clear_light(params, tables.irradiance_host, altitude_m, sun_el, moon_el,
                                                    moon_phase, sky_sun_elevation(sun_el))
    return hit


# Refraction as the sky sees it. The ephemeris gives the sun's APPARENT elevation e_a = e_0 + R(e_0)
# (SPA/Bennett refraction R, 0.48 deg at a true e_0 = 0): the bending of the rays that reach the
# eye through the whole lowest air. The air that scatters the sky's light is lit by rays bent
# only by the air they crossed: a ray grazing at height z is bent by ~R rho(z)/rho(0) (refraction
# scales with the density at the tangent point, scale height H ~ 8 km). Weighting by where that
# light is scattered (density rho) and how much of it arrives (the half tangent path's Rayleigh
# optical depth a rho/rho(0), a = beta_R(550) sqrt(pi R_e H / 2) = 0.013558 /km x 283 km = 3.83):
#     k = <rho/rho0> = int_0^1 x e^(-a x) dx / int_0^1 e^(-a x) dx = (1 - e^-a (1 + a)) / (a (1 - e^-a)),
# 0.24: the sky's sun stands e_0 + k R, not e_0 + R. At a true sunset that is 0.36 deg lower
# than the disk, and the sky's light there is 1.34x lower than for the disk's elevation
# (the irradiance falls by x1.9 a degree near 0 deg).
_A_TANGENT = 0.013558 * math.sqrt(math.pi * 6360.0 * 8.0 / 2.0)
SKY_REFRACTION_FRACTION = (1.0 - math.exp(-_A_TANGENT) * (1.0 + _A_TANGENT)) / (
    _A_TANGENT * (1.0 - math.exp(-_A_TANGENT)))
_REFRACTION_LIMIT = -(0.26667 + 0.5667)  # deg, true elevation below which the ephemeris applies none


def sky_sun_elevation(apparent_deg: float) -> float:
    """The sun's elevation (deg) for the sky's light: the apparent elevation less the part of
    its refraction the scattering air does not see (SKY_REFRACTION_FRACTION above). The
    ephemeris jumps from e_a = e_lim + R(e_lim) (-0.21 deg) to e_lim (-0.83) as the refraction
    stops; an instructor's fixed sun (time.sun_override) may lie in that gap, where the
    refraction is taken linear in e_a, so the result is continuous and rising in e_a."""
    top = _REFRACTION_LIMIT + refraction_deg(_REFRACTION_LIMIT)
    if apparent_deg <= _REFRACTION_LIMIT:
        return apparent_deg
    if apparent_deg < top:
        bend = refraction_deg(_REFRACTION_LIMIT) * (apparent_deg - _REFRACTION_LIMIT) / (top - _REFRACTION_LIMIT)
    else:
        true = apparent_deg - refraction_deg(apparent_deg)
        for _ in range(8):  # e_0 = e_a - R(e_0): |dR/de| < 0.25, converges to float64 in ~8 steps
            true = apparent_deg - refraction_deg(max(true, _REFRACTION_LIMIT))
        bend = apparent_deg - true
    return apparent_deg - (1.0 - SKY_REFRACTION_FRACTION) * bend


def scene_visibility(scene: Scene) -> float:
    """The one place the renderer reads the visibility (m): the host's value with the extinction of
    rain or snow added (igserver.weather.effective_visibility), unless the host says its value
    already includes it (weather.precipitation.lowers_visibility = false)."""
    return float(effective_visibility(scene))


def scene_haze(scene: Scene, params: AtmosphereParameters) -> HazeLayer:
    a = scene.atmosphere
    return haze_layer(scene_visibility(scene), a.turbidity, a.fog_top, _ground_extinction(params),
                      scene_ground_albedo(scene), cox_munk_mss(scene.weather.wind_speed) if scene.ocean.enabled else -1.0)


def scene_ground_albedo(scene: Scene) -> float:
    """Albedo under the fog/haze layer: the drawn ground's colour (its luminance, a Lambertian
    base colour: snow 0.8), the layer's default 0.1 over the sea or where no ground is drawn."""
    g = scene.ground
    if not g.enabled or scene.ocean.enabled:
        return GROUND_ALBEDO
    return float(np.dot(LUMA, g.color))


@lru_cache(maxsize=64)
def _ground_extinction(params: AtmosphereParameters) -> float:
    return ground_extinction_550_per_m(params)  # memoised: it integrates the aerosol profile


@dataclass
class SkyFrame:
    light: Daylight
    uniforms: dict
    tables: AtmosphereTables | None
    sky_view: SkyView | None = None
    haze: HazeLayer | None = None
    horizontal_illuminance: float = 0.0  # lux, natural light at the camera


def cirrus_offset_units(scene: Scene, camera_xy_m: np.ndarray) -> tuple[float, float]:
    """Noise-space position of the camera on the cirrus layer, drifted by the high wind, reduced
    modulo the noise period in float64 (a week of sim_time or 1e6 m of camera travel stays exact)."""
    w = scene.weather
    speed = w.cirrus_wind_speed if w.cirrus_wind_speed is not None else 4.0 * w.wind_speed
    # The one wind's direction (igserver.weather), stronger aloft; defined in calm air too.
    drift = wind_heading(scene) * speed * scene.time.sim_time  # m
    # The pattern is fixed in the air mass: a point x of the world sees noise at x - drift.
    pos = (np.asarray(camera_xy_m, dtype=np.float64) - drift) / (CIRRUS_FEATURE_KM * 1000.0)
    pos = np.mod(pos, CIRRUS_PERIOD_UNITS)
    return float(pos[0]), float(pos[1])


FOG_RELIEF_CELL_M = 300.0  # common/atmosphere.glsl fog_top_relief: the noise's lattice unit on the top
FOG_RELIEF_PERIOD_UNITS = 64.0
FOG_RELIEF_DEPTH_FRACTION = 0.1  # the top heaves by ~10 % of the layer's depth (Stull 1988, ch. 11)
FOG_RELIEF_MIN_SUN_DEG = 2.0  # below, the top is lit by the sky and its own glow: no sun on its slopes


def fog_relief_uniforms(haze: HazeLayer | None, height_m: float, camera_xy_m, sun_elevation: float) -> tuple:
    """u_fog_relief: the camera's position in the relief's noise units (wrapped on its period), its
    height above a sunlit fog layer's top (m; 0, no relief, where it is not above one) and the
    relief's amplitude (m)."""
    on = (haze is not None and haze.top > 0.0 and float(haze.beta[1]) > 0.0
          and height_m > haze.top + haze.edge and sun_elevation > FOG_RELIEF_MIN_SUN_DEG)
    if not on:
        return (0.0, 0.0, 0.0, 0.0)
    pos = np.mod(np.asarray(camera_xy_m, dtype=np.float64) / FOG_RELIEF_CELL_M, FOG_RELIEF_PERIOD_UNITS)
    amplitude = min(max(FOG_RELIEF_DEPTH_FRACTION * haze.top, 2.0), 40.0)
    return (float(pos[0]), float(pos[1]), float(height_m - haze.top), amplitude)


# The part of sky_frame that follows the world (everything but the cirrus layer's drift with
# sim_time and the GL bindings), per exact inputs (Memo: the last value per view).
SKY_PARTS = Memo()


def sky_frame(ctx: moderngl.Context, scene: Scene, celestial, altitude_m: float,
              camera_xy_m: np.ndarray, transition: HazeTransition | None = None) -> SkyFrame:
    atm = scene.atmosphere
    tables = params = haze = None
    if atm.model == "precomputed":
        params = scene_atmosphere(scene)
        tables = AtmosphereTables.get(ctx, params)
        tables.bind()
        # scene_haze's inputs: visibility (with the precipitation's), turbidity, fog top, the
        # atmosphere's parameters (from the atmosphere record), the ground's albedo, the sea's wind
        haze = SKY_PARTS.get("haze", (atm, scene.weather.precipitation, scene.ground, scene.ocean.enabled,
                                      scene.weather.wind_speed),
                             lambda: scene_haze(scene, params))
        if transition is not None:
            beta = transition.apply(haze.beta, atm.visibility_transition, scene.time.sim_time)
            # one layer object per (layer, eased extinction): a settled haze keeps its computed key
            haze = SKY_PARTS.get("eased_haze", (haze.key, beta.tobytes()), lambda: replace(haze, beta=beta))
    xy = (float(camera_xy_m[0]), float(camera_xy_m[1]))
    # Everything _sky_parts reads: the tables, the fog layer, the atmosphere and weather records
    # (visibility, turbidity, cirrus), the ground's altitude, sun and moon, the camera's position.
    key = (None if tables is None else (id(tables), tables.key), None if haze is None else haze.key, atm,
           scene.weather, scene.location.altitude, celestial, altitude_m, xy)
    light, horizontal, static, table, table_key, sky_sun = SKY_PARTS.get(
        "sky", key, lambda: _sky_parts(scene, celestial, altitude_m, xy, tables, params, haze))
    uniforms = dict(static)
    uniforms["u_cirrus_offset"] = cirrus_offset_units(scene, camera_xy_m)
    if table is not None:
        use_texture(haze_table_texture(ctx, table, table_key), HAZE_TABLE_UNIT)
    sky_view = None
    if tables is not None:
        sky_view = SkyView.get(ctx)
        # The clear sky is scattered light: its sun stands where the scattering air sees it.
        sky_view.update(tables, {**uniforms, "u_camera_altitude": altitude_m,
                                 "u_sun_dir": sky_sun, "u_moon_dir": _t(celestial.moon_dir)},
                        altitude_m, sky_sun, celestial.moon_dir, uniforms["u_moon_scale"])
        sky_view.bind()
        uniforms.update(sky_view.uniforms())
        if haze is not None:
            lobe = HazeLobe.get(ctx)
            lobe.update(sky_view, uniforms, haze, altitude_m, altitude_m - scene.location.altitude)
            uniforms.update(lobe.uniforms())
    return SkyFrame(light, uniforms, tables, sky_view, haze, horizontal)


def _sky_parts(scene: Scene, celestial, altitude_m: float, camera_xy_m: tuple, tables, params, haze) -> tuple:
    """(light, horizontal illuminance, the sky's uniforms but the cirrus offset and the sky-view
    units, the fog layer's light table and its key or None, the sky's sun direction)."""
    atm = scene.atmosphere
    uniforms: dict = {}
    table = key = None
    ground_m = scene.location.altitude
    moon_toa_lux = moon_illuminance_toa(celestial.moon_phase)
    moon_toa = moon_toa_lux * SOLAR_ILLUMINANCE / float(np.dot(LUMA, SOLAR_ILLUMINANCE))
    if tables is not None:
        # Everything below depends only on these inputs (exact values: a hit is the same result);
        # in a stream with a fixed UTC and steady fog they repeat every frame.
        key = (tables.key, atm.turbidity, altitude_m, ground_m, celestial.sun_elevation, celestial.moon_elevation,
               celestial.moon_phase, _t(celestial.sun_dir), _t(celestial.moon_dir), haze.key)
        hit = _sky_light_cache.get(key)
        if hit is None:
            clear = cached_clear_light(params, tables, altitude_m, celestial.sun_elevation,
                                       celestial.moon_elevation, celestial.moon_phase)
            light, horizontal = precomputed_daylight(params, tables.irradiance_host, celestial.sun_elevation,
                                                     altitude_m, atm.turbidity, celestial.moon_elevation,
                                                     celestial.moon_phase, haze, altitude_m - ground_m, clear)
            # Light arriving at the layer: the clear air's at the layer's top.
            top = cached_clear_light(params, tables, ground_m + haze.top + 0.5 * haze.edge,
                                     celestial.sun_elevation, celestial.moon_elevation, celestial.moon_phase)
            part = {**tables.uniforms(), **haze.uniforms(ground_m),
                    "u_haze_sun": _t(top.sun_normal), "u_haze_moon": _t(top.moon_normal),
                    "u_haze_sky": _t(top.sky_horizontal + NIGHT_SKY_ILLUMINANCE)}
            table = None
            if haze.beta[1] > 0.0:
                table = haze.source_table(top.sun_normal, float(celestial.sun_dir[2]), top.sky_horizontal
                                          + NIGHT_SKY_ILLUMINANCE, top.moon_normal, float(celestial.moon_dir[2]))
            if len(_sky_light_cache) > 64:
                _sky_light_cache.clear()
            hit = _sky_light_cache[key] = (light, horizontal, part, table)
        light, horizontal, part, table = hit
        uniforms.update(part)
        uniforms["u_haze_table"] = HAZE_TABLE_UNIT
        uniforms["u_sky_model"] = 1
        uniforms["u_fog_beta"] = float(haze.beta[1])
    else:
        light = daylight(celestial.sun_elevation, altitude_m, atm.turbidity,
                         celestial.moon_elevation, celestial.moon_phase)
        horizontal = float(np.dot(LUMA, light.sun_illuminance)) * max(
            math.sin(math.radians(celestial.sun_elevation)), 0.0) + float(
            np.dot(LUMA, light.sky_ambient)) * math.pi
        uniforms.update(AtmosphereParameters().uniforms())  # earth radius etc. for cirrus
        uniforms.update(TABLE_UNITS)
        uniforms.update(HazeLayer(np.zeros(3), 0.0, 1.0, 0.8, 1.0).uniforms(ground_m))
        uniforms["u_sky_model"] = 0
        uniforms["u_fog_beta"] = KOSCHMIEDER / scene_visibility(scene)  # gradient tier's exponential haze
    # Moon disk: the moon's illuminance above the atmosphere spread over its disk; the phase is drawn
    # from the geometry (terminator from the sun direction), so divide the phase back out. The sky
    # pass multiplies by the view transmittance.
    moon_lux = moon_toa / max(celestial.moon_phase, 1e-3)
    uniforms["u_fog_relief"] = fog_relief_uniforms(haze, altitude_m - ground_m, camera_xy_m, celestial.sun_elevation)
    sun_h = sun_horizontal(celestial.sun_dir)
    bottom = uniforms.get("u_bottom_radius_km", AtmosphereParameters.bottom_radius_km)
    moon_up = celestial.moon_elevation > -10.0 and celestial.moon_phase > 0.0
    uniforms.update({
        "u_solar_illuminance": _t(SOLAR_ILLUMINANCE),
        "u_night_sky": _t(NIGHT_SKY_LUMINANCE),
        "u_moon_scale": _t(moon_toa / SOLAR_ILLUMINANCE if moon_up else np.zeros(3)),
        "u_moon_disk_cos": math.cos(MOON_ANGULAR_RADIUS),
        "u_moon_disk_luminance": _t(moon_lux / MOON_SOLID_ANGLE),
        "u_cirrus_coverage": float(scene.weather.cirrus_coverage),
        "u_cirrus_altitude_km": scene.weather.cirrus_altitude / 1000.0,
        "u_cirrus_feature_km": CIRRUS_FEATURE_KM,
        "u_cirrus_period": CIRRUS_PERIOD_UNITS,
        "u_sky_view_sun_h": sun_h,
        "u_horizon_elevation": horizon_elevation(altitude_m, bottom),
    })
    sky_sun = _t(direction_enu(sky_sun_elevation(celestial.sun_elevation), celestial.sun_azimuth))
    return light, horizontal, uniforms, table, key, sky_sun


HAZE_TABLE_UNIT = FRAME_UNITS["HAZE_TABLE"]
_haze_tables: "weakref.WeakKeyDictionary[moderngl.Context, tuple]" = weakref.WeakKeyDictionary()


def haze_table_texture(ctx: moderngl.Context, table: np.ndarray, key=None) -> moderngl.Texture:
    """The fog layer's per-frame light table (4 rows x 64 heights, RGBA32F), resident per context;
    written again only when ``key`` (the inputs the table was made from) changed."""
    held = _haze_tables.get(ctx)
    tex = held[0] if held is not None else None
    size = (table.shape[1], table.shape[0])
    if tex is None or tex.size != size:
        tex = ctx.texture(size, 4, dtype="f4")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        held = None
    if held is None or key is None or held[1] != key:
        tex.write(np.ascontiguousarray(table, dtype=np.float32).tobytes())
    _haze_tables[ctx] = (tex, key)
    return tex


def held_haze_table(ctx: moderngl.Context) -> tuple[moderngl.Texture, object] | None:
    """(texture, key) of the fog layer's light table last written for ``ctx``, None before the first:
    the key is what the table was made from, so a table that reads it (the aerial table) knows when
    to refill."""
    return _haze_tables.get(ctx)


def _t(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)
