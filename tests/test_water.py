"""The sea's wave maths (igserver.water): dispersion, WMO calibration, no loops, depth effects,
host queries, long-time determinism. CPU only (float64 numpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.scene.model import Ocean, Weather
from igserver.water import sea_surface
from igserver.water.bathymetry import SURF_LINEAR_HS, depth_at
from igserver.water.dispersion import G, group_velocity, solve_kh, wavenumber
from igserver.water.spectrum import sea_spectrum, wave_bands

# WMO-No. 558 Beaufort table, transcribed independently of the code: (wind range m/s, probable height m).
WMO_BEAUFORT = [((0.0, 0.2), 0.0), ((0.3, 1.5), 0.1), ((1.6, 3.3), 0.2), ((3.4, 5.4), 0.6), ((5.5, 7.9), 1.0),
                ((8.0, 10.7), 2.0), ((10.8, 13.8), 3.0), ((13.9, 17.1), 4.0), ((17.2, 20.7), 5.5),
                ((20.8, 24.4), 7.0), ((24.5, 28.4), 9.0), ((28.5, 32.6), 11.5)]


def reference_kh(x: np.ndarray) -> np.ndarray:
    """y tanh y = x by 200 bisection steps in float64 (independent of Newton and of its start)."""
    lo, hi = np.zeros_like(x), np.maximum(np.sqrt(x), x) + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        below = mid * np.tanh(mid) < x
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def test_dispersion_against_float64_reference():
    x = np.geomspace(1e-6, 1e3, 5000)  # k0 h over the range
    rel = np.abs(solve_kh(x) - reference_kh(x)) / reference_kh(x)
    assert rel.max() <= 1e-5  # the bound
    # Limits: shallow k = ω/√(gh) up to the series term (kh)²/6 ≈ 1.7e-5 at kh = 0.01; deep k = ω²/g.
    assert wavenumber(1.0, 1e-3) == pytest.approx(1.0 / math.sqrt(G * 1e-3) * (1 + 0.0101**2 / 6), rel=1e-6)
    assert wavenumber(1.0, 11_000.0) == pytest.approx(1.0 / G, rel=1e-12)
    # Finite everywhere, including 1 mm and 11 km with any frequency.
    omega, depth = np.meshgrid(np.geomspace(1e-3, 100.0, 50), np.geomspace(1e-3, 11_000.0, 50))
    k = wavenumber(omega, depth)
    cg = group_velocity(omega, k, depth)
    assert np.all(np.isfinite(k)) and np.all(k > 0) and np.all(np.isfinite(cg)) and np.all(cg > 0)


def measured_hs(wind: float, sea_state=None) -> float:
    """4·std of the mesh surface height sampled over 4 km² (what hosts and the mesh see)."""
    sea = sea_surface(Ocean(enabled=True, sea_state=sea_state), Weather(wind_speed=wind))
    xy = np.random.default_rng(5).uniform(-2000.0, 2000.0, (6000, 2))
    return 4.0 * float(np.std(sea.evaluate(xy, 37.0)["position"][:, 2]))


def wmo_probable_height(wind: float) -> float:
    """Linear interpolation between the WMO classes' mid-range winds."""
    mids = [0.5 * (lo + hi) for (lo, hi), _ in WMO_BEAUFORT]
    return float(np.interp(wind, mids, [h for _, h in WMO_BEAUFORT]))


@pytest.mark.parametrize("wind", [3.0, 8.0, 15.0, 25.0])
def test_hs_follows_beaufort_table(wind):
    # ±15 %: the tolerance; sampling 6000 points of 24 random-phase waves adds ~2 %.
    assert measured_hs(wind) == pytest.approx(wmo_probable_height(wind), rel=0.15)


def test_hs_calm_and_hurricane():
    assert measured_hs(0.0) == 0.0  # Beaufort 0: "sea like a mirror" (height 0)
    hs40 = measured_hs(40.0)
    # Beaufort 12: "14 m and over"; never above the Pierson–Moskowitz fully developed sea 0.21 U19.5²/g
    # (U19.5 = 1.026 U10, Stewart 2008).
    assert 14.0 * 0.85 <= hs40 <= 0.21 * (1.026 * 40.0) ** 2 / G


