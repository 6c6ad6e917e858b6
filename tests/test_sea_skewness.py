"""Crests sharper than troughs: the sea's height skewness against second-order wave theory.

References: a random sea to second order in steepness has a positive height skewness, λ₃ = 3σk for a narrow
band (Longuet-Higgins 1963; Tayfun 1980) and λ₃ = 3σk_m(1 − ν + ν²) for a spectrum of bandwidth ν
(Tayfun & Fedele 2007); at the steepness of Beaufort 6-9 seas that is 0.1-0.2, as buoys measure. The
Gerstner sum alone has λ₃ ≈ 0 at a fixed place (its group set-down cancels Stokes's sum waves; surface.py).

Heights are what a host's query returns at fixed world points (Eulerian), over 36 km² and three instants;
the statistic's sampling error there is ~0.01-0.02 (24 waves, 60,000 points)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from igserver.scene.model import Ocean, Weather
from igserver.water import sea_surface

G = 9.80665
BEAUFORT_6_TO_9 = [12.3, 15.5, 18.95, 22.6]  # m/s, the classes' mid-range winds (WMO-No. 558)


def heights(sea) -> np.ndarray:
    xy = np.random.default_rng(5).uniform(-3000.0, 3000.0, (20000, 2))
    return np.concatenate([sea.query(xy, t)["height"] for t in (37.0, 411.0, 1303.0)])


def skewness(z: np.ndarray) -> float:
    d = z - z.mean()
    return float(np.mean(d**3) / np.mean(d**2) ** 1.5)


def tayfun_fedele(sea) -> float:
    """λ₃ = 3σk_m(1 − ν + ν²) of the mesh wave set: m_j = Σ ω^j a²/2, ω_m = m₁/m₀, k_m = ω_m²/g,
    ν = √(m₀m₂/m₁² − 1)."""
    w = sea.waves
    e = w.amplitude**2 / 2.0
    m0, m1, m2 = e.sum(), (e * w.omega).sum(), (e * w.omega**2).sum()
    nu = np.sqrt(m0 * m2 / m1**2 - 1.0)
    return float(3.0 * np.sqrt(m0) * (m1 / m0) ** 2 / G * (1.0 - nu + nu**2))


@pytest.mark.parametrize("wind", BEAUFORT_6_TO_9)
def test_beaufort_6_to_9_skewness_is_second_order(wind):
    """Skewness 0.1-0.2 (the issue's range for these steepnesses) and within 25 % of Tayfun & Fedele's
    λ₃ for the same spectrum (the √(k_i k_j) kernel and the directional spread: ~10 %; sampling ~10 %)."""
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=wind))
    lam = skewness(heights(sea))
    assert 0.1 <= lam <= 0.2, lam
    assert lam == pytest.approx(tayfun_fedele(sea), rel=0.25)


def test_gerstner_alone_is_symmetric_and_the_correction_keeps_level_and_height():
    """Without the second-order term (α = 0) the Gerstner sea's skewness is ~0 (|λ₃| < 0.04): the
    behaviour the correction exists for. With it the mean level moves by under 1 % of Hs and Hs by under
    2 % (z₂ is small, zero-mean at the rest points): the WMO calibration holds."""
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=18.95))
    assert sea.second_order > 0.0
    linear = dataclasses.replace(sea, second_order=0.0)
    z2, z1 = heights(sea), heights(linear)
    assert abs(skewness(z1)) < 0.04
    hs = 4.0 * z1.std()
    assert abs(z2.mean() - z1.mean()) < 0.01 * hs
    assert 4.0 * z2.std() == pytest.approx(hs, rel=0.02)


def test_crests_are_higher_than_troughs_are_deep():
    """Zero-up-crossing waves in time series at fixed points, Beaufort 8: among the highest third (the
    significant waves) the mean crest height exceeds the mean trough depth. Second order (narrow band): a
    wave of height H has crest ½H(1 + ¼kH) and trough ½H(1 − ¼kH) (Stokes), ratio 1.09 at the peak's
    k_p·Hs = 0.18 here; the spectrum's width and spread lower it (1.055 measured). Bound 1.03; the linear
    Gerstner sea gives 0.98."""
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=18.95))
    pts = np.random.default_rng(2).uniform(-500.0, 500.0, (60, 2))
    z = np.array([sea.query(pts, t)["height"] for t in np.arange(0.0, 900.0, 0.25)])
    crests, troughs = [], []
    for col in z.T:
        up = np.flatnonzero((col[:-1] < 0.0) & (col[1:] >= 0.0))
        for a, b in zip(up[:-1], up[1:]):
            crests.append(col[a:b + 1].max())
            troughs.append(-col[a:b + 1].min())
    crests, troughs = np.array(crests), np.array(troughs)
    top = crests + troughs > np.quantile(crests + troughs, 2.0 / 3.0)
    assert np.mean(crests[top]) / np.mean(troughs[top]) > 1.03


@pytest.mark.parametrize("wind", [18.95, 30.0])
def test_surface_still_never_loops(wind):
    """The correction is vertical: the horizontal Jacobian stays ≥ 0 at the sharpest steepness (Q = 1)."""
    sea = sea_surface(Ocean(enabled=True, steepness=1.0), Weather(wind_speed=wind))
    assert sea.second_order > 0.0
    xy = np.random.default_rng(2).uniform(-300.0, 300.0, (20000, 2))
    for t in (0.0, 13.7):
        out = sea.evaluate(xy, t)
        assert np.all(np.isfinite(out["position"])) and out["jacobian"].min() >= 0.0
