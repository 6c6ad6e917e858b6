"""The sea's wave maths against references written here (igserver/water): the dispersion solve to float64
round-off as its docstring promises, the group velocity as dω/dk of the dispersion relation, and more
below per module. GL-free and fast: they are part of the mutation run's selection (scripts/mutation.sh)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.water.dispersion import G, group_velocity, solve_kh, wavenumber

from test_water import reference_kh as _bisect_kh  # y tanh y = x by 200 float64 bisection steps


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
    SPREADING_S, SWELL_SPREADING_S, beaufort_hs, calibrate_detail, jonswap, peak_omega, pm_fully_developed_hs,
    WaveSet, sea_spectrum, wave_bands, wind_for_hs,
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
    Pierson–Moskowitz sea 0.21 U19.5²/g, U19.5 = 1.026 U (Stewart 2008: drag coefficient 1.3e-3; the
    figures 6.5 m at 17 m/s and 10.9 m at 22 m/s) (both grow as U², 0.0131 U² < 0.0225 U²: the cap never
    binds); wind_for_hs inverts it."""
    assert beaufort_hs(6.7) == pytest.approx(1.0) and beaufort_hs(18.95) == pytest.approx(5.5)
    assert beaufort_hs(32.7) == pytest.approx(14.0)
    assert beaufort_hs(31.6) == pytest.approx(11.5 + (14.0 - 11.5) * (31.6 - 30.55) / (32.7 - 30.55))  # Bf 11..12
    for wind in (36.0, 60.0):  # U² from Bf 12 on, below the fully developed sea (both grow as U²)
        assert beaufort_hs(wind) == pytest.approx(14.0 * (wind / 32.7) ** 2)
        assert pm_fully_developed_hs(wind) == pytest.approx(0.21 * (1.026 * wind) ** 2 / G)
        assert beaufort_hs(wind) < pm_fully_developed_hs(wind)
    for hs in (0.05, 0.4, 1.0, 3.7, 9.0, 12.5, 14.0, 17.5):
        assert beaufort_hs(wind_for_hs(hs)) == pytest.approx(hs, rel=1e-12), hs


def test_peak_frequency_from_the_fetch_laws():
    """JONSWAP fetch laws (g Hs/U² = 1.6e-3 χ^½, U f_p/g = 3.5 χ^−0.33) written here: a young sea (Hs well
    below full development) peaks higher than the Pierson–Moskowitz ω_p = 0.855 g/U, which bounds it below."""
    for wind, hs in ((10.0, 0.8), (15.0, 2.0), (20.0, 3.0)):
        chi = (G * hs / wind ** 2 / 1.6e-3) ** 2
        fetch_limited = 2 * math.pi * 3.5 * G / wind * chi ** -0.33
        assert fetch_limited > 0.855 * G / wind
        assert peak_omega(hs, wind) == pytest.approx(fetch_limited, rel=1e-12)
    # A sea higher than its wind can raise (the calibration's rule: PM fully developed Hs with the
    # rough-sea U19.5 = 1.075 U, 0.21 (1.075 U)²/g: 2.48 m at 10 m/s) is older than the wind: it peaks at
    # the PM frequency of the wind that does raise it fully developed.
    u_dev = math.sqrt(20.0 * G / 0.21) / 1.075
    assert peak_omega(20.0, 10.0) == pytest.approx(0.855 * G / u_dev)
    assert peak_omega(0.0, 0.0) == pytest.approx(0.855 * G / 1.0)  # no sea: the 1 m/s shape


@pytest.mark.parametrize("wind", [0.5, 1.0, 2.0, 3.0, 5.0])
def test_light_wind_mesh_waves_are_not_steeper_than_the_sea_surface(wind):
    """Cox & Munk (1954) measured the sea surface's whole slope variance: mss = 0.003 + 5.12e-3 U. The mesh
    carries only the long waves (the detail maps the rest), so its slope variance cannot exceed the whole;
    the fit's scatter (±0.004 in their data) is the allowance. At 1 m/s the WMO table's 0.1 m on the wind's
    own PM peak (0.8 m waves) gave 0.12, 15x the measurement."""
    from igserver.water import sea_surface
    from igserver.scene.model import Ocean, Weather
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=wind))
    mss = float(np.sum(sea.waves.k ** 2 * sea.waves.amplitude ** 2) / 2.0)  # Σ (k A)²/2 of the mesh's waves
    assert mss <= 0.003 + 5.12e-3 * wind + 0.004, mss


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