@pytest.mark.parametrize("code,lo,hi", [(2, 0.1, 0.5), (4, 1.25, 2.5), (6, 4.0, 6.0), (8, 9.0, 14.0)])
def test_hs_in_wmo_sea_state_range(code, lo, hi):
    assert lo <= measured_hs(5.0, sea_state=code) <= hi


def test_wave_set_is_deterministic_and_uses_wind_direction():
    a = wave_bands(sea_spectrum(12.0, 270.0, None), 24, 16)[0]
    b = wave_bands(sea_spectrum(12.0, 270.0, None), 24, 16)[0]
    assert np.array_equal(a.phase, b.phase) and np.array_equal(a.direction, b.direction)
    # Wind FROM 270° (west) → waves travel east: energy-weighted mean direction +x.
    mean = np.sum(a.amplitude[:, None] ** 2 * a.direction, axis=0)
    assert mean[0] > 0.9 * np.linalg.norm(mean)


BEACH = {"type": "slope", "depth": 30.0, "slope": 0.03, "shore_distance": 800.0, "shore_heading": 90.0}


@pytest.mark.parametrize("bathymetry", [{"type": "uniform", "depth": 4.0}, BEACH, {"type": "uniform"}])
@pytest.mark.parametrize("wind", [10.0, 30.0])
def test_no_loops_for_steepness_one(bathymetry, wind):
    sea = sea_surface(Ocean(enabled=True, steepness=1.0, bathymetry=bathymetry), Weather(wind_speed=wind))
    xy = np.random.default_rng(2).uniform([-300.0, -300.0], [820.0, 300.0], (20000, 2))
    for t in (0.0, 13.7):
        j = sea.evaluate(xy, t)["jacobian"]
        assert np.all(np.isfinite(j)) and j.min() >= 0.0  # J < 0 would be a loop (surface folding over)


def test_beach_refraction_shoaling_breaking_dry():
    ocean = Ocean(enabled=True, bathymetry=BEACH)
    sea = sea_surface(ocean, Weather(wind_speed=10.0, wind_direction=200.0))  # waves run NNE, oblique
    f = sea.field
    nodes = f.grid.nodes()[:, 0, :]
    h = depth_at(ocean.bathymetry, nodes)
    deep, shallow = np.argmin(np.abs(h - 25.0)), np.argmin(np.abs(h - 1.0))
    # Refraction: the angle between wave vector and shore normal (+x) shrinks toward the shore.
    angle = lambda i: np.degrees(np.abs(np.arctan2(f.kvec[:, i, 0, 1], f.kvec[:, i, 0, 0])))
    main = np.argmax(sea.waves.amplitude)
    assert angle(shallow)[main] < angle(deep)[main] - 5.0
    # Snell: k sin θ (the alongshore wavenumber) is conserved (for waves within 80° of the shore
    # normal offshore; beyond that the caustic guard of the march takes over).
    k_ref = f.kvec[:, deep, 0, :]
    normal_ish = np.abs(k_ref[:, 0]) > 0.2 * np.linalg.norm(k_ref, axis=1)
    assert f.kvec[normal_ish, shallow, 0, 1] == pytest.approx(f.kvec[normal_ish, deep, 0, 1], rel=1e-9)
    # Breaking cap: the linear sea's Hs ≤ SURF_LINEAR_HS·h everywhere wet (the surf zone's Hs = 0.59 h
    # of Thornton & Guza 1983 once the single-wave bound L takes its share); zero on dry land.
    a = sea.waves.amplitude[:, None] * f.factor[:, :, 0]
    hs = 4.0 * np.sqrt(0.5 * np.sum(a**2, axis=0))
    wet = h > 0
    assert np.all(hs[wet] <= SURF_LINEAR_HS * h[wet] * (1 + 1e-9))
    assert np.all(a[:, ~wet] == 0.0)
    assert np.max(hs[wet & (h < 2.0)] / h[wet & (h < 2.0)]) > 0.6  # the cap is reached in the surf zone
    # Steepening toward the shore.
    assert f.steepness[shallow, 0] > f.steepness[deep, 0]


