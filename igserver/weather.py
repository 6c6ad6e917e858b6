"""Weather physics without GL: the one wind, rain and snow (docs/design.md#precipitation).

Everything that moves with the air reads :func:`wind_vector` (smoke drift and the fire's tilt in
render/volumes, rain/snow slant in render/precip, cirrus drift in render/sky; the sea reads
``weather.wind_speed``/``wind_direction`` with the same "from" convention), so one wind drives the
whole picture.

Precipitation, with D the drop diameter in mm and R the rate in mm/h (liquid-water equivalent):

Rain, Marshall & Palmer (1948), "The distribution of raindrops with size", J. Meteor. 5, 165-166:
    N(D) = N0 exp(-Lambda D),   N0 = 8000 m^-3 mm^-1,   Lambda = 4.1 R^-0.21 mm^-1.
Fall speed, Atlas, Srivastava & Sekhon (1973), Rev. Geophys. 11, 1-35 (fit to Gunn & Kinzer 1949):
    v(D) = 9.65 - 10.3 exp(-0.6 D) m/s      (1 mm: 4.0 m/s, 2 mm: 6.5, 5 mm: 9.1).
Snow, Gunn & Marshall (1958), "The distribution with size of aggregate snowflakes", J. Meteor. 15,
452-461, D the melted diameter:
    N(D) = N0 exp(-Lambda D),   N0 = 3800 R^-0.87 m^-3 mm^-1,   Lambda = 2.55 R^-0.48 mm^-1;
beyond their data (2.5 mm/h) N0 grows in proportion to R at the 2.5 mm/h shape. A flake of
bulk density rho_s = 0.05 g/cm^3 (dry aggregates) has a diameter (1/rho_s)^(1/3) = 2.7 times
its melted one. Fall speed, Locatelli & Hobbs (1974), J. Geophys. Res. 79, 2185-2197, aggregates of
unrimed dendrites: v(D_flake) = 0.8 D_flake^0.16 m/s (0.85-1.2 m/s); single flakes scatter about
+-25 % around it (riming, shape), drawn per flake by the particle system.

Extinction: drops and flakes are large against the wavelength, so each removes twice its
geometric cross-section from a beam (extinction efficiency Q = 2, the extinction paradox), and
    beta = Q * pi/4 * integral D^2 N(D) dD = pi N0 / Lambda^3          (times k^2 for flakes)
in mm^2 m^-3 (1e-6 m^-1). Rain: beta = 0.365 R^0.63 km^-1 - within 40 % of the empirical
free-space-optics fit 0.25 R^0.67 km^-1 (1.076 R^0.67 dB/km) and 10 mm/h -> 2.5 km visibility.
Snow: 0.1 mm/h -> 2.7 km, 1 mm/h -> 0.74 km, 5 mm/h -> 0.22 km, the light/moderate/heavy bands
of the visibility-based snowfall intensity scale (Rasmussen et al. 1999, J. Appl. Meteor. 38,
1542-1563, who also show a factor 3-10 scatter between storms). Visibility follows from Koschmieder,
V = 3.912 / beta.
"""

from __future__ import annotations

import math

import numpy as np

from .scene.model import Scene

KOSCHMIEDER = 3.912  # -ln(0.02): contrast threshold 2 %
MIN_VISIBILITY = 50.0  # m, the lowest visibility the atmosphere supports (docs/design.md#atmosphere)

# Drop-size distributions: N0 (m^-3 mm^-1) and Lambda (mm^-1) as functions of R (mm/h).
MP_N0 = 8000.0
MP_LAMBDA, MP_LAMBDA_EXP = 4.1, -0.21
GM_N0, GM_N0_EXP = 3800.0, -0.87
GM_LAMBDA, GM_LAMBDA_EXP = 2.55, -0.48
SNOW_RATE_LIMIT = 2.5  # mm/h: the heaviest snowfalls Gunn & Marshall fitted; beyond, more of the
# same flakes: N0 grows in proportion to R and Lambda stays (their fit alone turns the number of
# visible flakes over near 2.7 mm/h as aggregation makes fewer, bigger flakes)
SNOW_DENSITY = 0.05  # g/cm^3, dry aggregate flakes
FLAKE_OVER_MELTED = (1.0 / SNOW_DENSITY) ** (1.0 / 3.0)  # ~2.71
EXTINCTION_EFFICIENCY = 2.0