def _mss(waves: WaveSet) -> float:
    """Mean-square slope of a sum of sinusoids: Σ (k_i A_i)² / 2."""
    return float(np.sum((waves.k * waves.amplitude) ** 2) / 2.0)


def test_slopes_match_cox_munk_after_calibration():
    """Cox & Munk (1954), clean surface: total mean-square slope 0.003 + 5.12e-3 U (U at 12.5 m): mesh
    plus calibrated detail band reach it (1e-12: a scale factor, exact up to round-off); at wind 0 (no
    mesh waves) the detail band alone holds the calm-sea 0.003. Only amplitudes are scaled."""
    for wind in (0.0, 3.0, 8.0, 15.0):
        mesh, detail = wave_bands(sea_spectrum(wind, 0.0, None), 64, 64)
        calibrated = calibrate_detail(mesh, detail, wind)
        assert _mss(mesh) + _mss(calibrated) == pytest.approx(0.003 + 5.12e-3 * wind, rel=1e-12), wind
        for field in ("omega", "k", "direction", "phase"):
            assert np.array_equal(getattr(calibrated, field), getattr(detail, field)), field
    assert _mss(wave_bands(sea_spectrum(0.0, 0.0, None), 64, 64)[0]) == 0.0


def test_detail_band_keeps_a_floor_of_capillary_roughness():
    """Where the mesh band alone is steeper than Cox–Munk (a 0.5 m/s sea here: the table's 0.05 m on the
    peak of the wind that raises it), the detail band keeps a quarter of the calm-sea slope (0.25 × 0.003)
    rather than vanishing: the sea is never a mirror."""
    mesh, detail = wave_bands(sea_spectrum(0.5, 0.0, None), 24, 36)
    assert _mss(mesh) > 0.003 + 5.12e-3 * 0.5
    assert _mss(calibrate_detail(mesh, detail, 0.5)) == pytest.approx(0.25 * 0.003, rel=1e-12)
    empty = WaveSet(*(np.zeros(0) for _ in range(2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    assert calibrate_detail(mesh, empty, 1.0).n == 0


# --------------------------------------------------------------------------- bathymetry (water/bathymetry.py)

from igserver.scene.model import Bathymetry, Ocean, Weather  # noqa: E402
from igserver.water.bathymetry import depth_at, reference_waves, shore_steepness, wave_field  # noqa: E402
from igserver.water.surface import SeaSurface, sea_surface, surface_key  # noqa: E402


def _k_of(omega: float, h: np.ndarray) -> np.ndarray:
    """Wavenumber from the bisection reference above (not igserver's Newton)."""
    h = np.asarray(h, dtype=np.float64)
    return _bisect_kh(omega ** 2 * h / G) / h


def _cg_of(omega: float, h: np.ndarray) -> np.ndarray:
    k = _k_of(omega, h)
    kh = k * h
    return 0.5 * omega / k * (1.0 + 2.0 * kh / np.sinh(2.0 * kh))


BEACH = Bathymetry(type="slope", depth=30.0, slope=0.03, shore_distance=800.0, shore_heading=90.0)


def test_plane_beach_depth():
    """h = slope × (distance to the shoreline along the shore heading), capped at the offshore depth."""
    assert depth_at(BEACH, np.array([[800.0, 123.0]])) == pytest.approx([0.0])
    assert depth_at(BEACH, np.array([[700.0, -50.0]])) == pytest.approx([3.0])
    assert depth_at(BEACH, np.array([[0.0, 0.0]])) == pytest.approx([24.0])
    assert depth_at(BEACH, np.array([[-500.0, 0.0]])) == pytest.approx([30.0])  # 39 m by the slope: capped
    assert depth_at(BEACH, np.array([[850.0, 0.0]]))[0] == pytest.approx(-1.5)  # dry land: negative
    north = Bathymetry(type="slope", depth=30.0, slope=0.03, shore_distance=800.0, shore_heading=0.0)
    assert depth_at(north, np.array([[123.0, 700.0]])) == pytest.approx([3.0])


def _one_wave(omega: float, to_azimuth: float, amplitude: float = 0.3, depth: float = 30.0) -> WaveSet:
    a = math.radians(to_azimuth)
    deep = WaveSet(np.array([omega]), np.array([omega ** 2 / G]), np.array([[math.sin(a), math.cos(a)]]),
                   np.array([amplitude]), np.array([0.0]))
    return reference_waves(deep, depth)


def test_reference_waves_are_shoaled_to_the_reference_depth():
    """Over h_ref: k = k(ω, h_ref) and A·√(c_g,deep / c_g(h_ref)) (linear shoaling)."""
    omega = 0.6
    w = _one_wave(omega, 90.0, 0.3, 8.0)
    assert w.k[0] == pytest.approx(_k_of(omega, 8.0), rel=1e-12)
    assert w.amplitude[0] == pytest.approx(0.3 * math.sqrt((G / (2 * omega)) / _cg_of(omega, 8.0)), rel=1e-9)


@pytest.mark.parametrize("incidence", [0.0, 25.0, 50.0])
def test_beach_rays_follow_snell_and_the_amplitude_follows_energy_flux(incidence):
    """Over straight parallel contours (ray theory, any linear-wave text): |K| = k(ω, h) (the eikonal),
    the alongshore component k sin θ is conserved (Snell), and the amplitude factor relative to the
    reference depth is K_s·K_r = √(c_g,ref/c_g) · √(cos θ_ref / cos θ) until the breaking cap.
    Wavenumbers and group velocities from the bisection reference; the march integrates the phase with the
    trapezoid rule (its |K| is exact per node): 1e-9 on |K| and Snell, 1e-6 on the factor."""
    omega = 0.7
    waves = _one_wave(omega, 90.0 - incidence)  # shore to the east; waves come in at `incidence`
    field = wave_field(BEACH, waves, 0.5, omega)
    h = field.depth[:, 0]
    sel = (h > 2.0) & (h < 29.0)  # wet, below the reference depth, outside the surf zone
    kvec = field.kvec[0, sel, 0, :]
    k_local = _k_of(omega, h[sel])
    assert np.allclose(np.linalg.norm(kvec, axis=1), k_local, rtol=1e-9)
    k_ref = _k_of(omega, 30.0)
    alongshore = k_ref * math.sin(math.radians(incidence))
    assert np.allclose(np.abs(kvec[:, 1]), alongshore, rtol=1e-9, atol=1e-12)
    cos_theta = np.sqrt(1.0 - (alongshore / k_local) ** 2)
    expected = np.sqrt(_cg_of(omega, 30.0) / _cg_of(omega, h[sel])) * np.sqrt(math.cos(math.radians(incidence)) / cos_theta)
    capped = field.breaking[sel, 0] > 0.0
    assert np.count_nonzero(~capped) > 50
    assert np.allclose(field.factor[0, sel, 0][~capped], expected[~capped], rtol=1e-6)


def test_breaking_caps_the_linear_sea_at_the_surf_zone_height_and_dry_land_is_still():
    """The linear sea's Hs may not exceed 0.61 h: the Hs whose elevation, once bounded inside ±0.39 h (single
    waves ≤ 0.78 h, McCowan), has 4σ = √2·0.42 h (Thornton & Guza 1983: Hrms = 0.42 h in the saturated surf
    zone). Where the cap acts Hs equals it; on dry land (h <= 0) nothing moves and the breaking mark is 0."""
    from igserver.water.bathymetry import SURF_LINEAR_HS
    assert SURF_LINEAR_HS == pytest.approx(0.61, abs=0.01)
    waves = _one_wave(0.5, 90.0, amplitude=1.2)
    field = wave_field(BEACH, waves, 0.5, 0.5)
    h = field.depth[:, 0]
    hs = 4.0 * np.sqrt(0.5 * (waves.amplitude[0] * field.factor[0, :, 0]) ** 2)
    capped = (field.breaking[:, 0] > 1e-9) & (h > 0)
    assert np.count_nonzero(capped) > 10
    assert np.allclose(hs[capped], SURF_LINEAR_HS * h[capped], rtol=1e-9)
    assert np.all(hs[h > 0] <= SURF_LINEAR_HS * h[h > 0] * (1 + 1e-9))
    dry = h <= 0
    assert np.count_nonzero(dry) > 0 and np.all(field.factor[0, dry, 0] == 0) and np.all(field.breaking[dry, 0] == 0)
    # the mark is 1 − cap: ~0 offshore, rising toward the shoreline
    assert field.breaking[np.argmax(h), 0] == 0.0 and np.max(field.breaking[capped, 0]) > 0.5


def test_shore_steepness_limits():
    """Q(x) = Q + (0.9 − Q)(1 − tanh k_p h): Q offshore (k_p h → ∞), 0.9 at the waterline, never below Q."""
    assert shore_steepness(0.4, np.array(50.0)) == pytest.approx(0.4)
    assert shore_steepness(0.4, np.array(0.0)) == pytest.approx(0.9)
    assert shore_steepness(0.4, np.array(1.0)) == pytest.approx(0.4 + 0.5 * (1 - math.tanh(1.0)))
    assert shore_steepness(0.95, np.array(0.0)) == pytest.approx(0.95)  # steeper than 0.9 offshore: kept


# --------------------------------------------------------------------------- surface (water/surface.py)

def _surface(waves: WaveSet, q: float) -> SeaSurface:
    return SeaSurface(sea_spectrum(8.0, 0.0, None), waves, waves, None, q, 1000.0)


def test_gerstner_surface_is_the_textbook_sum():
    """Two deep-water Gerstner waves written here (Tessendorf 2001, 'Simulating ocean water', eq. 9 with
    per-wave steepness Q_i = Q/(k_i A_i n)): x = x₀ + Σ (Q/(k_i n)) D_i cos θ_i, z = Σ A_i sin θ_i,
    θ_i = k_i D_i·x₀ − ω_i t + φ_i. float64 except sin/cos (float32 after a float64 reduction: 1e-7
    relative of a phase below π → 1e-6 m on these metre-scale waves)."""
    omega = np.array([0.8, 1.3])
    k = omega ** 2 / G
    d = np.array([[1.0, 0.0], [math.sin(math.radians(30)), math.cos(math.radians(30))]])
    amp, phase, q = np.array([0.9, 0.35]), np.array([0.4, 2.0]), 0.5
    sea = _surface(WaveSet(omega, k, d, amp, phase), q)
    p0 = np.random.default_rng(2).uniform(-100, 100, (50, 2))
    t = 12.7
    out = sea.evaluate(p0, t)
    theta = k[:, None] * (d @ p0.T) - omega[:, None] * t + phase[:, None]
    b = np.minimum(q / (k * 2), amp)[:, None]
    x = p0 + np.stack([np.sum(b * d[:, :1] * np.cos(theta), 0), np.sum(b * d[:, 1:] * np.cos(theta), 0)], axis=1)
    z = np.sum(amp[:, None] * np.sin(theta), axis=0)
    assert np.allclose(out["position"][:, :2], x, atol=1e-5)
    assert np.allclose(out["position"][:, 2], z, atol=1e-5)
    # an origin shift moves nothing (camera-relative phases are reduced, not changed)
    assert np.allclose(sea.evaluate(p0, t, origin_xy=(5e5, -3e5))["position"], out["position"], atol=1e-5)


def test_normal_velocity_and_jacobian_are_the_derivatives():
    """In uniform depth the tangent frame is exact: the normal is ∂P/∂x₀ × ∂P/∂y₀ normalised, the
    velocity ∂P/∂t, the Jacobian det ∂(x,y)/∂(x₀,y₀), all checked by central differences here (step
    1 mm and 1 ms: truncation ~1e-6 of the 100 m and 8 s scales, float32 sin/cos noise 1e-6 m / 1e-3 m:
    bounds 1e-3)."""
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=9.0, wind_direction=40.0), 16)
    p0 = np.random.default_rng(3).uniform(-300, 300, (40, 2))
    t, e, dt = 33.0, 1e-3, 1e-3
    out = sea.evaluate(p0, t)
    px = (sea.evaluate(p0 + [e, 0], t)["position"] - sea.evaluate(p0 - [e, 0], t)["position"]) / (2 * e)
    py = (sea.evaluate(p0 + [0, e], t)["position"] - sea.evaluate(p0 - [0, e], t)["position"]) / (2 * e)
    normal = np.cross(px, py)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    assert np.allclose(out["normal"], normal, atol=1e-3)
    velocity = (sea.evaluate(p0, t + dt)["position"] - sea.evaluate(p0, t - dt)["position"]) / (2 * dt)
    assert np.allclose(out["velocity"], velocity, atol=1e-3)
    assert np.allclose(out["jacobian"], px[:, 0] * py[:, 1] - px[:, 1] * py[:, 0], atol=1e-3)


def test_query_finds_the_surface_above_a_world_point():
    """The height returned for x is that of the rest point whose displaced position is x (Newton on the
    horizontal map): evaluating that rest point lands on x (1e-5 m: the query's tolerance)."""
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=14.0, wind_direction=300.0), 24)
    x = np.random.default_rng(4).uniform(-500, 500, (100, 2))
    got = sea.query(x, 81.0)
    back = sea.evaluate(got["rest"], 81.0)
    assert np.all(np.abs(back["position"][:, :2] - x) <= 1e-5)
    assert np.all(got["residual"] <= 1e-5)
    # The query's sines come by angle addition from the phases at x, evaluate's straight from the
    # reduced phases at the rest point: two float32 paths, each within ~2e-7 of the exact sine, so a
    # sum weighted by A (K A, ω A) differs by at most 4e-7 of Σ A (Σ K A, Σ ω A).
    w = sea.waves
    assert np.allclose(back["position"][:, 2], got["height"], rtol=0, atol=4e-7 * np.sum(w.amplitude))
    assert np.allclose(back["normal"], got["normal"], rtol=0, atol=4e-7 * np.sum(w.k * w.amplitude))
    assert np.allclose(back["velocity"], got["velocity"], rtol=0, atol=4e-7 * np.sum(w.omega * w.amplitude))


