"""Light for the other pipelines from the precomputed atmosphere and the fog/haze layer: the sun's
and moon's transmitted illuminance, the sky's irradiance, and the horizontal illuminance that the
exposure meter and the photometric read-out report.

Clear air (the tables, per turbidity class), at an altitude h:
  E_sun(h)   = E_0 exp(-tau(h, mu_s))                 lux per channel, normal to the sun
  E_sky(h)   = E_0 I(h, mu_s)                          lux, horizontal, from the irradiance table
  E_moon(h)  = E_moon,0(phase) exp(-tau(h, mu_m))      Krisciunas & Schaefer (1991) phase law
  L_night    = the natural night sky (airglow + zodiacal light + integrated starlight)
then the fog/haze layer (sky/haze.py) turns these into the fluxes at the camera's height:
  u_sun_illuminance = E_sun exp(-(1 - g^2) tau_above / slant_mu_s)   (direct + forward peak: sharp shadows;
                      slant_mu_s: HazeLayer.slant_mu, the sun's path on the round earth)
  u_sky_ambient     = (F_down - direct beams) / pi              (cd/m^2)
  horizontal illuminance = F_down (sun + sky + moon through the layer) + pi L_night.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...photometry import LUMA
from .atmosphere_model import SOLAR_ILLUMINANCE, SUN_ANGULAR_RADIUS, AtmosphereParameters, sun_transmittance
from .daylight import Daylight, daylight
from .haze import HazeLayer

SUN_SOLID_ANGLE = 2 * math.pi * (1 - math.cos(SUN_ANGULAR_RADIUS))  # sr
MOON_ANGULAR_RADIUS = math.radians(0.259)
MOON_SOLID_ANGLE = 2 * math.pi * (1 - math.cos(MOON_ANGULAR_RADIUS))
# Natural night sky at a dark site, V = 21.6 mag/arcsec^2 at the zenith (Patat 2003, ESO Paranal,
# dark time): L = 10.8e4 cd/m^2 * 10^(-0.4 V) = 2.5e-4 cd/m^2 (the usual photometric conversion),
# slightly green-blue (airglow 558 nm line, zodiacal light). Added in the sky-view table with a
# van Rhijn brightening toward the horizon, and to the illuminance.
NIGHT_SKY_V_MAG_ARCSEC2 = 21.6
NIGHT_SKY_LUMINANCE = 10.8e4 * 10 ** (-0.4 * NIGHT_SKY_V_MAG_ARCSEC2) * np.array([0.8, 1.05, 1.2]) / float(
    LUMA @ np.array([0.8, 1.05, 1.2]))
# Horizontal illuminance of the natural night sky: pi L times the van Rhijn mean over the dome
# (the sky in the table is L (1 + 2 (1 - sin e)^4), whose cosine-weighted mean is ~1.27 L).
NIGHT_SKY_ILLUMINANCE = math.pi * 1.27 * NIGHT_SKY_LUMINANCE


def moon_illuminance_toa(phase_fraction: float) -> float:
    """Illuminance (lux) of the moon above the atmosphere at mean distance, normal to it, from its
    illuminated fraction k: phase angle a = acos(2k - 1) (deg), Krisciunas & Schaefer (1991, PASP
    103, 1033), eq. 20: I = 10^(-0.4 (3.84 + 0.026 |a| + 4e-9 a^4)) foot-candles (1 fc = 10.764 lx).
    Full moon: 0.31 lx; quarter: 0.025 lx (the opposition surge makes the full moon 10x a quarter)."""
    k = min(max(phase_fraction, 0.0), 1.0)
    a = math.degrees(math.acos(2.0 * k - 1.0))
    return 10.0 ** (-0.4 * (3.84 + 0.026 * a + 4e-9 * a ** 4)) * 10.764


def irradiance_from_table(params: AtmosphereParameters, irradiance: np.ndarray, altitude_m: float,
                          mu_s: float) -> np.ndarray:
    """Lookup of the (rows r, cols sun elevation, 4) irradiance table, mirroring irradiance_uv():
    linear in altitude, GEOMETRIC between the sun-elevation columns (the twilight irradiance falls
    exponentially: straight lines between 0.9-deg columns would overshoot and kink). Below the
    table's last elevation it keeps falling at the last columns' rate (never a constant floor)."""
    rows, cols = irradiance.shape[:2]
    x_r = (min(max(altitude_m, 1.0), (params.top_radius_km - params.bottom_radius_km) * 1000.0)
           / 1000.0) / (params.top_radius_km - params.bottom_radius_km)
    e_min = math.asin(params.mu_s_min)
    e = math.asin(min(max(mu_s, -1.0), 1.0))
    fx = (e - e_min) / (math.pi / 2 - e_min) * (cols - 1)
    fy = x_r * (rows - 1)
    y0 = int(min(fy, rows - 2))
    ty = fy - y0
    column = irradiance[y0, :, :3] * (1 - ty) + irradiance[y0 + 1, :, :3] * ty  # (cols, 3)
    logc = np.log(np.maximum(column, 1e-30))
    x0 = int(min(max(math.floor(fx), 0), cols - 2))
    t = fx - x0  # < 0 below the table: extrapolates the last slope (falling)
    if fx < 0:
        slope = np.maximum(logc[1] - logc[0], 0.0)
        return np.exp(logc[0] + slope * fx)
    t = min(t, 1.0)
    return np.exp(logc[x0] * (1 - t) + logc[x0 + 1] * t)


@dataclass(frozen=True)
class ClearLight:
    """Clear-air light at one altitude (lux per channel)."""

    sun_normal: np.ndarray
    sky_horizontal: np.ndarray
    moon_normal: np.ndarray
    moon_toa: np.ndarray  # above the atmosphere, normal


def clear_light(params: AtmosphereParameters, irradiance_table: np.ndarray, altitude_m: float, sun_elevation: float,
                moon_elevation: float, moon_phase: float, sky_sun_elevation: float | None = None) -> ClearLight:
    """``sun_elevation`` is the apparent (refracted) one the direct beam arrives at;
    ``sky_sun_elevation`` the one the air that scatters the sky's light sees (sky_sun_elevation()
    in frame_sky.py; the apparent one if None)."""
    sky_el = sun_elevation if sky_sun_elevation is None else sky_sun_elevation
    mu_s = math.sin(math.radians(sky_el))
    sun = SOLAR_ILLUMINANCE * sun_transmittance(params, altitude_m, sun_elevation)
    sky = SOLAR_ILLUMINANCE * irradiance_from_table(params, irradiance_table, altitude_m, mu_s)
    moon_toa = moon_illuminance_toa(moon_phase) * SOLAR_ILLUMINANCE / float(LUMA @ SOLAR_ILLUMINANCE)
    moon = moon_toa * sun_transmittance(params, altitude_m, moon_elevation)
    # The moon lights the sky too: scattered moonlight is the sunlit sky scaled by E_moon / E_sun.
    mu_m = math.sin(math.radians(moon_elevation))
    sky = sky + moon_toa * irradiance_from_table(params, irradiance_table, altitude_m, mu_m)
    return ClearLight(sun, sky, moon, moon_toa)


def precomputed_daylight(params: AtmosphereParameters, irradiance_table: np.ndarray, sun_elevation: float,
                         altitude_m: float, turbidity: float, moon_elevation: float, moon_phase: float,
                         haze: HazeLayer | None = None, haze_height_m: float = 0.0,
                         clear: ClearLight | None = None) -> tuple[Daylight, float]:
    """Daylight for the precomputed tier (the gradient fields stay analytic for the cheap tier) and
    the natural horizontal illuminance (lux) at the camera."""
    base = daylight(sun_elevation, altitude_m, turbidity, moon_elevation, moon_phase)
    light = clear or clear_light(params, irradiance_table, altitude_m, sun_elevation, moon_elevation, moon_phase)
    mu_s = math.sin(math.radians(sun_elevation))
    mu_m = math.sin(math.radians(moon_elevation))
    sun, moon, sky = light.sun_normal, light.moon_normal, light.sky_horizontal
    if haze is not None and haze.beta[1] > 0.0:
        f = haze.fluxes(haze_height_m, sun, mu_s, sky, moon, mu_m)
        ta = haze.tau_above(haze_height_m)
        scale = 1.0 - haze.g ** 2
        slant_s, slant_m = haze.slant_mu(mu_s, haze_height_m), haze.slant_mu(mu_m, haze_height_m)
        sun_t = sun * np.exp(-np.minimum(scale * ta / slant_s, 80.0)) if mu_s > 0 else sun * 0.0
        moon_t = moon * np.exp(-np.minimum(scale * ta / slant_m, 80.0)) if mu_m > 0 else moon * 0.0
        down = f["down"]
        sky_diffuse = np.maximum(down - sun_t * max(mu_s, 0.0) - moon_t * max(mu_m, 0.0), 0.0)
        true_sun = sun * np.exp(-np.minimum(ta / slant_s, 80.0))
        sun, moon = sun_t, moon_t
    else:
        down = sun * max(mu_s, 0.0) + moon * max(mu_m, 0.0) + sky
        sky_diffuse = sky
        true_sun = sun
    sky_diffuse = sky_diffuse + NIGHT_SKY_ILLUMINANCE
    horizontal = float(LUMA @ (down + NIGHT_SKY_ILLUMINANCE))
    out = replace(base, sun_illuminance=sun, sky_ambient=sky_diffuse / math.pi,
                  sun_disk_luminance=true_sun / SUN_SOLID_ANGLE, moon_illuminance=moon,
                  ev100=float(math.log2(max(horizontal, 1e-6) * 100.0 / 250.0)))
    return out, horizontal
