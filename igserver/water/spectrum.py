"""Wind (or WMO sea state) → a deterministic set of Gerstner waves.

Calibration (docs/design.md#water). The target significant wave height Hs = 4σ is the WMO "probable wave
height" of the Beaufort scale (WMO-No. 558), interpolated linearly in wind speed between the
classes' mid-range winds; above Beaufort 12 (32.7 m/s, "14 m and over") it grows as U² (the
fully-developed Pierson–Moskowitz law) and is capped by the PM fully developed sea. When the host
sets ``ocean.sea_state`` the target is the midpoint of that WMO sea-state code's Hs range instead.

Growth (``ocean.fetch_km``, ``ocean.duration_h``). The WMO probable heights are those of the seas
sailors meet, limited by fetch and duration. A host that knows how far (X) and how long (t) the wind
U (10 m) has blown gets the JONSWAP growth laws instead (Hasselmann et al. 1973; the Shore Protection
Manual 1984, eqs 3-33..3-35, in the 10 m wind), with χ = g·X/U² and τ = g·t/U:
    g·Hs/U² = 1.6e-3·χ^½,    g·T_p/U = 0.2857·χ^⅓ (U·f_p/g = 3.5·χ^−0.33),    τ = 68.8·χ^⅔.
The last is the time the peak's energy takes to cross the fetch at the JONSWAP peak's group velocity
g/(2ω_p) (integrating dX/c_g gives 65.6·χ^0.67: within 5 %); a duration-limited sea is the sea of the
fetch it has crossed, χ_t = (τ/68.8)^{3/2}, and the sea is limited by the shorter of the two. Both cap
at the Pierson–Moskowitz fully developed sea (Pierson & Moskowitz 1964, wind at 19.5 m):
    Hs = 0.21·U19.5²/g,    ω_p = 0.877·g/U19.5,    U19.5 = 1.026·U10
(Stewart 2008, §16: the neutral log profile with drag coefficient 1.3e-3), i.e. Hs = 0.2211·U10²/g
and ω_p = 0.855·g/U10: 6.5 m and 12.7 s at 17 m/s, 10.9 m and 16.5 s at 22 m/s. The JONSWAP laws meet
that cap at χ = 1.91e4 (563 km and 23.6 h at 17 m/s), where their T_p is within 0.5 % of PM's.

Shape. A JONSWAP spectrum (γ = 3.3). Its peak follows from (Hs, U) through the fetch-limited
JONSWAP laws g·Hs/U² = 1.6e-3·χ^½ and U·f_p/g = 3.5·χ^−0.33 (χ = g·X/U², X the fetch): the table's
Hs at wind U implies an effective fetch, and the fetch the peak; never below the fully developed
PM peak ω_p = 0.855·g/U (U the wind that raises the table's Hs fully developed where
that Hs is more than the local wind can raise: light winds, see peak_omega). Directional spreading D(θ) ∝ cos^{2s}(θ/2), s = 10, about the direction
the wind blows TO. The spectrum is cut into equal-energy bins: every wave of a band carries the
same energy, at the bin's median frequency (so any wave count keeps Hs), with a direction drawn by
inverse CDF at a golden-ratio quasi-random quantile and a phase from a fixed-seed generator.

Bands. The mesh band (ω ≤ MESH_CUT·ω_p) holds what the vertex shader displaces; the detail band
above it (to capillary scale) feeds the normal maps only. The detail band's amplitude is set so
that the total mean-square slope matches Cox & Munk (1954), σ² = 0.003 + 5.12e-3·U: even at wind 0
a glassy sea keeps some capillary roughness and is not a perfect mirror.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .dispersion import G

# (mid-range wind m/s, WMO probable wave height m) of Beaufort 0..12 (WMO-No. 558, Table).
BEAUFORT_PROBABLE_HEIGHT = (
    (0.0, 0.0), (0.1, 0.0), (0.9, 0.1), (2.45, 0.2), (4.4, 0.6), (6.7, 1.0), (9.35, 2.0), (12.3, 3.0),
    (15.5, 4.0), (18.95, 5.5), (22.6, 7.0), (26.45, 9.0), (30.55, 11.5), (32.7, 14.0),
)
# WMO sea-state code 0..9: Hs range (m); code 9 is "over 14 m", taken as 14..18.
SEA_STATE_RANGE = ((0.0, 0.0), (0.0, 0.1), (0.1, 0.5), (0.5, 1.25), (1.25, 2.5), (2.5, 4.0), (4.0, 6.0),
                   (6.0, 9.0), (9.0, 14.0), (14.0, 18.0))
JONSWAP_GAMMA = 3.3
SPREADING_S = 10.0
SWELL_SPREADING_S = 60.0
MESH_CUT = 3.5  # mesh band ends at 3.5 ω_p (λ_p / 12); higher waves go to the normal maps
DETAIL_TOP_K = 2.0 * math.pi / 0.08  # rad/m, shortest detail wave 8 cm (gravity-capillary)
SEED = 20260421  # fixed: the sea is the same for the same state on every run and server
GOLDEN = 0.6180339887498949


U195_PER_U10 = 1.026  # U(19.5 m) / U(10 m): neutral log profile, drag coefficient 1.3e-3 (Stewart 2008)
PM_HS = 0.21  # g·Hs/U19.5² of the Pierson–Moskowitz fully developed sea
PM_OMEGA_U10 = 0.855  # ω_p·U10/g of the same sea: 0.877·g/U19.5 ((4β/5)^¼, β = 0.74) with U19.5 = 1.026 U10
# The WMO calibration's light-wind rule (peak_omega) reads "a sea older than its wind" where the table's
# height passes 0.21·(1.075 U)²/g (U19.5 = 1.075 U10: the log profile over a rough sea, z₀ ≈ 1 mm): the
# rule the default seas were calibrated with, kept so that they stay as they were.
OLDER_SEA_U195_PER_U10 = 1.075
# JONSWAP growth in the 10 m wind (module docstring): g·Hs/U² = JS_HS·χ^½, U·f_p/g = JS_FP·χ^JS_FP_POW,
# τ = g·t/U = JS_DURATION·χ^⅔.
JS_HS, JS_FP, JS_FP_POW, JS_DURATION = 1.6e-3, 3.5, -0.33, 68.8


def pm_fully_developed_hs(wind: float) -> float:
    """Pierson–Moskowitz fully developed Hs = 0.21 U19.5²/g, U19.5 = 1.026 U10 (m; U10 in m/s)."""
    return PM_HS * (U195_PER_U10 * wind) ** 2 / G


def pm_peak_omega(wind: float) -> float:
    """Pierson–Moskowitz fully developed peak ω_p = 0.877 g/U19.5 = 0.855 g/U10 (rad/s)."""
    return PM_OMEGA_U10 * G / max(wind, 1e-9)


def growth(wind: float, fetch_m: float | None, duration_s: float | None) -> tuple[float, float]:
    """(Hs m, ω_p rad/s) of a wind sea grown over fetch ``fetch_m`` for ``duration_s`` (None: not
    limiting) by the JONSWAP laws, capped at the Pierson–Moskowitz fully developed sea (module
    docstring). Wind 0 raises no sea (Hs 0; the peak is then only the ripples' shape)."""
    wind = max(wind, 0.0)
    u = max(wind, SHAPE_MIN_WIND)
    chi = math.inf
    if fetch_m is not None:
        chi = G * fetch_m / u**2
    if duration_s is not None:
        chi = min(chi, (G * duration_s / u / JS_DURATION) ** 1.5)
    hs = min(JS_HS * math.sqrt(chi) * wind**2 / G, pm_fully_developed_hs(wind))
    omega_p = max(2.0 * math.pi * JS_FP * G / u * chi**JS_FP_POW, pm_peak_omega(u))
    return hs, omega_p


def beaufort_hs(wind: float) -> float:
    """Target Hs (m) for a 10 m wind (m/s): the WMO probable height, continued as U² past Bf 12."""
    winds, heights = zip(*BEAUFORT_PROBABLE_HEIGHT)
    if wind <= winds[-1]:
        return float(np.interp(wind, winds, heights))
    return min(heights[-1] * (wind / winds[-1]) ** 2, pm_fully_developed_hs(wind))


def wind_for_hs(hs: float) -> float:
    """Inverse of ``beaufort_hs`` (the wind whose probable height is hs), for sea-state-driven seas."""
    winds, heights = zip(*BEAUFORT_PROBABLE_HEIGHT[1:])
    if hs <= heights[-1]:
        return float(np.interp(hs, heights, winds))
    return winds[-1] * math.sqrt(hs / heights[-1])


def sea_state_hs(code: int) -> float:
    lo, hi = SEA_STATE_RANGE[code]
    return 0.5 * (lo + hi)


SHAPE_MIN_WIND = 1.0  # m/s: the spectrum's shape (for the ripples of a glassy sea) below this wind


def peak_omega(hs: float, wind: float) -> float:
    """JONSWAP fetch-limited peak (rad/s) implied by (Hs, U), not below the fully developed PM peak.

    Below about 5.5 m/s the WMO probable height exceeds what the wind itself can raise (PM fully
    developed Hs, here with U19.5 = 1.075 U10 (OLDER_SEA_U195_PER_U10) = 0.0248 U²: 0.025 m at 1 m/s
    against the table's 0.1 m): such a sea is older than the
    local wind, and a peak at the wind's own PM frequency would carry that height on 0.8 m waves (mean
    square slope 0.12 at 1 m/s, 15× Cox–Munk's 0.008). Its peak is then the PM peak of the wind that
    does raise that height fully developed."""
    wind = max(wind, SHAPE_MIN_WIND)
    if hs > PM_HS * (OLDER_SEA_U195_PER_U10 * wind) ** 2 / G:
        wind = math.sqrt(hs * G / PM_HS) / OLDER_SEA_U195_PER_U10  # the wind that raises hs fully developed
    pm = pm_peak_omega(wind)
    if hs <= 0.0:
        return pm
    chi = (G * hs / wind**2 / JS_HS) ** 2
    return max(2.0 * math.pi * JS_FP * G / wind * chi**JS_FP_POW, pm)


def jonswap(omega: np.ndarray, omega_p: float) -> np.ndarray:
    """Unnormalised JONSWAP shape S(ω) (only the shape matters: bands are normalised to Hs)."""
    sigma = np.where(omega <= omega_p, 0.07, 0.09)
    r = np.exp(-((omega - omega_p) ** 2) / (2.0 * sigma**2 * omega_p**2))
    return omega**-5.0 * np.exp(-1.25 * (omega_p / omega) ** 4) * JONSWAP_GAMMA**r


@dataclass(frozen=True)
class WaveSet:
    """Deep-water Gerstner components: θ_i = k_i D_i·x − ω_i t + φ_i, height Σ A_i sin θ_i."""

    omega: np.ndarray  # rad/s
    k: np.ndarray  # rad/m, deep water
    direction: np.ndarray  # (n, 2) unit ENU, propagation (wind blows TO)
    amplitude: np.ndarray  # m
    phase: np.ndarray  # rad

    @property
    def n(self) -> int:
        return len(self.omega)

    @property
    def hs(self) -> float:
        return 4.0 * math.sqrt(float(np.sum(self.amplitude**2)) / 2.0)

    @staticmethod
    def concat(*sets: "WaveSet") -> "WaveSet":
        return WaveSet(*(np.concatenate([getattr(s, f) for s in sets]) for f in
                         ("omega", "k", "direction", "amplitude", "phase")))


@dataclass(frozen=True)
class SeaSpectrum:
    wind: float  # m/s, the wind that shapes the spectrum
    azimuth_to: float  # deg, direction the waves travel to
    hs: float  # m, target of the wind sea
    omega_p: float  # rad/s


def sea_spectrum(wind_speed: float, wind_from: float, sea_state: int | None, fetch_km: float | None = None,
                 duration_h: float | None = None) -> SeaSpectrum:
    """The wind sea: a WMO sea-state code's height; else the JONSWAP growth over a fetch and/or a
    duration when either is given; else the WMO/Beaufort calibration of the wind."""
    to = (wind_from + 180.0) % 360.0
    if sea_state is not None:
        hs = sea_state_hs(sea_state)
        wind = wind_for_hs(hs) if hs > 0 else 0.0
    elif fetch_km is not None or duration_h is not None:
        hs, omega_p = growth(wind_speed, None if fetch_km is None else 1e3 * fetch_km,
                             None if duration_h is None else 3600.0 * duration_h)
        return SeaSpectrum(wind_speed, to, hs, omega_p)
    else:
        wind, hs = wind_speed, beaufort_hs(wind_speed)
    return SeaSpectrum(wind, to, hs, peak_omega(hs, wind))


def _quantiles(cdf_x: np.ndarray, cdf: np.ndarray, q: np.ndarray) -> np.ndarray:
    return np.interp(q, cdf, cdf_x)


def _spreading_cdf(s: float) -> tuple[np.ndarray, np.ndarray]:
    theta = np.linspace(-math.pi, math.pi, 2001)
    pdf = np.cos(theta / 2.0) ** (2.0 * s)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]))])
    return theta, cdf / cdf[-1]