def test_whitecap_threshold_gives_monahans_coverage():
    """Monahan & O'Muircheartaigh (1980): whitecap fraction W = 3.84e-6 U^3.41 (12 m/s: 1.8 %). The
    threshold is the J quantile at W over its own samples; over 20,000 fresh points and instants the
    fraction below it is W within 25 % (sampling: ~360 points below; the field is correlated over a
    wavelength, which widens the spread beyond the binomial 5 %)."""
    wind = 12.0
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=wind, wind_direction=0.0))
    threshold = sea.foam_jacobian(wind)
    rng = np.random.default_rng(99)
    j = np.concatenate([sea.evaluate(rng.uniform(-2000, 2000, (5000, 2)), t, full=False)["jacobian"]
                        for t in (3.0, 50.0, 111.0, 170.0)])
    coverage = 3.84e-6 * wind ** 3.41
    assert float(np.mean(j < threshold)) == pytest.approx(coverage, rel=0.25)
    assert sea_surface(Ocean(enabled=True), Weather(wind_speed=0.0)).foam_jacobian(0.0) == -1.0


def test_whitecaps_cover_at_most_half_the_sea():
    """Monahan's law passes 50 % at 31.6 m/s; past it the coverage is held at one half (the threshold is the
    median J): at 40 m/s half of 20,000 fresh samples lie below it (± 0.06: the correlated field's
    sampling spread, as above)."""
    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=40.0, wind_direction=0.0))
    threshold = sea.foam_jacobian(40.0)
    rng = np.random.default_rng(7)
    j = np.concatenate([sea.evaluate(rng.uniform(-2000, 2000, (5000, 2)), t, full=False)["jacobian"]
                        for t in (3.0, 50.0, 111.0, 170.0)])
    assert float(np.mean(j < threshold)) == pytest.approx(0.5, abs=0.06)