# The drawn particles are the drops an observer sees as streaks: rain from 1 mm (4 m/s) to the
# break-up limit ~6 mm; snow from 0.5 mm melted (1.4 mm flakes) to 6 mm melted (16 mm flakes).
VISIBLE_DIAMETER = {"rain": (1.0, 6.0), "snow": (0.5, 6.0)}


def wind_vector(scene: Scene) -> np.ndarray:
    """m/s, ENU (x east, y north, z up): where the air goes. ``weather.wind_direction`` is the
    direction the wind blows FROM (meteorological), so 270 (a westerly) gives +x."""
    w = scene.weather
    return w.wind_speed * np.append(wind_heading(scene), 0.0)


def wind_heading(scene: Scene) -> np.ndarray:
    """Unit 2D vector (east, north) the wind blows TO, defined even in calm air (speed 0)."""
    a = math.radians(scene.weather.wind_direction)
    return -np.array([math.sin(a), math.cos(a)])


def size_distribution(kind: str, rate: float) -> tuple[float, float]:
    """(N0 in m^-3 mm^-1, Lambda in mm^-1) of the exponential distribution for ``rate`` mm/h > 0."""
    if rate <= 0.0:
        raise ValueError("size_distribution needs a positive rate")
    if kind == "rain":
        return MP_N0, MP_LAMBDA * rate**MP_LAMBDA_EXP
    if kind == "snow":
        r = min(rate, SNOW_RATE_LIMIT)
        return GM_N0 * r**GM_N0_EXP * (rate / r), GM_LAMBDA * r**GM_LAMBDA_EXP
    raise ValueError(f"unknown precipitation type {kind!r}")


def fall_speed(kind: str, diameter_mm):
    """Terminal fall speed in still air (m/s) of a raindrop of ``diameter_mm`` (equivalent-sphere
    diameter) or of a snowflake of ``diameter_mm`` (flake diameter). Accepts arrays."""
    d = np.asarray(diameter_mm, dtype=np.float64)
    if kind == "rain":
        v = 9.65 - 10.3 * np.exp(-0.6 * d)
    elif kind == "snow":
        v = 0.8 * np.power(np.maximum(d, 1e-6), 0.16)
    else:
        raise ValueError(f"unknown precipitation type {kind!r}")
    v = np.maximum(v, 0.0)  # the rain fit is negative below 0.12 mm, where drops barely fall
    return float(v) if v.ndim == 0 else v


def visible_number_density(kind: str, rate: float) -> float:
    """Drops (flakes) per m^3 between the visible diameters: N0/Lambda (e^-Lambda D1 - e^-Lambda D2)."""
    if rate <= 0.0 or kind == "none":
        return 0.0
    n0, lam = size_distribution(kind, rate)
    d1, d2 = VISIBLE_DIAMETER[kind]
    return n0 / lam * (math.exp(-lam * d1) - math.exp(-lam * d2))


def precipitation_extinction(kind: str, rate: float) -> float:
    """1/m, extinction of visible light by rain or snow falling at ``rate`` mm/h (0 for none)."""
    if kind == "none" or rate <= 0.0:
        return 0.0
    n0, lam = size_distribution(kind, rate)
    area_scale = FLAKE_OVER_MELTED**2 if kind == "snow" else 1.0
    # Q * pi/4 * integral D^2 N0 exp(-Lambda D) dD = Q * pi/4 * 2 N0 / Lambda^3  (mm^2 m^-3)
    return EXTINCTION_EFFICIENCY * math.pi / 4.0 * 2.0 * n0 / lam**3 * area_scale * 1e-6


def effective_visibility(scene: Scene) -> float:
    """m, the visibility the picture shows: the host's ``atmosphere.visibility`` with the rain/snow
    extinction added (``weather.precipitation.lowers_visibility``, default), or the host's value
    alone when it already includes precipitation (``lowers_visibility = false``). Extinctions add:
    beta = 3.912 / V_air + beta_precip. Never below the atmosphere's 50 m floor."""
    v_air = scene.atmosphere.visibility
    p = scene.weather.precipitation
    if not p.lowers_visibility:
        return v_air
    beta = KOSCHMIEDER / v_air + precipitation_extinction(p.type, p.rate)
    return max(KOSCHMIEDER / beta, MIN_VISIBILITY)


def precipitation_falls(scene: Scene) -> bool:
    p = scene.weather.precipitation
    return p.type != "none" and p.rate > 0.0


__all__ = ["wind_vector", "wind_heading", "fall_speed", "size_distribution", "visible_number_density",
           "precipitation_extinction", "effective_visibility", "precipitation_falls", "KOSCHMIEDER"]
