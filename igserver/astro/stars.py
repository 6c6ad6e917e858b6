"""Bright stars from PyEphem's catalogue (116 navigation stars, magnitude <= ~3), placed for a
time and place: apparent elevation (refraction included) and azimuth, plus the visual magnitude.

A star's illuminance outside the atmosphere at visual magnitude m (Allen's Astrophysical
Quantities): E = 2.54e-6 lux * 10^(-0.4 m). The sky pass spreads it over the pixel it falls in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timezone
from functools import lru_cache

import ephem
import ephem.stars
import numpy as np

from .ephemeris import _observer, direction_enu

ZERO_MAGNITUDE_LUX = 2.54e-6


@dataclass(frozen=True)
class StarField:
    directions: np.ndarray  # (N, 3) unit ENU vectors toward each star (apparent)
    illuminance: np.ndarray  # (N,) lux outside the atmosphere
    names: tuple[str, ...]


@lru_cache(maxsize=8)
def _star_field(utc_key: float, lat: float, lon: float) -> StarField:
    obs = _observer(datetime.fromtimestamp(utc_key, timezone.utc), lat, lon, 0.0)
    dirs, lux, names = [], [], []
    for name in sorted(ephem.stars.stars):
        body = ephem.star(name, obs)
        dirs.append(direction_enu(math.degrees(float(body.alt)), math.degrees(float(body.az))))
        lux.append(ZERO_MAGNITUDE_LUX * 10.0 ** (-0.4 * float(body.mag)))
        names.append(name)
    return StarField(np.array(dirs), np.array(lux), tuple(names))


def star_field(utc: datetime, lat: float, lon: float) -> StarField:
    """Stars for ``utc``, recomputed at most every 10 s of time (they move 0.04 deg in 10 s)."""
    t = utc.timestamp()
    return _star_field(math.floor(t / 10.0) * 10.0, round(lat, 4), round(lon, 4))
