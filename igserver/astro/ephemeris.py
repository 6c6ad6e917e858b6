"""Positions of the sun and moon for a scene, from PyEphem (a well-kept VSOP87/ELP ephemeris).

Angles come back in degrees: elevation above the horizon (with standard atmospheric refraction
included by PyEphem through ``pressure``/``temp``), azimuth clockwise from north.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime

import ephem


@dataclass(frozen=True)
class CelestialState:
    sun_elevation: float  # deg, apparent (refracted)
    sun_azimuth: float  # deg clockwise from north
    moon_elevation: float  # deg
    moon_azimuth: float  # deg
    moon_phase: float  # illuminated fraction 0..1


def direction_enu(elevation_deg: float, azimuth_deg: float) -> tuple[float, float, float]:
    """Unit vector (x east, y north, z up) toward a body at the given elevation/azimuth."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return (math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el))


PRESSURE_HPA = 1010.0
TEMPERATURE_C = 10.0


def _observer(utc: datetime, lat: float, lon: float, altitude: float) -> ephem.Observer:
    obs = ephem.Observer()
    obs.lat, obs.lon = str(lat), str(lon)
    obs.elevation = altitude
    obs.date = ephem.Date(utc.replace(tzinfo=None))
    obs.pressure = PRESSURE_HPA  # mbar: turns on PyEphem's refraction (used for the moon)
    obs.temp = TEMPERATURE_C  # degC
    return obs


def refraction_deg(true_elevation_deg: float, pressure_hpa: float = PRESSURE_HPA,
                   temperature_c: float = TEMPERATURE_C) -> float:
    """Atmospheric refraction (deg) of NREL SPA (Reda & Andreas 2004, eq. 42; Bennett 1982):
        R = P/1010 * 283/(273 + T) * 1.02 / (60 tan(e0 + 10.3 / (e0 + 5.11)))   [deg, e0 in deg]
    applied while the body's upper limb is above the horizon, e0 >= -(0.26667 + 0.5667) deg."""
    e0 = true_elevation_deg
    if e0 < -(0.26667 + 0.5667):
        return 0.0
    return (pressure_hpa / 1010.0) * (283.0 / (273.0 + temperature_c)) * 1.02 / (
        60.0 * math.tan(math.radians(e0 + 10.3 / (e0 + 5.11))))


def sun_position(utc: datetime, lat: float, lon: float, altitude: float = 0.0,
                 pressure_hpa: float = PRESSURE_HPA, temperature_c: float = TEMPERATURE_C) -> tuple[float, float]:
    """Apparent (refracted) topocentric elevation and azimuth of the sun, deg.

    PyEphem gives the true topocentric position (pressure 0 turns its own refraction off); the
    refraction is SPA's, so the result agrees with NREL SPA (tested against pvlib within 0.01 deg).
    """
    obs = _observer(utc, lat, lon, altitude)
    obs.pressure = 0.0
    sun = ephem.Sun(obs)
    true_el = math.degrees(float(sun.alt))
    return true_el + refraction_deg(true_el, pressure_hpa, temperature_c), math.degrees(float(sun.az))


def celestial_state(utc: datetime, lat: float, lon: float, altitude: float = 0.0) -> CelestialState:
    obs = _observer(utc, lat, lon, altitude)
    moon = ephem.Moon(obs)
    sun_el, sun_az = sun_position(utc, lat, lon, altitude)
    return CelestialState(
        sun_elevation=sun_el,
        sun_azimuth=sun_az,
        moon_elevation=math.degrees(float(moon.alt)),
        moon_azimuth=math.degrees(float(moon.az)),
        moon_phase=float(moon.moon_phase),
    )
