"""The physical atmosphere the precomputed tables, the CPU lighting and the reference all share.

Lengths inside the atmosphere model are in **kilometres** (Bruneton's convention: coefficients of
order 1e-2 /km instead of 1e-5 /m); everything the rest of igserver sees is in metres.

Composition (a spherically symmetric shell between the bottom radius R_g and the top R_t):

  beta_R(h)  = beta_R0 * exp(-h / H_R)                      Rayleigh, pure scattering, lambda^-4
  beta_M(h)  = beta_M0 * [exp(-h / H_M) + k_ft rho_ft(h) + k_st rho_st(h)]   aerosol (Mie), albedo 0.9, g = 0.8
  beta_O3(h) = beta_O0 * max(0, 1 - |h - 25 km| / 15 km)     ozone absorption (Chappuis band)

The tables hold the CLEAR air only, fixed per turbidity class (so a new visibility never rebuilds
them): Rayleigh, ozone and a thin background aerosol whose ground extinction and layer depth follow
the surface-layer turbidity, quantised to classes of TURBIDITY_STEP so nearby values share tables:

  beta_M0(550 nm) = BACKGROUND_AEROSOL_550 * turbidity / 2,    H_M = 1.2 km * turbidity / 2,

with an Angstrom law (lambda / 550 nm)^-1.3, plus the turbidity-independent BACKGROUND aerosol that
every clear sky has above the boundary layer (same particles' optics, own profiles):
  free troposphere  rho_ft(h) = exp(-h / 3 km) - exp(-h / 1.2 km)   (zero at the ground, peak at 1.8 km)
                    column tau_ft(550) = 0.03;
  stratosphere      rho_st(h) = max(0, 1 - |h - 20 km| / 8 km)      (the Junge sulphate layer, 12-28 km)
                    column tau_st(550) = 0.006 (volcanically quiescent, SAGE II 1998-2004).
They barely change the day sky (vertical optical depth +0.036), but twilight is lit by sunlight
that grazes the earth with tangent heights of 5-25 km, through 30-40 air masses of exactly these
layers: without them the -6 deg sky was ~1.3x too bright (float64 single scattering: horizontal
illuminance 5.2 -> 4.0 lx, zenith 0.62 -> 0.46 cd/m^2; `igserver quality light`). Neither touches the
ground extinction, so the visibility the haze layer adds up to stays as it was.
Whatever the host's visibility V asks beyond that
(Koschmieder, sigma(0) = 3.912 / V) is carried by the analytic near-ground fog/haze layer of
sky/haze.py, evaluated per frame and per pixel, never baked into a table.

Radiance in the tables is per unit solar irradiance at the top of the atmosphere (sr^-1); the
renderer multiplies by SOLAR_ILLUMINANCE (lux per RGB channel) to get cd/m^2 per channel.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ...photometry import LUMA
# The R, G, B channels. R sits at 610 nm, near the dominant wavelength of the sRGB red primary (611
# nm) and inside the ozone Chappuis band (peak 600 nm), where the red a display shows is actually
# absorbed: at Bruneton's 680 nm the red channel saw 1/3.6 of that absorption, and the twilight sky,
# lit through 30-40 air masses of the ozone layer, came out red-magenta (at -6 deg R = 2x G in the
# horizontal illuminance) instead of the blue that the Chappuis band gives it (Hulburt 1953, JOSA 43,
# 113), and ~1.2x too bright.
WAVELENGTHS_NM = np.array([610.0, 550.0, 440.0])
# Solar illuminance above the atmosphere, lux per channel: 128 klx, slightly warm white (Y = 1).
_SUN_TINT = np.array([1.0, 0.985, 0.96])
SOLAR_ILLUMINANCE = 128_000.0 * _SUN_TINT / float(np.dot(LUMA, _SUN_TINT))
SUN_ANGULAR_RADIUS = 0.004675  # rad (0.2679 deg)
KOSCHMIEDER = 3.912  # -ln(0.02)
# Ground extinction of the tables' background aerosol at turbidity 2 (1/km at 550 nm): with the
# Rayleigh 0.0136 /km the clear tables alone see ~200 km, the longest visibility the model accepts.
BACKGROUND_AEROSOL_550 = 0.005
TURBIDITY_STEP = 0.5
# Background aerosol above the boundary layer (optical depths at 550 nm; see the module docstring).
FREE_TROPOSPHERE_AEROSOL_TAU = 0.03
FREE_TROPOSPHERE_SCALES_KM = (3.0, 1.2)  # rho_ft = exp(-h/a) - exp(-h/b): column a - b
STRATOSPHERIC_AEROSOL_TAU = 0.006
STRATOSPHERIC_LAYER_KM = (20.0, 8.0)  # centre, half width of the tent (column = half width)
# Bumped whenever the layout or meaning of a cached table changes (part of the cache key).
TABLE_FORMAT_VERSION = 3


@dataclass(frozen=True)
class TableSizes:
    """Quality knobs: table resolutions, scattering orders and integration sample counts."""

    transmittance: tuple[int, int] = (128, 32)  # (mu, r)
    irradiance: tuple[int, int] = (128, 8)  # (sun elevation, r): 0.9 deg per column
    r: int = 16
    mu: int = 64
    mu_s: int = 32  # twilight: 16 leaves steps of up to 10x per degree in zenith luminance
    nu: int = 8
    orders: int = 4
    density_samples: int = 16  # theta samples of the scattering density sphere (phi: 2x); twilight needs 16

    @property
    def scattering(self) -> tuple[int, int, int]:
        """3D texture size: (nu * mu_s, mu, r)."""
        return (self.nu * self.mu_s, self.mu, self.r)


PRESETS: dict[str, TableSizes] = {
    "low": TableSizes((64, 16), (64, 8), 8, 32, 16, 8, 2, 6),
    "medium": TableSizes(),
    "high": TableSizes((256, 64), (256, 16), 32, 128, 64, 8, 6, 16),
}


@dataclass(frozen=True)
class AtmosphereParameters:
    bottom_radius_km: float = 6360.0
    top_radius_km: float = 6460.0  # 100 km: twilight down to -18 deg is lit from 60-100 km
    # Rayleigh: 1.24062e-3 / lambda(um)^4 per km (Bruneton's kRayleigh); at 610, 550, 440 nm.
    rayleigh_scattering_km: tuple[float, float, float] = (0.008960, 0.013558, 0.0331)
    rayleigh_scale_height_km: float = 8.0
    mie_scattering_km: tuple[float, float, float] = (0.0036, 0.0036, 0.0036)
    mie_extinction_km: tuple[float, float, float] = (0.004, 0.004, 0.004)
    mie_scale_height_km: float = 1.2
    mie_g: float = 0.8
    # (k_ft, k_st): the background aerosol's free-tropospheric and stratospheric profiles, as
    # multiples of the boundary-layer coefficient beta_M0 (same optics, see mie_density()).
    mie_background: tuple[float, float] = (0.0, 0.0)
    # Ozone: 300 DU in the tent (peak number density 5.374e18 m^-3) times the cross-sections of
    # the IUP Bremen 233 K spectra averaged over 10-nm bins (as in Bruneton's demo): 4.305e-25 m^2
    # (610-620 nm), 3.5e-25 (550-560), 1.582e-26 (440-450).
    ozone_absorption_km: tuple[float, float, float] = (0.002314, 0.001881, 0.000085)
    ground_albedo: float = 0.1
    # cos of the largest sun zenith angle in the tables: 110 deg, past astronomical twilight (108 deg).
    mu_s_min: float = -0.342
    sizes: TableSizes = field(default_factory=TableSizes)

    def uniforms(self) -> dict:
        """GLSL uniforms of common/atmosphere.glsl and the precompute shaders."""
        return {
            "u_bottom_radius_km": self.bottom_radius_km,
            "u_top_radius_km": self.top_radius_km,
            "u_rayleigh_scattering_km": self.rayleigh_scattering_km,
            "u_rayleigh_scale_height_km": self.rayleigh_scale_height_km,
            "u_mie_scattering_km": self.mie_scattering_km,
            "u_mie_extinction_km": self.mie_extinction_km,
            "u_mie_scale_height_km": self.mie_scale_height_km,
            "u_mie_g": self.mie_g,
            "u_mie_background": self.mie_background,
            "u_ozone_absorption_km": self.ozone_absorption_km,
            "u_ground_albedo": self.ground_albedo,
            "u_mu_s_min": self.mu_s_min,
            "u_scattering_nu_size": self.sizes.nu,
            "u_scattering_mu_s_size": self.sizes.mu_s,
        }

    def key(self, shader_source: str = "") -> str:
        """Cache key: the parameters, table sizes, orders and the precompute shader source."""
        blob = json.dumps({**asdict(self), "format": TABLE_FORMAT_VERSION}, sort_keys=True) + shader_source
        return hashlib.sha256(blob.encode()).hexdigest()[:24]

    # --- float64 profiles (the GLSL mirrors these) ---------------------------------------------
    def mie_density(self, h_km: np.ndarray) -> np.ndarray:
        """Aerosol density relative to the boundary layer's ground value (mie_density() in GLSL)."""
        h = np.maximum(np.asarray(h_km, dtype=np.float64), 0.0)
        a, b = FREE_TROPOSPHERE_SCALES_KM
        c, w = STRATOSPHERIC_LAYER_KM
        return (np.exp(-h / self.mie_scale_height_km) + self.mie_background[0] * (np.exp(-h / a) - np.exp(-h / b))
                + self.mie_background[1] * np.maximum(0.0, 1.0 - np.abs(h - c) / w))

    def extinction_km(self, h_km: np.ndarray) -> np.ndarray:
        """(..., 3) extinction coefficient at altitude h (km)."""
        h = np.asarray(h_km, dtype=np.float64)[..., None]
        rayleigh = np.array(self.rayleigh_scattering_km) * np.exp(-h / self.rayleigh_scale_height_km)
        mie = np.array(self.mie_extinction_km) * self.mie_density(h)
        ozone = np.array(self.ozone_absorption_km) * np.maximum(0.0, 1.0 - np.abs(h - 25.0) / 15.0)
        return rayleigh + mie + ozone