def test_amplitude_sum_bounds_every_displacement():
    """The mesh's error sphere: no displacement (horizontal or vertical) exceeds Σ A_i·max F."""
    for ocean in (Ocean(enabled=True), Ocean(enabled=True, bathymetry=BEACH)):
        sea = sea_surface(ocean, Weather(wind_speed=11.0, wind_direction=250.0))
        p0 = np.random.default_rng(5).uniform(-900, 900, (3000, 2))
        out = sea.evaluate(p0, 17.0)
        displacement = np.linalg.norm(np.concatenate([out["displaced_xy"] - p0, out["position"][:, 2:]], 1), axis=1)
        assert displacement.max() <= sea.amplitude_sum
        assert sea.amplitude_sum == pytest.approx(float(np.sum(sea.waves.amplitude))
                                                  * max(1.0, float(np.max(sea.field.factor)) if sea.field else 1.0))


def test_surface_key_ignores_what_does_not_shape_the_waves():
    """Level, LOD error and detail-map resolution change no wave: the cache key ignores them; wind and
    bathymetry change it."""
    weather = Weather(wind_speed=7.0, wind_direction=10.0)
    base = surface_key(Ocean(enabled=True), weather)
    assert surface_key(Ocean(enabled=False, level=12.0, lod_error=4.0, detail_resolution=64), weather) == base
    assert surface_key(Ocean(enabled=True), Weather(wind_speed=7.5, wind_direction=10.0)) != base
    assert surface_key(Ocean(enabled=True), Weather(wind_speed=7.0, wind_direction=11.0)) != base
    assert surface_key(Ocean(enabled=True, bathymetry=BEACH), weather) != base