def _band(omega_grid, cdf_energy, lo_q, hi_q, n, energy, azimuth_to, spreading_s, offset, rng,
          by_slope: bool = False) -> WaveSet:
    """n waves between quantiles lo_q..hi_q of ``cdf_energy``, each carrying 1/n of ``energy``:
    the elevation variance σ² (m²), or with ``by_slope`` the mean-square slope (the detail band)."""
    if n <= 0:
        empty = np.zeros(0)
        return WaveSet(empty, empty, np.zeros((0, 2)), empty, empty)
    q = lo_q + (hi_q - lo_q) * (np.arange(n) + 0.5) / n
    omega = _quantiles(omega_grid, cdf_energy, q)
    theta_x, theta_cdf = _spreading_cdf(spreading_s)
    dq = (offset + GOLDEN * np.arange(1, n + 1)) % 1.0
    theta = _quantiles(theta_x, theta_cdf, dq)
    az = math.radians(azimuth_to) + theta
    direction = np.stack([np.sin(az), np.cos(az)], axis=1)  # azimuth clockwise from north → ENU
    amplitude = np.full(n, math.sqrt(2.0 * max(energy, 0.0) / n))
    if by_slope:
        amplitude = amplitude / (omega**2 / G)
    phase = rng.uniform(0.0, 2.0 * math.pi, n)
    return WaveSet(omega, omega**2 / G, direction, amplitude, phase)


