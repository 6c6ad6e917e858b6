"""Per-frame sky state: the tables for the scene's atmosphere (resident, bound on units 12..15),
the daylight they imply, and the sky's own uniforms (moon disk, cirrus layer)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from ...scene.model import Scene
from ...weather import wind_heading
from .atmosphere_model import PRESETS, SOLAR_ILLUMINANCE, AtmosphereParameters, atmosphere_parameters
from .daylight import Daylight, daylight
from .lighting import MOON_ANGULAR_RADIUS, MOON_SOLID_ANGLE, NIGHT_SKY_LUMINANCE, precomputed_daylight
from .tables import TABLE_UNITS, AtmosphereTables

CIRRUS_FEATURE_KM = 6.0     # noise lattice unit on the cirrus layer
CIRRUS_PERIOD_UNITS = 64.0  # noise period (lattice units) per horizontal axis: offsets wrap on it


def scene_atmosphere(scene: Scene) -> AtmosphereParameters:
    a = scene.atmosphere
    return atmosphere_parameters(a.visibility, a.turbidity, a.ozone, PRESETS[a.quality], a.scattering_orders)


@dataclass
class SkyFrame:
    light: Daylight
    uniforms: dict
    tables: AtmosphereTables | None


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


def sky_frame(ctx: moderngl.Context, scene: Scene, celestial, altitude_m: float,
              camera_xy_m: np.ndarray) -> SkyFrame:
    atm = scene.atmosphere
    tables = None
    uniforms: dict = {}
    if atm.model == "precomputed":
        params = scene_atmosphere(scene)
        tables = AtmosphereTables.get(ctx, params)
        tables.bind()
        light = precomputed_daylight(params, tables.irradiance_host, celestial.sun_elevation, altitude_m,
                                     atm.turbidity, celestial.moon_elevation, celestial.moon_phase)
        uniforms.update(tables.uniforms())
        uniforms["u_sky_model"] = 1
    else:
        light = daylight(celestial.sun_elevation, altitude_m, atm.turbidity,
                         celestial.moon_elevation, celestial.moon_phase)
        uniforms.update(AtmosphereParameters().uniforms())  # earth radius etc. for cirrus
        uniforms.update(TABLE_UNITS)
        uniforms["u_sky_model"] = 0
    # Moon disk: the full moon's transmitted illuminance spread over its disk; the phase is drawn
    # from the geometry (terminator from the sun direction), so divide the phase back out.
    moon_lux = np.asarray(light.moon_illuminance) / max(celestial.moon_phase, 1e-3)
    off_x, off_y = cirrus_offset_units(scene, camera_xy_m)
    uniforms.update({
        "u_solar_illuminance": tuple(float(x) for x in SOLAR_ILLUMINANCE),
        "u_night_sky": tuple(float(x) for x in NIGHT_SKY_LUMINANCE),
        "u_moon_disk_cos": math.cos(MOON_ANGULAR_RADIUS),
        "u_moon_disk_luminance": tuple(float(x) for x in moon_lux / MOON_SOLID_ANGLE),
        "u_cirrus_coverage": float(scene.weather.cirrus_coverage),
        "u_cirrus_altitude_km": scene.weather.cirrus_altitude / 1000.0,
        "u_cirrus_offset": (off_x, off_y),
        "u_cirrus_feature_km": CIRRUS_FEATURE_KM,
        "u_cirrus_period": CIRRUS_PERIOD_UNITS,
    })
    return SkyFrame(light, uniforms, tables)
