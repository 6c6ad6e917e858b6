"""The sea's wave maths against references written here (igserver/water): the dispersion solve to float64
round-off as its docstring promises, the group velocity as dω/dk of the dispersion relation, and more
below per module. GL-free and fast: they are part of the mutation run's selection (scripts/mutation.sh)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.water.dispersion import G, group_velocity, solve_kh, wavenumber


def _bisect_kh(x: np.ndarray) -> np.ndarray:
    """y tanh y = x by 200 float64 bisection steps: the interval shrinks below one ulp of y."""
    lo, hi = np.zeros_like(x), np.maximum(np.sqrt(x), x) + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        below = mid * np.tanh(mid) < x
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def test_dispersion_solve_reaches_float64_round_off():
    """'Newton then converges quadratically, three steps give float64 round-off' (dispersion.py), over
    x = 1e-12 … 1e7. Bisection stops at a few ulps of y (the bracket halves until neighbouring floats);
    y tanh y near x is then flat to ~4 ulps: 1e-14 relative is over ten times that and a Newton step with a
    wrong derivative (linear convergence from the 1.5 % start) stays above 1e-9 after four steps."""
    x = np.geomspace(1e-12, 1e7, 4000)
    rel = np.abs(solve_kh(x) - _bisect_kh(x)) / _bisect_kh(x)
    assert rel.max() < 1e-14, (rel.max(), x[np.argmax(rel)])
    assert solve_kh(0.0) == 0.0


def test_float32_inputs_are_solved_in_float64():
    """Callers may hand float32 arrays (GPU readbacks, msgpack float32): the maths is float64 throughout, so
    the result equals the float64 one for the same (float32-representable) inputs."""
    x32 = np.geomspace(1e-6, 1e3, 200).astype(np.float32)
    assert np.array_equal(solve_kh(x32), solve_kh(x32.astype(np.float64)))
    omega32, depth32 = np.geomspace(0.05, 20.0, 50).astype(np.float32), np.float32(7.3)
    k = wavenumber(omega32, depth32)
    assert k.dtype == np.float64 and np.array_equal(k, wavenumber(omega32.astype(np.float64), float(depth32)))
    cg = group_velocity(omega32, k.astype(np.float32), depth32)
    assert cg.dtype == np.float64
    assert np.array_equal(cg, group_velocity(omega32.astype(np.float64), k.astype(np.float32).astype(np.float64), float(depth32)))


@pytest.mark.parametrize("depth", [0.5, 3.0, 20.0, 200.0, math.inf])
def test_group_velocity_is_domega_dk(depth):
    """c_g = dω/dk of ω(k) = √(g k tanh(k h)), by central differences (step 1e-5 k: truncation ~1e-10,
    round-off ~1e-11; bound 1e-8)."""
    omega = np.geomspace(0.05, 30.0, 60)
    k = wavenumber(omega, depth)

    def omega_of(kk):
        return np.sqrt(G * kk * (np.tanh(kk * depth) if math.isfinite(depth) else 1.0))

    dk = 1e-5 * k
    expected = (omega_of(k + dk) - omega_of(k - dk)) / (2 * dk)
    assert np.allclose(group_velocity(omega, k, depth), expected, rtol=1e-8, atol=0)


def test_group_velocity_limits():
    """Shallow water: c_g → √(g h) (non-dispersive) up to the (kh)² terms; deep: c_g = c/2 = g/(2ω)."""
    h, omega = 0.01, 0.05
    k = wavenumber(omega, h)
    assert k * h < 2e-3
    assert group_velocity(omega, k, h) == pytest.approx(math.sqrt(G * h), rel=(k * h) ** 2)
    assert group_velocity(3.0, wavenumber(3.0, math.inf), math.inf) == pytest.approx(G / 6.0, rel=1e-14)


# --------------------------------------------------------------------------- spectrum (water/spectrum.py)

from igserver.water.spectrum import (  # noqa: E402
    SPREADING_S, SWELL_SPREADING_S, beaufort_hs, calibrate_detail, jonswap, mean_square_slope, peak_omega,
    sea_spectrum, wave_bands, wind_for_hs,
)


def test_jonswap_is_pierson_moskowitz_times_the_peak_enhancement():
    """Hasselmann et al. (1973): S = S_PM · γ^r, r = exp(−(ω−ω_p)²/(2σ²ω_p²)), γ = 3.3, σ = 0.07 below the
    peak and 0.09 above; S_PM ∝ ω⁻⁵ exp(−5/4 (ω_p/ω)⁴) peaks at ω_p. Ratios only (the shape is unnormalised)."""
    wp = 0.8
    w = np.array([0.5, wp * (1 - 0.07), wp, wp * (1 + 0.09), 1.6, 3.0])
    pm = w ** -5.0 * np.exp(-1.25 * (wp / w) ** 4)
    enhancement = jonswap(w, wp) / pm
    assert enhancement[2] == pytest.approx(3.3, rel=1e-12)
    assert enhancement[1] == pytest.approx(3.3 ** math.exp(-0.5), rel=1e-12)  # one σ below: σ = 0.07
    assert enhancement[3] == pytest.approx(3.3 ** math.exp(-0.5), rel=1e-12)  # one σ above: σ = 0.09
    assert enhancement[-1] == pytest.approx(1.0, abs=1e-12)  # far from the peak: Pierson–Moskowitz
    grid = np.linspace(0.5 * wp, 2 * wp, 30001)
    assert grid[np.argmax(jonswap(grid, wp))] == pytest.approx(wp, abs=2 * (grid[1] - grid[0]))


def test_beaufort_heights_and_their_inverse():
    """WMO-No. 558 probable heights at the class mid-winds (Bf 4: 5.5–7.9 m/s → 1.0 m; Bf 8: 17.2–20.7 →
    5.5 m; Bf 12 starts at 32.7: 14 m); past Bf 12 U² growth capped by the fully developed
    Pierson–Moskowitz sea 0.21 (1.075 U)²/g (both grow as U², 0.0131 U² < 0.0248 U²: the cap never
    binds); wind_for_hs inverts it."""
    assert beaufort_hs(6.7) == pytest.approx(1.0) and beaufort_hs(18.95) == pytest.approx(5.5)
    assert beaufort_hs(32.7) == pytest.approx(14.0)
    for wind in (36.0, 60.0):  # U² from Bf 12 on, below the fully developed sea (both grow as U²)
        assert beaufort_hs(wind) == pytest.approx(14.0 * (wind / 32.7) ** 2)
        assert beaufort_hs(wind) < 0.21 * (1.075 * wind) ** 2 / G
    for hs in (0.05, 0.4, 1.0, 3.7, 9.0, 14.0, 17.5):
        assert beaufort_hs(wind_for_hs(hs)) == pytest.approx(hs, rel=1e-12), hs


def test_peak_frequency_from_the_fetch_laws():
    """JONSWAP fetch laws (g Hs/U² = 1.6e-3 χ^½, U f_p/g = 3.5 χ^−0.33) written here: a young sea (Hs well
    below full development) peaks higher than the Pierson–Moskowitz ω_p = 0.855 g/U, which bounds it below."""
    for wind, hs in ((10.0, 0.8), (15.0, 2.0), (20.0, 3.0)):
        chi = (G * hs / wind ** 2 / 1.6e-3) ** 2
        fetch_limited = 2 * math.pi * 3.5 * G / wind * chi ** -0.33
        assert fetch_limited > 0.855 * G / wind
        assert peak_omega(hs, wind) == pytest.approx(fetch_limited, rel=1e-12)
    assert peak_omega(20.0, 10.0) == pytest.approx(0.855 * G / 10.0)  # an old sea: the PM peak
    assert peak_omega(0.0, 0.0) == pytest.approx(0.855 * G / 1.0)  # no sea: the 1 m/s shape


@pytest.mark.parametrize("s,swell", [(SPREADING_S, False), (SWELL_SPREADING_S, True)])
def test_directional_spreading_has_the_cos2s_mean_resultant(s, swell):
    """D(θ) ∝ cos^{2s}(θ/2) has mean resultant length E[cos θ] = s/(s+1) (Longuet-Higgins et al. 1963):
    0.909 for the wind sea (s = 10), 0.984 for swell (s = 60). The waves' directions are equal-weight
    quantile samples (golden-ratio quantiles): 200 of them estimate it to ~0.5 % (bound 1 %); with s
    doubled or halved it moves by 4 % or more."""
    spectrum = sea_spectrum(12.0, 90.0, None)  # waves run to 270 deg (west)
    if swell:
        mesh, _ = wave_bands(spectrum, 203, 0, swell_hs=2.0, swell_from=0.0, n_swell=200)  # swell runs south
        direction, to = mesh.direction[:200], 180.0
    else:
        mesh, _ = wave_bands(spectrum, 200, 0)
        direction, to = mesh.direction, 270.0
    mean_direction = np.array([math.sin(math.radians(to)), math.cos(math.radians(to))])
    assert float(np.mean(direction @ mean_direction)) == pytest.approx(s / (s + 1.0), rel=0.01)


def test_slopes_match_cox_munk_after_calibration():
    """Cox & Munk (1954), clean surface: total mean-square slope 0.003 + 5.12e-3 U (U at 12.5 m): mesh
    plus calibrated detail band reach it (1e-12: a scale factor, exact up to round-off)."""
    for wind in (3.0, 8.0, 15.0):
        mesh, detail = wave_bands(sea_spectrum(wind, 0.0, None), 64, 64)
        total = mean_square_slope(mesh) + mean_square_slope(calibrate_detail(mesh, detail, wind))
        assert total == pytest.approx(0.003 + 5.12e-3 * wind, rel=1e-12), wind