def wave_bands(spectrum: SeaSpectrum, n_mesh: int, n_detail: int, swell_hs: float = 0.0,
               swell_period: float = 10.0, swell_from: float = 270.0, n_swell: int = 3) -> tuple[WaveSet, WaveSet]:
    """(mesh band, detail band). The mesh band holds the wind sea below MESH_CUT·ω_p plus the swell."""
    rng = np.random.default_rng(SEED)
    wp = spectrum.omega_p
    w_top = math.sqrt(G * DETAIL_TOP_K)
    omega_grid = np.geomspace(0.5 * wp, max(w_top, 8.0 * wp), 6000)
    s = jonswap(omega_grid, wp)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (s[1:] + s[:-1]) * np.diff(omega_grid))])
    cdf /= cdf[-1]
    q_cut = float(np.interp(MESH_CUT * wp, omega_grid, cdf))
    sigma2 = (spectrum.hs / 4.0) ** 2
    n_swell = n_swell if swell_hs > 0.0 else 0
    mesh = _band(omega_grid, cdf, 0.0, q_cut, n_mesh - n_swell, sigma2 * q_cut, spectrum.azimuth_to,
                 SPREADING_S, 0.0, rng)
    # Detail band: equal shares of slope variance (ω⁴S, k = ω²/g), so it reaches the capillary end.
    top = omega_grid <= w_top
    og, slope = omega_grid[top], (omega_grid**4 / G**2 * s)[top]
    cdf_slope = np.concatenate([[0.0], np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(og))])
    detail_lo = min(MESH_CUT * wp, 0.5 * w_top)  # a glassy sea's ripples still span a band
    band = og >= detail_lo
    total_s = float(np.trapezoid(s, omega_grid))
    mss_detail = sigma2 * (cdf_slope[-1] - np.interp(detail_lo, og, cdf_slope)) / total_s
    c = cdf_slope[band] - cdf_slope[band][0]
    detail = _band(og[band], c / max(c[-1], 1e-300), 0.0, 1.0, n_detail, mss_detail,
                   spectrum.azimuth_to, SPREADING_S, 0.5, rng, by_slope=True)
    if n_swell:
        ws = 2.0 * math.pi / swell_period
        grid = np.geomspace(0.7 * ws, 1.5 * ws, 400)
        ss = grid**-5.0 * np.exp(-1.25 * (ws / grid) ** 4) * 7.0 ** np.exp(-((grid - ws) ** 2) / (2 * 0.07**2 * ws**2))
        c = np.concatenate([[0.0], np.cumsum(0.5 * (ss[1:] + ss[:-1]) * np.diff(grid))])
        swell = _band(grid, c / c[-1], 0.0, 1.0, n_swell, (swell_hs / 4.0) ** 2, (swell_from + 180.0) % 360.0,
                      SWELL_SPREADING_S, 0.25, rng)
        mesh = WaveSet.concat(swell, mesh)
    return mesh, detail


