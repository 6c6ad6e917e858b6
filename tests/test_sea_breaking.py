"""Depth-limited waves: a breaking limit at every depth and bathymetry, and linear shoaling before it.

References, written here:
- McCowan (1894): a single wave breaks beyond H = 0.78·h (h the still-water depth).
- Thornton & Guza (1983), the saturated surf zone at Torrey Pines: Hrms ≈ 0.42·h, i.e. Hs = Hm0 = √2·Hrms
  ≈ 0.59·h. "Within 20 %" is the issue's tolerance (their data scatter about as much).
- Linear shoaling and refraction over straight parallel contours (any linear-wave text, e.g. Dean &
  Dalrymple 1991 ch. 4): energy flux conserved along rays, H² ∝ 1/(c_g cos θ), with Snell's law
  k sin θ = const; k and c_g from ω² = g k tanh kh, solved here by bisection.

Heights are what a host's query returns at fixed world points (Eulerian), as time series; zero-up-crossing
wave heights from those series."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from igserver.scene.model import Ocean, Weather
from igserver.water import sea_surface

G = 9.80665
MCCOWAN = 0.78
TG_HS = math.sqrt(2.0) * 0.42  # Hs / h of the saturated surf zone (Thornton & Guza 1983)
BEACH_SCENE = Path(__file__).resolve().parents[1] / "igserver" / "scenes" / "sea_beach.toml"


def series(sea, pts: np.ndarray, t_end: float, dt: float) -> np.ndarray:
    """(T, P) heights at world points ``pts`` over [0, t_end)."""
    return np.array([sea.query(pts, t)["height"] for t in np.arange(0.0, t_end, dt)])


def wave_heights(z: np.ndarray) -> np.ndarray:
    """Crest-to-trough heights of the zero-up-crossing waves of each column of z (T, P)."""
    out = []
    for col in z.T:
        up = np.flatnonzero((col[:-1] < 0.0) & (col[1:] >= 0.0))
        out += [np.ptp(col[a:b + 1]) for a, b in zip(up[:-1], up[1:])]
    return np.array(out)


@pytest.mark.parametrize("depth", [2.0, 0.01, 0.001])
def test_uniform_shallow_water_is_a_saturated_surf_zone(depth):
    """9.4 m/s over uniform depth (the deep sea would be Hs 2 m: 2.25 m over 2 m, 8 m over 1 cm and 14 m
    over 1 mm before): single waves ≤ 0.78 h, no trough below −0.39 h (never through the bed), Hs (4σ)
    within 20 % of Thornton & Guza's 0.59 h and the zero-crossing Hrms within 20 % of their 0.42 h."""
    sea = sea_surface(Ocean(enabled=True, bathymetry={"type": "uniform", "depth": depth}), Weather(wind_speed=9.4))
    pts = np.random.default_rng(1).uniform(-200.0, 200.0, (40, 2))
    z = series(sea, pts, 600.0, 0.1)
    assert np.all(np.isfinite(z))
    h = wave_heights(z)
    assert len(h) > 1000
    assert h.max() <= MCCOWAN * depth
    assert z.min() > -0.5 * MCCOWAN * depth
    assert 4.0 * z.std() == pytest.approx(TG_HS * depth, rel=0.20)
    assert math.sqrt(np.mean(h**2)) == pytest.approx(0.42 * depth, rel=0.20)


def test_height_never_grows_as_the_depth_falls():
    """Over uniform depths from 30 m to 1 mm the sea's Hs never exceeds the surf zone's 0.61 h cap on the
    linear sea, and in the surf zone it falls with the depth (it grew as depth fell: 2.25 m at 2 m, 8 m at
    1 cm, 14 m at 1 mm)."""
    from igserver.water.bathymetry import SURF_LINEAR_HS

    last = math.inf
    for depth in (2.0, 1.0, 0.1, 0.01, 0.001):
        sea = sea_surface(Ocean(enabled=True, bathymetry={"type": "uniform", "depth": depth}), Weather(wind_speed=9.4))
        assert sea.waves.hs <= SURF_LINEAR_HS * depth * (1 + 1e-12)
        assert sea.waves.hs < last
        last = sea.waves.hs


def _beach(wind_from: float | None = None) -> tuple:
    scene = tomllib.loads(BEACH_SCENE.read_text())
    if wind_from is not None:  # head-on: wind sea and swell toward the shore (east)
        scene["weather"]["wind_direction"] = wind_from
        scene["ocean"]["swell"]["direction"] = wind_from
    ocean, weather = Ocean(**scene["ocean"]), Weather(**scene["weather"])
    return ocean, sea_surface(ocean, weather)


def _beach_hs(ocean, sea, depth: float) -> float:
    """4σ of the heights along the contour of ``depth`` (200 points over 6 km of shore, 83 instants)."""
    b = ocean.bathymetry
    assert b.type == "slope" and b.shore_heading == 90.0  # shore to the east: depth = slope·(shore − x)
    rng = np.random.default_rng(3)
    x = b.shore_distance - depth / b.slope
    pts = np.column_stack([x + rng.uniform(-0.5, 0.5, 200), rng.uniform(-3000.0, 3000.0, 200)])
    return 4.0 * float(np.std(np.concatenate([sea.query(pts, t)["height"] for t in np.arange(0.0, 600.0, 7.3)])))