def turbidity_class(turbidity: float) -> float:
    """Quantise the turbidity to its table class (steps of TURBIDITY_STEP within 1..10)."""
    return float(min(max(round(turbidity / TURBIDITY_STEP) * TURBIDITY_STEP, 1.0), 10.0))


def atmosphere_parameters(turbidity: float = 2.0, ozone: bool = True, sizes: TableSizes | None = None,
                          orders: int | None = None) -> AtmosphereParameters:
    """Clear-air table parameters for a turbidity class (visibility is the haze layer's business)."""
    sizes = sizes or TableSizes()
    if orders is not None:
        sizes = TableSizes(**{**asdict(sizes), "orders": int(orders)})
    t = turbidity_class(turbidity)
    angstrom = (WAVELENGTHS_NM / 550.0) ** -1.3
    mie_extinction = BACKGROUND_AEROSOL_550 * t / 2.0 * angstrom

    def r4(v):
        return tuple(float(f"{x:.4g}") for x in v)
    beta_m0 = BACKGROUND_AEROSOL_550 * t / 2.0  # 1/km at 550 nm, the boundary layer at the ground
    a, b = FREE_TROPOSPHERE_SCALES_KM
    k_ft = FREE_TROPOSPHERE_AEROSOL_TAU / (beta_m0 * (a - b))
    k_st = STRATOSPHERIC_AEROSOL_TAU / (beta_m0 * STRATOSPHERIC_LAYER_KM[1])
    return AtmosphereParameters(
        mie_scattering_km=r4(0.9 * mie_extinction),
        mie_extinction_km=r4(mie_extinction),
        mie_scale_height_km=float(f"{1.2 * t / 2.0:.4g}"),
        mie_background=(float(f"{k_ft:.4g}"), float(f"{k_st:.4g}")),
        ozone_absorption_km=AtmosphereParameters.ozone_absorption_km if ozone else (0.0, 0.0, 0.0),
        sizes=sizes,
    )


