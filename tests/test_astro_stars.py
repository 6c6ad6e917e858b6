"""Star positions against a textbook reduction written here, independent of PyEphem (which igserver's star code
uses): J2000 catalogue places of bright stars (typed from the Hipparcos/FK5 values, not read from igserver's
catalogue) → precession to the date (Meeus, Astronomical Algorithms, 2nd ed., eq. 21.3–21.4) → Greenwich mean
sidereal time (Meeus 12.4) → hour angle → altitude/azimuth (Meeus 13.5–13.6) → refraction by Bennett's formula
for the apparent altitude (Meeus 16.3), inverted by iteration (igserver lifts with Saemundsson's 16.4).
Checked where igserver's star field puts them and where the rendered star disks land in the picture.

What the reduction leaves out bounds the agreement: annual aberration (<= 20.5"), nutation (<= 17.2" in
longitude, 9.2" in obliquity; the equation of the equinoxes <= 1.2 s of time = 18"), proper motion from 2000
to 2040 (<= 2.3"/yr × 40 yr = 92" for Arcturus, the fastest of these) and UT1 − UTC (<= 0.9 s = 14"): at most
~0.045 deg together. The tolerance is 0.06 deg (a bug in precession, sidereal time, hour-angle sign,
latitude or refraction moves a star by 0.2 deg or more: 40 years of precession is 0.56 deg)."""

from __future__ import annotations

import math
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from igserver.astro import star_field

from helpers import luminance, tiny

POSITION_TOLERANCE_DEG = 0.06  # the omitted effects above sum to <= 0.045 deg


def _hms(h, m, s):
    return math.radians(15.0 * (h + m / 60.0 + s / 3600.0))


def _dms(d, m, s):
    sign = -1.0 if d < 0 or (d == 0 and m < 0) else 1.0
    return math.radians(sign * (abs(d) + m / 60.0 + s / 3600.0))


# ICRS (J2000) right ascension and declination, epoch 2000 (Hipparcos; SIMBAD lists the same to 0.01")
BRIGHT_STARS = {
    "Sirius": (_hms(6, 45, 8.917), _dms(-16, 42, 58.02)),
    "Canopus": (_hms(6, 23, 57.110), _dms(-52, 41, 44.38)),
    "Arcturus": (_hms(14, 15, 39.672), _dms(19, 10, 56.67)),
    "Vega": (_hms(18, 36, 56.336), _dms(38, 47, 1.28)),
    "Capella": (_hms(5, 16, 41.359), _dms(45, 59, 52.77)),
    "Rigel": (_hms(5, 14, 32.272), _dms(-8, 12, 5.90)),
    "Betelgeuse": (_hms(5, 55, 10.305), _dms(7, 24, 25.43)),
    "Altair": (_hms(19, 50, 46.999), _dms(8, 52, 5.96)),
    "Polaris": (_hms(2, 31, 49.09), _dms(89, 15, 50.8)),
    "Deneb": (_hms(20, 41, 25.915), _dms(45, 16, 49.22)),
}


def _julian_day(utc: datetime) -> float:
    return 2440587.5 + utc.timestamp() / 86400.0  # the Unix epoch is JD 2440587.5


def reference_alt_az(name: str, utc: datetime, lat: float, lon: float, refract: bool = True) -> tuple[float, float]:
    """Apparent (or with ``refract=False`` geometric) altitude and azimuth (degrees, azimuth clockwise from
    north) by the textbook reduction."""
    ra0, dec0 = BRIGHT_STARS[name]
    jd = _julian_day(utc)
    t = (jd - 2451545.0) / 36525.0
    arcsec = math.pi / (180.0 * 3600.0)
    zeta = (2306.2181 * t + 0.30188 * t * t + 0.017998 * t ** 3) * arcsec
    z = (2306.2181 * t + 1.09468 * t * t + 0.018203 * t ** 3) * arcsec
    theta = (2004.3109 * t - 0.42665 * t * t - 0.041833 * t ** 3) * arcsec
    a = math.cos(dec0) * math.sin(ra0 + zeta)
    b = math.cos(theta) * math.cos(dec0) * math.cos(ra0 + zeta) - math.sin(theta) * math.sin(dec0)
    c = math.sin(theta) * math.cos(dec0) * math.cos(ra0 + zeta) + math.cos(theta) * math.sin(dec0)
    ra, dec = math.atan2(a, b) + z, math.asin(c)
    gmst = (280.46061837 + 360.98564736629 * (jd - 2451545.0) + 0.000387933 * t * t - t ** 3 / 38710000.0)
    hour_angle = math.radians(gmst + lon) - ra
    phi = math.radians(lat)
    altitude = math.degrees(math.asin(math.sin(phi) * math.sin(dec)
                                      + math.cos(phi) * math.cos(dec) * math.cos(hour_angle)))
    azimuth_from_south = math.atan2(math.sin(hour_angle),
                                    math.cos(hour_angle) * math.sin(phi) - math.tan(dec) * math.cos(phi))
    azimuth = (math.degrees(azimuth_from_south) + 180.0) % 360.0
    # Bennett: R = cot(h_a + 7.31/(h_a + 4.4)) arcmin for the apparent altitude h_a; solve h_a - R(h_a) = h
    if not refract:
        return altitude, azimuth
    apparent = altitude
    for _ in range(20):
        apparent = altitude + 1.0 / math.tan(math.radians(apparent + 7.31 / (apparent + 4.4))) / 60.0
    return apparent, azimuth