def _write_map(folder, name: str, array: np.ndarray) -> None:
    from PIL import Image

    (folder / "bathymetry").mkdir(parents=True, exist_ok=True)
    Image.fromarray(array).save(folder / "bathymetry" / f"{name}.png")


def test_bathymetry_maps_are_read_as_fractions_of_full_scale(tmp_path, monkeypatch):
    """A map's grey level is its fraction of the format's full scale: 8-bit levels over 255, 16-bit over
    65535 (whatever the largest level in the picture), white is exactly 1, RGB is read as its luminance."""
    from igserver.water.bathymetry import load_map

    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    _write_map(tmp_path, "eight", np.array([[0, 51], [204, 255]], np.uint8))
    _write_map(tmp_path, "sixteen", np.array([[0, 200], [40000, 65535]], np.uint16))
    _write_map(tmp_path, "sixteen_dark", np.array([[0, 200]], np.uint16))  # 16-bit levels all below 256
    _write_map(tmp_path, "colour", np.full((2, 2, 3), 255, np.uint8))
    assert np.array_equal(load_map("eight"), np.array([[0.0, 0.2], [0.8, 1.0]]))
    assert np.array_equal(load_map("sixteen"), np.array([[0.0, 200 / 65535], [40000 / 65535, 1.0]]))
    assert np.array_equal(load_map("sixteen_dark"), np.array([[0.0, 200 / 65535]]))
    assert np.array_equal(load_map("colour"), np.ones((2, 2)))
    assert load_map("eight").dtype == np.float64