def ground_extinction_550_per_m(params: AtmosphereParameters) -> float:
    """Extinction of the clear-air tables at the ground, 550 nm (1/m)."""
    return float(params.extinction_km(np.array(0.0))[1]) / 1000.0


def optical_depth_to_top(params: AtmosphereParameters, r_km: np.ndarray, mu: np.ndarray,
                         samples: int = 400) -> np.ndarray:
    """(..., 3) optical depth from radius r along direction cosine mu to the top (float64, trapezoid
    with samples concentrated near the start: d_i = D (i/N)^2, where the density is highest)."""
    r = np.asarray(r_km, dtype=np.float64)
    mu = np.asarray(mu, dtype=np.float64)
    rt = params.top_radius_km
    disc = r * r * (mu * mu - 1.0) + rt * rt
    dist = np.maximum(-r * mu + np.sqrt(np.maximum(disc, 0.0)), 0.0)
    t = (np.linspace(0.0, 1.0, samples + 1) ** 2)
    d = dist[..., None] * t  # (..., N+1)
    rr = np.sqrt(d * d + 2.0 * r[..., None] * mu[..., None] * d + r[..., None] ** 2)
    ext = params.extinction_km(rr - params.bottom_radius_km)  # (..., N+1, 3)
    return np.trapezoid(ext, d[..., None], axis=-2)


def sun_transmittance(params: AtmosphereParameters, altitude_m: float, sun_elevation_deg: float) -> np.ndarray:
    """RGB transmittance of the direct sun at an observer, including the disk setting behind the
    horizon over its own diameter (the geometric horizon dips with altitude)."""
    rg = params.bottom_radius_km
    r = rg + max(altitude_m, 1.0) / 1000.0
    mu_s = math.sin(math.radians(sun_elevation_deg))
    mu_horizon = -math.sqrt(max(1.0 - (rg / r) ** 2, 0.0))
    a = SUN_ANGULAR_RADIUS * rg / r
    visible = float(np.clip((mu_s - mu_horizon + a) / (2 * a), 0.0, 1.0))
    if visible == 0.0 or r >= params.top_radius_km:
        return np.full(3, visible)
    tau = optical_depth_to_top(params, np.array(r), np.array(max(mu_s, mu_horizon + 1e-6)))
    return np.exp(-np.minimum(tau, 80.0)) * visible