def test_query_inverts_horizontal_displacement():
    sea = sea_surface(Ocean(enabled=True, bathymetry=BEACH), Weather(wind_speed=12.0))
    rest = np.random.default_rng(3).uniform(-400.0, 790.0, (4000, 2))
    e = sea.evaluate(rest, 55.5)
    q = sea.query(e["position"][:, :2], 55.5)
    # The query at a displaced point returns that point's height (Newton inverse, < 1 mm).
    assert np.max(np.abs(q["height"] - e["position"][:, 2])) < 1e-3
    assert np.allclose(q["normal"], e["normal"], atol=1e-4)
    assert np.all(q["normal"][:, 2] > 0)
    # Its speed is a benchmark, not a test: scripts/bench_water_query.py (docs/water.md, Host queries).


def test_velocity_is_time_derivative():
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=9.0))
    rest = np.random.default_rng(4).uniform(-100.0, 100.0, (50, 2))
    dt = 1e-2
    a, b = sea.evaluate(rest, 10.0 - dt)["position"], sea.evaluate(rest, 10.0 + dt)["position"]
    v = sea.evaluate(rest, 10.0)["velocity"]
    # Central difference error ΣAω³dt²/6 ≈ 1e-4 m/s here; float32 trig noise 1e-7·A/dt ≈ 1e-5 m/s.
    assert np.allclose((b - a) / (2 * dt), v, atol=1e-3)


def test_long_time_phases_stay_exact():
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=9.0))
    # Phases reduced in float64: at 1e9 s they equal the exact (ω t mod 2π) to ~1e-6 rad.
    t = 1e9
    exact = np.array([float((np.longdouble(w) * np.longdouble(t)) % np.longdouble(2 * math.pi))
                      for w in sea.waves.omega])
    got = np.mod(sea.waves.phase - sea.phase_offsets(t), 2 * math.pi)
    diff = np.angle(np.exp(1j * (got - exact)))
    assert np.max(np.abs(diff)) < 1e-5
    # Determinism: the same state and time give the same heights, bit for bit.
    xy = np.array([[12.0, -40.0], [1e5, 3e4]])
    assert np.array_equal(sea.query(xy, t)["height"], sea.query(xy, t)["height"])
    # Statistics at 1e9 s are those at 100 s.
    grid = np.random.default_rng(6).uniform(-1000, 1000, (4000, 2))
    s100 = np.std(sea.evaluate(grid, 100.0)["position"][:, 2])
    s1e9 = np.std(sea.evaluate(grid, t)["position"][:, 2])
    assert s1e9 == pytest.approx(s100, rel=0.1)  # 4000 samples: std estimate ±~3 %


def test_height_map_bathymetry_asset():
    bathy = {"type": "map", "map": "island", "map_center": [500.0, 0.0], "map_size": [1500.0, 1500.0],
             "map_heading": 0.0, "map_elevation": [-50.0, 10.0], "depth": 60.0}
    ocean = Ocean(enabled=True, bathymetry=bathy)
    centre = depth_at(ocean.bathymetry, np.array([[500.0 + 0.1 * 750.0, 0.05 * 750.0]]))  # island top
    assert centre[0] < 0  # dry land: the island
    assert depth_at(ocean.bathymetry, np.array([[-2000.0, 0.0]]))[0] == 60.0  # around the map
    sea = sea_surface(ocean, Weather(wind_speed=10.0, wind_direction=270.0))
    q = sea.query(np.array([[575.0, 37.5], [-1000.0, 0.0]]), 10.0)
    assert q["height"][0] == 0.0 and abs(q["height"][1]) > 0.0  # no waves on the island, waves offshore
    j = sea.evaluate(np.random.default_rng(8).uniform(-300.0, 1300.0, (5000, 2)), 3.0)["jacobian"]
    assert j.min() >= 0.0


