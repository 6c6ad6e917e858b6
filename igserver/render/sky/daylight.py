"""Analytic daylight for the gradient tier and for exposure: sun colour, sky ambient, sky gradient.

Units: illuminance in lux, luminance in cd/m^2, per RGB channel (a channel's value is the
luminance it would have if the light were white in that channel). These are engineering fits to
clear-sky measurements, not a scattering solution (that is the precomputed tier's job):
  * direct sun:  E = E0 * exp(-m * tau),  m = Kasten-Young air mass, tau = Rayleigh + aerosol
  * diffuse sky: log-linear interpolation of clear-sky horizontal illuminance vs sun elevation,
    from noon (~20 klx) through civil (-6 deg, ~3 lx) to astronomical twilight (-18 deg, ~1 mlx).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...photometry import LUMA
SOLAR_ILLUMINANCE_TOA = 128_000.0  # lux, solar illuminance constant
SUN_ANGULAR_RADIUS = math.radians(0.2666)  # rad
SUN_SOLID_ANGLE = 2 * math.pi * (1 - math.cos(SUN_ANGULAR_RADIUS))  # sr, ~6.8e-5
FULL_MOON_ILLUMINANCE = 0.25  # lux at zenith, above the atmosphere's losses
# Zenith optical depths for R, G, B (~680, 550, 440 nm): Rayleigh, and aerosol per unit turbidity excess.
RAYLEIGH_TAU = np.array([0.036, 0.097, 0.236])
AEROSOL_TAU_PER_TURBIDITY = np.array([0.052, 0.06, 0.07])
RAYLEIGH_SCALE_HEIGHT = 8000.0  # m
AEROSOL_SCALE_HEIGHT = 1200.0  # m

# Clear-sky diffuse horizontal illuminance (lux) against sun elevation (deg).
_DIFFUSE_ELEV = np.array([-90.0, -18.0, -12.0, -6.0, -3.0, 0.0, 5.0, 10.0, 30.0, 60.0, 90.0])
_DIFFUSE_LUX = np.array([3e-4, 7e-4, 8e-3, 3.4, 60.0, 700.0, 4000.0, 8000.0, 15000.0, 19000.0, 20000.0])


def air_mass(elevation_deg: float) -> float:
    """Kasten & Young (1989) relative air mass; finite down to the horizon, capped below it."""
    zenith = 90.0 - max(elevation_deg, -1.0)
    zenith = min(zenith, 91.0)
    return 1.0 / (math.cos(math.radians(min(zenith, 90.0))) + 0.50572 * (96.07995 - zenith) ** -1.6364)


def zenith_optical_depth(altitude_m: float, turbidity: float) -> np.ndarray:
    alt = max(altitude_m, 0.0)
    return RAYLEIGH_TAU * math.exp(-alt / RAYLEIGH_SCALE_HEIGHT) + AEROSOL_TAU_PER_TURBIDITY * max(
        turbidity - 1.0, 0.0
    ) * math.exp(-alt / AEROSOL_SCALE_HEIGHT)


def sun_transmittance(elevation_deg: float, altitude_m: float, turbidity: float) -> np.ndarray:
    """RGB transmittance of the direct sun; the disk sets smoothly over its own diameter."""
    tau = zenith_optical_depth(altitude_m, turbidity) * air_mass(elevation_deg)
    visible = np.clip((elevation_deg + 0.27) / 0.54, 0.0, 1.0)
    return np.exp(-np.minimum(tau, 80.0)) * visible


STARLIGHT_AIRGLOW_LUX = 7.0e-4  # lux, clear moonless night sky background (pi x ~2.1e-4 cd/m^2)


def diffuse_illuminance(elevation_deg: float, altitude_m: float = 0.0) -> float:
    """Clear-sky diffuse horizontal illuminance (lux); thinner above the troposphere."""
    log_e = np.interp(elevation_deg, _DIFFUSE_ELEV, np.log(_DIFFUSE_LUX))
    return float(math.exp(log_e) * math.exp(-max(altitude_m, 0.0) / 12_000.0))


def _normalise(rgb) -> np.ndarray:
    rgb = np.asarray(rgb, dtype=np.float64)
    return rgb / (LUMA[0] * rgb[0] + LUMA[1] * rgb[1] + LUMA[2] * rgb[2])


@dataclass(frozen=True)
class Daylight:
    sun_illuminance: np.ndarray  # lux RGB, normal to the sun
    sky_ambient: np.ndarray  # cd/m^2 RGB (diffuse horizontal / pi)
    zenith: np.ndarray  # cd/m^2
    horizon: np.ndarray
    below: np.ndarray
    halo: np.ndarray
    halo_exponent: float
    sun_disk_luminance: np.ndarray
    moon_illuminance: np.ndarray
    ev100: float  # automatic exposure

    def exposure(self, ev100: float | None = None) -> float:
        ev = self.ev100 if ev100 is None else ev100
        return 1.0 / (1.2 * 2.0**ev)


def daylight(
    sun_elevation: float,
    altitude_m: float = 0.0,
    turbidity: float = 2.0,
    moon_elevation: float = -90.0,
    moon_phase: float = 0.0,
) -> Daylight:
    transmittance = sun_transmittance(sun_elevation, altitude_m, turbidity)
    sun = SOLAR_ILLUMINANCE_TOA * transmittance
    e_diffuse = diffuse_illuminance(sun_elevation, altitude_m)
    # Sky tint: blue by day, deeper blue in twilight (Chappuis band / ozone), warm horizon at sunset.
    twilight = float(np.clip(-sun_elevation / 12.0, 0.0, 1.0))
    sunset = float(np.clip(1.0 - abs(sun_elevation - 2.0) / 10.0, 0.0, 1.0))
    ambient_tint = _normalise(np.array([0.75, 0.9, 1.2]) * (1 - twilight) + np.array([0.45, 0.65, 1.4]) * twilight)
    sky_ambient = e_diffuse / math.pi * ambient_tint
    mean = e_diffuse / math.pi
    thin = math.exp(-max(altitude_m, 0.0) / 7000.0)  # zenith darkens with altitude, black in space
    zenith = mean * 0.6 * thin * _normalise([0.28, 0.5, 1.0])
    horizon_tint = (1 - sunset) * np.array([0.85, 0.92, 1.0]) + sunset * np.array([1.0, 0.6, 0.35])
    horizon = mean * 1.5 * (0.25 + 0.75 * math.exp(-max(altitude_m, 0.0) / 20_000.0)) * _normalise(horizon_tint)
    below = 0.6 * horizon
    sun_colour = _normalise(transmittance + 1e-9)
    halo_strength = float(np.dot(LUMA, sun)) * 0.02
    halo = halo_strength * sun_colour
    halo_exponent = 60.0 + 340.0 * float(np.clip(sun_elevation / 45.0, 0.0, 1.0))
    sun_disk = sun / SUN_SOLID_ANGLE
    moon_t = sun_transmittance(moon_elevation, altitude_m, turbidity)
    moon = FULL_MOON_ILLUMINANCE * moon_phase * moon_t
    total = float(np.dot(LUMA, sun)) * max(math.sin(math.radians(sun_elevation)), 0.0)
    total += e_diffuse + float(np.dot(LUMA, moon))
    # The sky never goes fully dark: starlight and airglow light a horizontal surface by ~7e-4 lux even
    # where sun, moon and the (vanishing) atmosphere give nothing: a camera in space at night (1e7 m).
    total += STARLIGHT_AIRGLOW_LUX
    ev100 = max(math.log2(total * 100.0 / 250.0), -4.0)
    return Daylight(sun, sky_ambient, zenith, horizon, below, halo, halo_exponent, sun_disk, moon, ev100)
