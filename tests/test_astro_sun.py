"""Sun position against NREL SPA (pvlib, test-only dependency): apparent elevation and azimuth
within 0.01 deg at many dates and places, refraction included with the same pressure/temperature."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pandas as pd
import pytest

pvlib = pytest.importorskip("pvlib")

from igserver.astro import celestial_state, star_field  # noqa: E402
from igserver.astro.ephemeris import PRESSURE_HPA, TEMPERATURE_C, sun_position  # noqa: E402

PLACES = [(59.93, 30.31, 0.0), (0.0, 0.0, 0.0), (-33.9, 18.4, 50.0), (40.0, -105.2, 1650.0),
          (78.2, 15.6, 0.0), (-77.8, 166.7, 10.0), (35.7, 139.7, 40.0), (21.3, -157.9, 0.0)]


def _times(n: int, seed: int) -> list[datetime]:
    rng = np.random.default_rng(seed)
    start = datetime(2000, 1, 1, tzinfo=timezone.utc)
    return [start + timedelta(seconds=float(s)) for s in rng.uniform(0, 40 * 365.25 * 86400, n)]


@pytest.mark.parametrize("lat,lon,alt", PLACES)
def test_sun_matches_spa(lat, lon, alt):
    times = _times(40, int(abs(lat * 100 + lon)))
    spa = pvlib.solarposition.spa_python(pd.DatetimeIndex(times), lat, lon, altitude=alt,
                                         pressure=PRESSURE_HPA * 100.0, temperature=TEMPERATURE_C,
                                         delta_t=None)
    for t, (_, row) in zip(times, spa.iterrows()):
        el, az = sun_position(t, lat, lon, alt)
        if row["apparent_elevation"] < -1.0:
            # SPA applies no refraction below the horizon either; compare the geometry only.
            assert abs(el - row["elevation"]) < 0.01
        else:
            assert abs(el - row["apparent_elevation"]) < 0.01, (t, lat, lon, el, row["apparent_elevation"])
        daz = (az - row["azimuth"] + 180.0) % 360.0 - 180.0
        if row["elevation"] < 89.5:  # azimuth is undefined at the zenith
            assert abs(daz) < 0.01, (t, lat, lon, az, row["azimuth"])


def test_sun_near_horizon_refraction():
    # Sunrise/sunset instants have the largest refraction (~0.5 deg): sample around them.
    lat, lon = 59.93, 30.31
    t0 = datetime(2026, 3, 20, 3, 0, tzinfo=timezone.utc)
    times = [t0 + timedelta(minutes=2 * i) for i in range(90)]
    spa = pvlib.solarposition.spa_python(pd.DatetimeIndex(times), lat, lon, pressure=PRESSURE_HPA * 100.0,
                                         temperature=TEMPERATURE_C, delta_t=None)
    near = 0
    for t, (_, row) in zip(times, spa.iterrows()):
        if -0.8 < row["apparent_elevation"] < 5.0:
            near += 1
            assert abs(sun_position(t, lat, lon)[0] - row["apparent_elevation"]) < 0.01
    assert near > 5


def test_celestial_state_and_stars():
    t = datetime(2026, 1, 15, 22, 0, tzinfo=timezone.utc)
    s = celestial_state(t, 59.93, 30.31)
    assert -90 <= s.sun_elevation <= 90 and 0 <= s.moon_phase <= 1
    stars = star_field(t, 59.93, 30.31)
    assert len(stars.names) > 5000  # the naked-eye sky to V = 6.5 (Hipparcos), not only 116 bright stars
    assert np.allclose(np.linalg.norm(stars.directions, axis=1), 1.0)
    sirius = stars.illuminance[stars.names.index("Sirius")]
    assert 8e-6 < sirius < 1.2e-5  # magnitude -1.46: 2.54e-6 * 10^0.584
