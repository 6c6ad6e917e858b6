"""Sky geometry from the ephemeris, checked by geometry alone: the ENU direction convention, the moon
opposite the sun at a lunar eclipse, refraction lifting the horizon sun by about half a degree."""

from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np
import pytest

from igserver.astro import celestial_state
from igserver.astro.ephemeris import direction_enu, refraction_deg


@pytest.mark.parametrize("elevation, azimuth, expect", [
    (0.0, 0.0, (0.0, 1.0, 0.0)),     # north
    (0.0, 90.0, (1.0, 0.0, 0.0)),    # east: azimuth clockwise from north
    (0.0, 180.0, (0.0, -1.0, 0.0)),
    (90.0, 123.0, (0.0, 0.0, 1.0)),  # the zenith
    (-30.0, 270.0, (-math.cos(math.radians(30.0)), 0.0, -0.5)),
])
def test_direction_convention(elevation, azimuth, expect):
    assert direction_enu(elevation, azimuth) == pytest.approx(expect, abs=1e-12)


def test_moon_is_opposite_the_sun_at_a_lunar_eclipse():
    """Total lunar eclipse of 2025-03-14, greatest at 06:58:43 UTC: the moon stands in the earth's shadow,
    within its umbra's ~0.7 deg radius of the antisolar point (refraction near the horizon adds < 1 deg)."""
    state = celestial_state(datetime(2025, 3, 14, 6, 58, 43, tzinfo=timezone.utc), 40.0, -100.0)
    sun = np.array(direction_enu(state.sun_elevation, state.sun_azimuth))
    moon = np.array(direction_enu(state.moon_elevation, state.moon_azimuth))
    separation = math.degrees(math.acos(float(np.clip(sun @ moon, -1.0, 1.0))))
    assert separation > 178.0, separation


def test_refraction_lifts_the_horizon_by_half_a_degree():
    """Standard refraction at the horizon is ~34 arcmin (0.57 deg) at 1010 hPa and 10 C, ~5 arcmin at 10 deg
    elevation; denser (colder, higher-pressure) air refracts more; nothing below the sun's disk set."""
    assert 0.45 < refraction_deg(0.0) < 0.65
    assert 0.07 < refraction_deg(10.0) < 0.1
    assert refraction_deg(0.0, 1030.0, -20.0) > refraction_deg(0.0, 1010.0, 10.0) > refraction_deg(0.0, 990.0, 30.0)
    assert refraction_deg(-5.0) == 0.0