def test_bathymetry_maps_over_4096_squared_pixels_are_refused(tmp_path, monkeypatch):
    """The documented bound is 4096x4096 pixels (16.8 Mpx): that size loads, one pixel row more does not."""
    from igserver.water.bathymetry import load_map

    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    _write_map(tmp_path, "largest", np.zeros((4096, 4096), np.uint8))
    _write_map(tmp_path, "too_tall", np.zeros((4097, 4096), np.uint8))
    _write_map(tmp_path, "too_wide", np.zeros((4096, 4097), np.uint8))
    assert load_map("largest").shape == (4096, 4096)
    for name in ("too_tall", "too_wide"):
        with pytest.raises(ValueError, match="larger than 4096x4096"):
            load_map(name)


def test_query_of_no_points_is_empty_and_quiet():
    """A batch of zero points answers empty arrays of the right shapes, with no warning (no mean of an
    empty batch)."""
    import warnings

    sea = sea_surface(Ocean(enabled=True), Weather(wind_speed=6.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = sea.query(np.zeros((0, 2)), 5.0)
    assert got["height"].shape == (0,) and got["normal"].shape == (0, 3) and got["velocity"].shape == (0, 3)


def _float64_reference(sea: SeaSurface, x: np.ndarray, t: float) -> dict:
    """The surface above world points x, written independently in plain float64: per-wave loops, np.sin
    and np.cos in float64 on unreduced phases (|θ| < 1e4 rad here: 2e-12 rad of rounding), the field
    interpolated by np.interp along the beach's one-row grid, and fixed-point-plus-Newton iterations
    of p + Δ(p) = x run far past convergence (60 steps). The height is L(z₁ + z₂) (surface.py): the
    second-order term z₂ = ½(|Σ s_i e^{iθ_i}|² − Σ s_i²), s_i = a_i √(α|K_i|), and the depth limit L,
    identity up to z₀ = 0.195 h then z₀ + (0.39 h − z₀) tanh((|z| − z₀)/(0.39 h − z₀)), written here."""
    w, f = sea.waves, sea.field

    def local(p):
        if f is None:
            kv = w.k[:, None, None] * w.direction[:, :, None] * np.ones(len(p))
            return np.zeros((w.n, len(p))), w.amplitude[:, None] * np.ones(len(p)), kv[:, 0], kv[:, 1], \
                np.full(len(p), sea.steepness), np.full(len(p), sea.reference_depth)
        g = f.grid
        gu = np.clip(((p - g.origin) @ g.u) / g.du, 0, g.nu - 1)
        if g.nv == 1:
            nodes = np.arange(g.nu)
            lerp = lambda values: np.interp(gu, nodes, values[:, 0])  # noqa: E731
        else:  # bilinear, clamped at the edges
            gv = np.clip(((p - g.origin) @ g.v) / g.dv, 0, g.nv - 1)
            i, j = np.minimum(np.floor(gu).astype(int), g.nu - 2), np.minimum(np.floor(gv).astype(int), g.nv - 2)
            tu, tv = gu - i, gv - j

            def lerp(values):
                return ((values[i, j] * (1 - tu) + values[i + 1, j] * tu) * (1 - tv)
                        + (values[i, j + 1] * (1 - tu) + values[i + 1, j + 1] * tu) * tv)
        r = np.array([lerp(f.residual[i]) for i in range(w.n)])
        a = np.array([w.amplitude[i] * lerp(f.factor[i]) for i in range(w.n)])
        kx = np.array([lerp(f.kvec[i, ..., 0]) for i in range(w.n)])
        ky = np.array([lerp(f.kvec[i, ..., 1]) for i in range(w.n)])
        return r, a, kx, ky, lerp(f.steepness), lerp(f.depth)

    def surface(p):
        r, a, kx, ky, q, depth = local(p)
        theta = (w.k[:, None] * (w.direction @ p.T)) - w.omega[:, None] * t + w.phase[:, None] + r
        s, c = np.sin(theta), np.cos(theta)
        kmag = np.hypot(kx, ky)
        b = np.minimum(q / (kmag * w.n), a)
        ux, uy = b * kx / kmag, b * ky / kmag
        disp = np.stack([np.sum(ux * c, 0), np.sum(uy * c, 0)], 1)
        jac = np.stack([[1 - np.sum(ux * kx * s, 0), -np.sum(ux * ky * s, 0)],
                        [-np.sum(uy * kx * s, 0), 1 - np.sum(uy * ky * s, 0)]]).transpose(2, 0, 1)
        sk = a * np.sqrt(sea.second_order * kmag)
        big_x, big_y = np.sum(sk * s, 0), np.sum(sk * c, 0)
        z = np.sum(a * s, 0) + 0.5 * (big_x**2 + big_y**2 - np.sum(sk**2, 0))
        dz_dx = np.sum(a * kx * c, 0) + big_x * np.sum(sk * kx * c, 0) - big_y * np.sum(sk * kx * s, 0)
        dz_dy = np.sum(a * ky * c, 0) + big_x * np.sum(sk * ky * c, 0) - big_y * np.sum(sk * ky * s, 0)
        om = w.omega[:, None]
        dz_dt = -np.sum(a * om * c, 0) - big_x * np.sum(sk * om * c, 0) + big_y * np.sum(sk * om * s, 0)
        bound = 0.39 * np.maximum(depth, 1e-3)
        knee, width = 0.5 * bound, 0.5 * bound
        over = np.abs(z) > knee
        th = np.tanh(np.where(over, np.abs(z) - knee, 0.0) / width)
        z = np.where(over, np.sign(z) * (knee + width * th), z)
        dl = np.where(over, 1.0 - th**2, 1.0)
        tx = np.stack([jac[:, 0, 0], jac[:, 1, 0], dl * dz_dx], 1)
        ty = np.stack([jac[:, 0, 1], jac[:, 1, 1], dl * dz_dy], 1)
        normal = np.cross(tx, ty)
        velocity = np.stack([np.sum(ux * w.omega[:, None] * s, 0), np.sum(uy * w.omega[:, None] * s, 0),
                             dl * dz_dt], 1)
        return disp, jac, z, normal / np.linalg.norm(normal, axis=1, keepdims=True), velocity

    p = x.copy()
    for _ in range(60):
        disp, jac, *_ = surface(p)
        p = p - np.linalg.solve(jac, (p + disp - x)[:, :, None])[:, :, 0]
    disp, _, height, normal, velocity = surface(p)
    return {"height": height, "normal": normal, "velocity": velocity, "residual": np.abs(p + disp - x).max(1)}


ISLAND = Bathymetry(type="map", map="island", map_center=[500.0, 0.0], map_size=[1500.0, 1500.0], map_heading=20.0,
                    map_elevation=[-50.0, 10.0], depth=60.0)




@pytest.mark.parametrize("bathymetry,wind", [(b, w) for b in (None, BEACH) for w in (3.0, 12.0, 30.0)]
                         + [(ISLAND, 12.0)])
def test_query_equals_a_float64_reference(bathymetry, wind):
    """The fast query (float32 sines and cosines of float64-reduced phases, angle addition across the
    Chebyshev iterations, reused buffers, chunks) against the plain float64 reference above, over the
    open sea, the beach and a height-map island (surf zone and dry land included). Bounds per point: float32 trig ≤ 4e-7 of
    Σ A (Σ K A, Σ ω A; see test_query_finds_the_surface_above_a_world_point), plus the query's rest
    point error δ ≤ √2·residual/(1 − Q_SHORE) (J ≥ 1 − Q, Q ≤ 0.9 anywhere) times the slope (height),
    curvature ≤ Σ A K² (normal) or Σ A ω K (velocity). And never more than 1e-5 m in height: ≪ 1 mm,
    what a hull on these numbers can feel."""
    ocean = Ocean(enabled=True, bathymetry=bathymetry) if bathymetry else Ocean(enabled=True)
    sea = sea_surface(ocean, Weather(wind_speed=wind, wind_direction=70.0))
    x = np.random.default_rng(21).uniform(-400.0, 830.0, (3000, 2))
    t = 1234.5
    got, ref = sea.query(x, t), _float64_reference(sea, x, t)
    assert np.all(ref["residual"] < 1e-9)  # the reference converged
    assert np.all(got["residual"] <= 1e-5)
    amp = sea.amplitude_sum
    kmax = float(np.max(np.hypot(sea.field.kvec[..., 0], sea.field.kvec[..., 1]) if sea.field else sea.waves.k))
    omega = float(np.max(sea.waves.omega))
    delta = math.sqrt(2.0) * got["residual"] / (1.0 - 0.9)
    slope = np.hypot(*(ref["normal"][:, :2].T)) / ref["normal"][:, 2]
    dh = np.abs(got["height"] - ref["height"])
    assert np.all(dh <= 4e-7 * amp + slope * delta)
    assert dh.max() < 1e-5
    dn = np.max(np.abs(got["normal"] - ref["normal"]), axis=1)
    assert np.all(dn <= 4e-7 * amp * kmax + amp * kmax ** 2 * delta)
    dv = np.max(np.abs(got["velocity"] - ref["velocity"]), axis=1)
    assert np.all(dv <= 4e-7 * amp * omega + amp * omega * kmax * delta)