def _enu(alt: float, az: float) -> np.ndarray:
    e, a = math.radians(alt), math.radians(az)
    return np.array([math.cos(e) * math.sin(a), math.cos(e) * math.cos(a), math.sin(e)])


def _separation_deg(u: np.ndarray, v: np.ndarray) -> float:
    return math.degrees(math.atan2(np.linalg.norm(np.cross(u, v)), float(np.dot(u, v))))


# (UTC, lat, lon): whole ten seconds (star_field recomputes every 10 s); J2000 itself (no precession), two
# dates of this era and one 40 years on (0.56 deg of precession); both hemispheres, east and west longitudes
CASES = [
    (datetime(2000, 1, 1, 12, 0, 0, tzinfo=timezone.utc), 0.0, 0.0),
    (datetime(2026, 1, 15, 22, 0, 0, tzinfo=timezone.utc), 59.93, 30.31),
    (datetime(2026, 7, 4, 6, 17, 40, tzinfo=timezone.utc), 40.015, -105.27),
    (datetime(2040, 10, 10, 11, 30, 0, tzinfo=timezone.utc), -33.87, 151.21),
    (datetime(2040, 3, 1, 20, 5, 10, tzinfo=timezone.utc), 78.22, 15.65),
]


@pytest.mark.parametrize("utc,lat,lon", CASES)
def test_star_field_matches_the_textbook_reduction(utc, lat, lon):
    stars = star_field(utc, lat, lon)
    compared = 0
    for name in BRIGHT_STARS:
        alt, az = reference_alt_az(name, utc, lat, lon)
        if alt < 1.0:  # below the horizon igserver applies no refraction; near it both formulas part by > 0.01
            continue
        got = stars.directions[stars.names.index(name)]
        error = _separation_deg(got, _enu(alt, az))
        assert error < POSITION_TOLERANCE_DEG, (name, utc, lat, lon, alt, az, error)
        compared += 1
    assert compared >= 3  # each case has stars well above the horizon to compare


def test_stars_below_the_horizon_are_placed_without_refraction():
    """Geometry alone below the horizon (-0.83 deg and lower: refraction is not defined for a star that is
    not seen); the textbook altitude without Bennett's lift, same tolerance."""
    utc, lat, lon = CASES[1]
    stars = star_field(utc, lat, lon)
    below = 0
    for name in BRIGHT_STARS:
        geometric, az = reference_alt_az(name, utc, lat, lon, refract=False)
        if geometric > -2.0:
            continue
        got = stars.directions[stars.names.index(name)]
        assert _separation_deg(got, _enu(geometric, az)) < POSITION_TOLERANCE_DEG, name
        below += 1
    assert below >= 2  # Canopus (dec -52.7) never rises at 59.9 N; Altair and Vega are low in the north-west


def test_stars_move_every_ten_seconds_at_the_sidereal_rate():
    """star_field holds a field for 10 s (the documented cache step): equal within a step, and across one
    step the sky turns by 10 sidereal seconds (360.9856 deg/day × 10 s = 0.04178 deg) about the celestial
    pole, which moves a star on the celestial equator by that angle (Rigel, dec -8.2: × cos dec)."""
    utc, lat, lon = CASES[1]
    a = star_field(utc, lat, lon)
    b = star_field(utc + timedelta(seconds=9.9), lat, lon)
    c = star_field(utc + timedelta(seconds=10.0), lat, lon)
    i = a.names.index("Rigel")
    assert np.array_equal(a.directions[i], b.directions[i])
    moved = _separation_deg(a.directions[i], c.directions[i])
    expected = 360.98564736629 * 10.0 / 86400.0 * math.cos(BRIGHT_STARS["Rigel"][1])
    # 2 % covers the refraction's change over the step (Rigel at ~20 deg: 0.045 deg lift changing by ~1e-4)
    assert abs(moved - expected) < 0.02 * expected, (moved, expected)


