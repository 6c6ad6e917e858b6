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


def _observer(utc: datetime, lat: float, lon: float, altitude: float) -> ephem.Observer:
    obs = ephem.Observer()
    obs.lat, obs.lon = str(lat), str(lon)
    obs.elevation = altitude
    obs.date = ephem.Date(utc.replace(tzinfo=None))
    obs.pressure = 1010.0  # mbar: turns on refraction near the horizon
    obs.temp = 10.0  # degC
    return obs


def celestial_state(utc: datetime, lat: float, lon: float, altitude: float = 0.0) -> CelestialState:
    obs = _observer(utc, lat, lon, altitude)
    sun, moon = ephem.Sun(obs), ephem.Moon(obs)
    return CelestialState(
        sun_elevation=math.degrees(float(sun.alt)),
        sun_azimuth=math.degrees(float(sun.az)),
        moon_elevation=math.degrees(float(moon.alt)),
        moon_azimuth=math.degrees(float(moon.az)),
        moon_phase=float(moon.moon_phase),
    )
