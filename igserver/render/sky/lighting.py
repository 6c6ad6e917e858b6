"""Light for the other pipelines from the precomputed atmosphere: the sun's transmitted
illuminance, the sky's irradiance, the moon, and the automatic exposure.

  E_sun(h)   = E_0 * exp(-tau(h, mu_s))                    lux per channel, normal to the sun
  E_sky(h)   = E_0 * I(h, mu_s)                            lux, horizontal, from the irradiance table
  L_ambient  = E_sky / pi                                  cd/m^2 (the u_sky_ambient convention)
  EV100      = log2(E_total * 100 / 250) + twilight offset,  E_total the horizontal illuminance (sun + sky + moon +
               a natural night floor), clamped to [-9, 20] so noon to astronomical night stays
               watchable without a black frame.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .atmosphere_model import SOLAR_ILLUMINANCE, SUN_ANGULAR_RADIUS, AtmosphereParameters, sun_transmittance
from .daylight import FULL_MOON_ILLUMINANCE, Daylight, daylight

LUMA = np.array([0.2126, 0.7152, 0.0722])
SUN_SOLID_ANGLE = 2 * math.pi * (1 - math.cos(SUN_ANGULAR_RADIUS))  # sr
MOON_ANGULAR_RADIUS = math.radians(0.259)
MOON_SOLID_ANGLE = 2 * math.pi * (1 - math.cos(MOON_ANGULAR_RADIUS))
# Natural night sky (airglow + zodiacal light + unresolved stars), cd/m^2 at the zenith: ~21.5
# mag/arcsec^2 ~ 2e-4 cd/m^2, slightly green-blue. Added to the precomputed sky and to exposure.
NIGHT_SKY_LUMINANCE = np.array([1.6e-4, 2.1e-4, 2.4e-4])
EV_MIN, EV_MAX = -9.0, 20.0


def twilight_ev_offset(sun_elevation: float) -> float:
    """Around sunset the sky toward the sun is several times brighter than the horizontal
    illuminance / pi an incident-light meter exposes for: expose for the sky instead (+2.5..3 EV,
    fading in from +15 deg, down to +1 EV at -20 deg). A tuned heuristic, not photometry."""
    return float(np.interp(sun_elevation, [-20.0, -12.0, 3.0, 15.0], [1.0, 3.0, 2.5, 0.0]))


def irradiance_from_table(params: AtmosphereParameters, irradiance: np.ndarray, altitude_m: float,
                          mu_s: float) -> np.ndarray:
    """Bilinear lookup of the (rows r, cols mu_s, 4) irradiance table, mirroring irradiance_uv()."""
    rows, cols = irradiance.shape[:2]
    x_r = (min(max(altitude_m, 1.0), (params.top_radius_km - params.bottom_radius_km) * 1000.0)
           / 1000.0) / (params.top_radius_km - params.bottom_radius_km)
    fx = min(max(mu_s * 0.5 + 0.5, 0.0), 1.0) * (cols - 1)
    fy = x_r * (rows - 1)
    x0, y0 = int(min(fx, cols - 2)), int(min(fy, rows - 2))
    tx, ty = fx - x0, fy - y0
    top = irradiance[y0, x0, :3] * (1 - tx) + irradiance[y0, x0 + 1, :3] * tx
    bottom = irradiance[y0 + 1, x0, :3] * (1 - tx) + irradiance[y0 + 1, x0 + 1, :3] * tx
    return np.maximum(top * (1 - ty) + bottom * ty, 0.0)


def precomputed_daylight(params: AtmosphereParameters, irradiance_table: np.ndarray, sun_elevation: float,
                         altitude_m: float, turbidity: float, moon_elevation: float,
                         moon_phase: float) -> Daylight:
    """Daylight for the precomputed tier (the gradient fields stay analytic for the cheap tier)."""
    base = daylight(sun_elevation, altitude_m, turbidity, moon_elevation, moon_phase)
    mu_s = math.sin(math.radians(sun_elevation))
    t_sun = sun_transmittance(params, altitude_m, sun_elevation)
    sun = SOLAR_ILLUMINANCE * t_sun
    e_sky = SOLAR_ILLUMINANCE * irradiance_from_table(params, irradiance_table, altitude_m, mu_s)
    e_sky = e_sky + math.pi * NIGHT_SKY_LUMINANCE
    moon_t = sun_transmittance(params, altitude_m, moon_elevation)
    moon = FULL_MOON_ILLUMINANCE * moon_phase * moon_t
    total = float(LUMA @ sun) * max(mu_s, 0.0) + float(LUMA @ e_sky)
    total += float(LUMA @ moon) * max(math.sin(math.radians(moon_elevation)), 0.0)
    ev100 = math.log2(total * 100.0 / 250.0) + twilight_ev_offset(sun_elevation)
    ev100 = float(np.clip(ev100, EV_MIN, EV_MAX))
    return replace(base, sun_illuminance=sun, sky_ambient=e_sky / math.pi, sun_disk_luminance=sun / SUN_SOLID_ANGLE,
                   moon_illuminance=moon, ev100=ev100)