def _pinhole_pixel(direction: np.ndarray, heading: float, pitch: float, fov_y: float, size: int):
    """Where a direction lands in a square pinhole camera (x right, y down, pixel units), written here
    from the camera angles: heading clockwise from north, pitch up, no roll."""
    h, p = math.radians(heading), math.radians(pitch)
    forward = np.array([math.cos(p) * math.sin(h), math.cos(p) * math.cos(h), math.sin(p)])
    right = np.array([math.cos(h), -math.sin(h), 0.0])
    up = np.cross(right, forward)
    scale = math.tan(math.radians(fov_y) / 2.0)
    x = float(direction @ right) / float(direction @ forward) / scale
    y = float(direction @ up) / float(direction @ forward) / scale
    return np.array([(x * 0.5 + 0.5) * size, (1.0 - (y * 0.5 + 0.5)) * size])


@pytest.mark.parametrize("name,utc,lat,lon", [
    ("Sirius", datetime(2026, 1, 15, 22, 0, 0, tzinfo=timezone.utc), 59.93, 30.31),
    ("Vega", datetime(2026, 7, 4, 6, 17, 40, tzinfo=timezone.utc), 40.015, -105.27),
])
def test_rendered_star_lands_where_the_textbook_puts_it(renderer, name, utc, lat, lon):
    """The brightest star in a 10-degree view: its rendered disk (2 px points) is centred where the textbook
    direction projects. At 128 px per 10 deg a pixel is 0.078 deg; the position tolerance (0.06 deg = 0.77
    px) plus the point's rasterisation (a 2 px point covers the 2x2 pixels around its centre: centroid
    within 0.5 px) gives 1.3 px."""
    alt, az = reference_alt_az(name, utc, lat, lon)
    heading, pitch, fov, size = az - 2.0, alt - 1.5, 10.0, 128
    scene = tiny({"ground": {"enabled": False}, "time": {"utc": utc.isoformat().replace("+00:00", "Z")},
                  "location": {"lat": lat, "lon": lon},
                  "camera": {"heading": heading, "pitch": pitch, "fov_y": fov, "exposure_ev": -2}}, size, size)
    renderer.render(scene)
    lum = luminance(renderer.read_hdr())
    expect = _pinhole_pixel(_enu(alt, az), heading, pitch, fov, size)
    assert 0 < expect[0] < size and 0 < expect[1] < size
    y, x = np.unravel_index(np.argmax(lum), lum.shape)
    window = lum[y - 3:y + 4, x - 3:x + 4]
    background = np.median(lum)
    assert lum[y, x] > 100 * background, "no star stands out of the sky"  # a star, not a sky gradient
    weights = np.clip(window - background, 0.0, None)
    yy, xx = np.mgrid[y - 3:y + 4, x - 3:x + 4]
    found = np.array([(weights * (xx + 0.5)).sum(), (weights * (yy + 0.5)).sum()]) / weights.sum()
    assert np.all(np.abs(found - expect) <= 1.3), (name, expect, found)


def test_refraction_lift_matches_bennett_and_stops_below_the_horizon():
    """igserver lifts a star by Saemundsson's formula (true → apparent); Bennett's (apparent → true,
    Meeus 16.3) inverted here agrees with it to 0.07' from the horizon to the zenith (measured 0.06' at
    10°): bound 0.1'. A star lower than −0.83° is not lifted (no refraction is defined for it)."""
    from igserver.astro.stars import _refraction_deg

    for true_alt in (0.0, 0.3, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 45.0, 80.0):
        apparent = true_alt
        for _ in range(30):
            apparent = true_alt + 1.0 / math.tan(math.radians(apparent + 7.31 / (apparent + 4.4))) / 60.0
        lift_arcmin = float(_refraction_deg(np.array(true_alt))) * 60.0
        assert abs(lift_arcmin - (apparent - true_alt) * 60.0) < 0.1, (true_alt, lift_arcmin)
    assert float(_refraction_deg(np.array(-0.82))) > 0.5  # still lifted just above the limit (~35')
    assert float(_refraction_deg(np.array(-0.84))) == 0.0 and float(_refraction_deg(np.array(-1.5))) == 0.0