def test_unknown_bathymetry_asset_is_a_clear_error():
    with pytest.raises(ValueError, match="no_such_map"):
        Ocean(enabled=True, bathymetry={"type": "map", "map": "no_such_map"})
    with pytest.raises(ValueError):
        Ocean(bathymetry={"type": "map"})  # a map needs its asset name
    with pytest.raises(ValueError):
        Ocean(bathymetry={"type": "map", "map": "../etc/passwd"})


def test_eikonal_sweep_keeps_a_plane_wave_exact():
    """Constant k, ψ = k·D·x held on the inflow edges: the Godunov update is exact for a linear ψ
    whose both upwind neighbours are used ((k h cos)² + (k h sin)² = (k h)²), so the sweep must
    return the plane wave everywhere, for directions in all four quadrants. Bound: float64 rounding
    of sums of ≤ 2·60 terms of ≤ 40 rad (≪ 1e-9 rad)."""
    from igserver.water.bathymetry import _eikonal_sweep

    nu, nv, h, k = 61, 47, 2.5, 0.3
    x = np.stack(np.meshgrid(np.arange(nu) * h, np.arange(nv) * h, indexing="ij"), -1)
    for az in (20.0, 110.0, 200.0, 290.0, 0.0):
        d = np.array([math.sin(math.radians(az)), math.cos(math.radians(az))])
        plane = k * (x @ d)
        fixed = np.zeros((nu, nv), bool)
        fixed[0 if d[0] > 0 else -1, :] |= abs(d[0]) > 1e-12
        fixed[:, 0 if d[1] > 0 else -1] |= abs(d[1]) > 1e-12
        psi = _eikonal_sweep(np.where(fixed, np.inf, k)[None], h, np.where(fixed, plane, np.inf)[None], ~fixed)
        assert np.abs(psi[0] - plane).max() < 1e-9


@pytest.mark.parametrize("wind_direction", [70.0, 250.0])
def test_height_map_phase_is_continuous(wind_direction):
    """Over the island map the residual phase R = ψ − k_ref·D·x may not jump between neighbouring
    nodes (a row march, which this replaced, left |ΔR|/Δ up to 324 rad/m against k ≤ 0.32). The converged
    sweep satisfies ψ_i ≤ ψ_j + k_i·Δ for every neighbour j (the Godunov update is at most the one-sided
    value), so |Δψ| ≤ max(k_i, k_j)·Δ and |ΔR| ≤ (max(k_i, k_j) + k_ref)·Δ, dry land (filled at its
    own k) included. Rounding: 1e-9 relative (float64 sums of ≤ 800 steps)."""
    bathy = {"type": "map", "map": "island", "map_center": [500.0, 0.0], "map_size": [1500.0, 1500.0],
             "map_heading": 20.0, "map_elevation": [-50.0, 10.0], "depth": 60.0}
    sea = sea_surface(Ocean(enabled=True, bathymetry=bathy), Weather(wind_speed=12.0, wind_direction=wind_direction))
    f = sea.field
    assert f.grid.du == f.grid.dv
    k = np.hypot(f.kvec[..., 0], f.kvec[..., 1])
    kref = sea.waves.k[:, None, None]
    for axis in (1, 2):
        n = f.residual.shape[axis]
        lo, hi = (slice(None),) * axis + (slice(0, n - 1),), (slice(None),) * axis + (slice(1, n),)
        jump = np.abs(f.residual[hi] - f.residual[lo])
        bound = (np.maximum(k[hi], k[lo]) + kref) * f.grid.du
        assert np.all(jump <= bound * (1 + 1e-9))
    # and over the water (where the field's amplitude lives) that is ~2k: the old march's 27 % of
    # node pairs above 2k is now none (max k of the pair, plus k_ref ≤ k).
    wet = f.depth > 0.0
    pair = wet[:-1] & wet[1:]
    jump = np.abs(np.diff(f.residual, axis=1))[:, pair] / f.grid.du
    assert np.all(jump <= 2.0 * np.maximum(k[:, :-1], k[:, 1:])[:, pair] * (1 + 1e-9))