def second_order_coefficient(waves: WaveSet) -> float:
    """α of the surface's second-order crest-trough asymmetry (surface.py): z₂ = ½|Σ a_i √(α k_i) e^{iθ_i}|²
    gives a height skewness λ₃ = 3 α σ ⟨√k⟩² (⟨√k⟩ = Σ a_i² √k_i / Σ a_i²: the narrow-band kernel √(k_i k_j)).
    Second-order theory for a sea of finite spectral width (Tayfun & Fedele 2007) gives
    λ₃ = 3 σ k_m (1 − ν + ν²), k_m = ω_m²/g with ω_m = m₁/m₀ and the bandwidth ν = √(m₀ m₂/m₁² − 1)
    (0.30 for this JONSWAP mesh band): so α = k_m (1 − ν + ν²) / ⟨√k⟩², 0.79 here (λ₃ 0.12-0.17 at
    Beaufort 5-9). Deep-water wavenumbers (``waves`` before shoaling); 0 for a still sea."""
    e = waves.amplitude**2
    if waves.n == 0 or float(np.sum(e)) <= 0.0:
        return 0.0
    m0, m1, m2 = float(np.sum(e)), float(np.sum(e * waves.omega)), float(np.sum(e * waves.omega**2))
    nu = math.sqrt(max(m0 * m2 / m1**2 - 1.0, 0.0))
    k_m = (m1 / m0) ** 2 / G
    root_k = float(np.sum(e * np.sqrt(waves.k))) / m0
    return k_m * (1.0 - nu + nu * nu) / root_k**2


def cox_munk_mss(wind: float) -> float:
    """Mean-square slope of a wind-roughened sea (Cox & Munk 1954, clean surface)."""
    return 0.003 + 5.12e-3 * wind


def mean_square_slope(waves: WaveSet) -> float:
    return float(np.sum((waves.k * waves.amplitude) ** 2) / 2.0)


def calibrate_detail(mesh: WaveSet, detail: WaveSet, wind: float) -> WaveSet:
    """Scale the detail band so mesh + detail slopes have the Cox–Munk mean-square slope."""
    want = max(cox_munk_mss(wind) - mean_square_slope(mesh), 0.25 * cox_munk_mss(0.0))
    have = mean_square_slope(detail)
    if detail.n == 0:
        return detail
    if have <= 0.0:  # wind 0: capillary ripples with the shape of a 1 m/s sea
        amplitude = 1.0 / detail.k
        have = float(np.sum((detail.k * amplitude) ** 2) / 2.0)
    else:
        amplitude = detail.amplitude
    return WaveSet(detail.omega, detail.k, detail.direction, amplitude * math.sqrt(want / have), detail.phase)