def _k(omega: np.ndarray, h: float) -> np.ndarray:
    lo, hi = np.zeros_like(omega), np.full_like(omega, 1e3)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        big = G * mid * np.tanh(mid * h) > omega**2
        lo, hi = np.where(big, lo, mid), np.where(big, mid, hi)
    return 0.5 * (lo + hi)


def _cg(omega: np.ndarray, h: float) -> np.ndarray:
    k = _k(omega, h)
    return 0.5 * omega / k * (1.0 + 2.0 * k * h / np.sinh(2.0 * k * h))


def linear_shoaling(sea, h0: float, h1: float, refraction: bool) -> float:
    """Hs(h1)/Hs(h0) of the sea's waves by energy flux: Σ a_i² c_g(h0)/c_g(h1) [· cos θ(h0)/cos θ(h1)]."""
    w = sea.waves
    e = w.amplitude**2
    ratio = _cg(w.omega, h0) / _cg(w.omega, h1)
    if refraction:  # shore normal +x; Snell: k sin θ conserved
        k0, k1 = _k(w.omega, h0), _k(w.omega, h1)
        sin0 = np.abs(w.direction[:, 1])
        ratio = ratio * np.sqrt(1.0 - sin0**2) / np.sqrt(1.0 - (k0 * sin0 / k1) ** 2)
    return math.sqrt(float(np.sum(e * ratio) / np.sum(e)))


def test_head_on_waves_grow_by_shoaling_before_they_break():
    """sea_beach's sea turned head-on (wind and swell from the west, the shore to the east): from 30 m to 4 m
    the waves grow by linear shoaling (+7.6 % for this spectrum without refraction, +5.9 % with the
    directional spread's refraction): measured within 3 % of the latter (sampling ~1 %, the single-wave
    bound's share at Hs = 0.45 h ~1 %), and more than +3 %. Then the surf zone: Hs within 20 % of 0.59 h
    at 2, 1 and 0.5 m."""
    ocean, sea = _beach(270.0)
    assert linear_shoaling(sea, 30.0, 4.0, refraction=False) == pytest.approx(1.076, abs=0.005)
    expected = linear_shoaling(sea, 30.0, 4.0, refraction=True)
    measured = _beach_hs(ocean, sea, 4.0) / _beach_hs(ocean, sea, 30.0)
    assert measured == pytest.approx(expected, rel=0.03)
    assert measured > 1.03
    for depth in (2.0, 1.0, 0.5):
        assert _beach_hs(ocean, sea, depth) == pytest.approx(TG_HS * depth, rel=0.20)


def test_oblique_beach_sea_shoals_and_refracts():
    """sea_beach as it is (waves 35° off the shore normal): shoaling (+7.6 %) and refraction (the crests
    turn and spread along the shore) nearly cancel, −1.1 % from 30 m to 4 m by linear theory (the
    measured −2 % once read as "no shoaling" is this); measured within 3 %. Surf zone as above."""
    ocean, sea = _beach()
    expected = linear_shoaling(sea, 30.0, 4.0, refraction=True)
    assert expected == pytest.approx(0.989, abs=0.005)
    assert _beach_hs(ocean, sea, 4.0) / _beach_hs(ocean, sea, 30.0) == pytest.approx(expected, rel=0.03)
    for depth in (2.0, 1.0):
        assert _beach_hs(ocean, sea, depth) == pytest.approx(TG_HS * depth, rel=0.20)


def test_single_waves_in_the_beach_surf_zone_stay_below_mccowan():
    """Time series on the 1.5 m contour of sea_beach: every zero-crossing wave ≤ 0.78 h, troughs above the bed."""
    ocean, sea = _beach()
    b = ocean.bathymetry
    depth = 1.5
    pts = np.column_stack([np.full(30, b.shore_distance - depth / b.slope), np.linspace(-1500.0, 1500.0, 30)])
    z = series(sea, pts, 600.0, 0.1)
    h = wave_heights(z)
    assert len(h) > 500 and h.max() <= MCCOWAN * depth * 1.01  # 1 %: the 2 cm cell of the field's grid
    assert z.min() > -depth


@pytest.mark.parametrize("depth", [2.0, 0.001])
def test_height_map_shallows_are_capped(depth):
    """A height-map bathymetry around which the sea is shallow: the cap holds there too (the field's depth
    and the reference depth alike)."""
    bathy = {"type": "map", "map": "island", "map_center": [0.0, 0.0], "map_size": [1500.0, 1500.0],
             "map_elevation": [-50.0, 10.0], "depth": depth}
    sea = sea_surface(Ocean(enabled=True, bathymetry=bathy), Weather(wind_speed=12.0))
    pts = np.random.default_rng(4).uniform(-3000.0, 3000.0, (2000, 2))
    pts = pts[np.max(np.abs(pts), axis=1) > 1000.0]  # outside the map: the surrounding depth
    z = np.concatenate([sea.query(pts, t)["height"] for t in np.arange(0.0, 300.0, 3.1)])
    assert np.all(np.abs(z) < 0.5 * MCCOWAN * depth)
    assert 4.0 * z.std() == pytest.approx(TG_HS * depth, rel=0.20)
