"""Near-ground fog and haze: an analytic, height-dependent layer over the clear-air tables.

The clear-air tables (atmosphere_model.py) are fixed per turbidity class; the host's visibility V
lives here, so a new V costs a few uniforms, never a table rebuild. Heights h are metres above the
scene's ground (``location.altitude``); the mirror in common/atmosphere.glsl (haze_*) computes the
same quantities per pixel.

Extinction (Koschmieder): the layer adds what the clear air lacks at the ground,
    beta(550 nm) = max(3.912 / V - beta_clear(0), 0)          1/m,
    beta(lambda) = beta(550) (lambda / 550 nm)^-alpha,
with alpha, the asymmetry g and the single-scattering albedo omega going from droplet fog
(V <= 1 km: alpha = 0, g = 0.85, omega = 1: neutral) to haze (V >= 10 km: alpha = 1.3, g = 0.7,
omega = 0.9), log-linearly in V between.

Density profile: rho(h) = 1 up to the top t, exp(-(h - t) / H_e) above. ``atmosphere.fog_top`` set:
a fog layer with its top at t and an edge H_e = max(0.1 t, 5 m); unset: haze, t = 0 and H_e the
turbidity's aerosol scale height (1.2 km * turbidity / 2). The column above h is closed-form:
    C(h) = integral_h^inf rho = (t - h) + H_e  (h <= t),   H_e exp(-(h - t) / H_e)  (h > t),
so the optical depth of any straight segment is beta d (C(h0) - C(h1)) / (h1 - h0).

Light inside the layer (multiple scattering, two-stream/diffusion with delta-scaling, checked
against a float64 Monte Carlo slab in ``igserver quality fog``): for optical depth tau above h,
a beam at cosine mu0 arrives as
    T(tau, mu0) = t_d + (1 - t_d) b0 / (1 + c tau),   t_d = exp(-(1 - g^2) tau / mu0),
    b0 = 1/2 + 3/4 g' mu0 (g' = g / (1 + g)),   c = 3/4 (1 - g) b0 / (1/2 + 3/4 mu0),
the single-scattering limit for thin layers (the forward part b0 of what is scattered goes on
down) and the diffusion limit (1/2 + 3/4 mu0) / (3/4 (1 - g) tau) for thick ones. Sky light uses
mu0 = 1/2. The part below h reflects r_d = 1 - T(tau_below, 1/2) plus the ground (albedo A) seen
through it; up and down fluxes at h follow by adding the two parts (one geometric series).
The in-scattered radiance toward the eye is the source
    S(h, v) = omega [ E_beam(h) p_HG(nu) + (F_up (1 - v_z) / 2 + F_down_diffuse (1 + v_z) / 2) / pi ]
(a viewer looking down sees light going up), taken at an effective height along the ray, and
L_in = S (1 - exp(-tau_ray)). The shaders add omega A(h, v), the lobe: the clear sky's light that
reaches h straight through the layer, scattered by p_HG instead of isotropically, less the same light
as the isotropic term holds it (sky/haze_lobe.glsl haze_sky_lobe, tabulated by haze_lobe.py; zero
for an isotropic sky; over a sea, sea_mss >= 0, also the sky the sea mirrors into the layer). It
needs the clear sky's radiance per direction, which this module does not have: source() here is the
isotropic model (the CPU exposure estimate's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from .atmosphere_model import KOSCHMIEDER, WAVELENGTHS_NM

FOG_VISIBILITY_M = 1_000.0
HAZE_VISIBILITY_M = 10_000.0
EARTH_RADIUS_M = 6_360_000.0
GROUND_ALBEDO = 0.1
HAZE_TABLE_SIZE = 64  # heights in the per-frame light table of the layer
SKY_MU0 = 0.5  # diffuse incidence acts like a beam at 60 deg (diffusivity factor 2)


def _fog_fraction(visibility_m: float) -> float:
    """1 for droplet fog (V <= 1 km), 0 for haze (V >= 10 km), log-linear between."""
    x = (math.log10(visibility_m) - math.log10(FOG_VISIBILITY_M)) / (
        math.log10(HAZE_VISIBILITY_M) - math.log10(FOG_VISIBILITY_M))
    return 1.0 - min(max(x, 0.0), 1.0)


@dataclass(frozen=True)
class HazeLayer:
    beta: np.ndarray  # (3,) 1/m, extinction in the dense part (R, G, B)
    top: float  # m above the ground
    edge: float  # m, scale height above the top
    g: float
    omega: float
    # Albedo of the surface under the layer: what the light going down comes back up as. Snow
    # under a snowfall (0.8) fills the layer with nearly as much light going up as down, so the
    # whiteout's horizon is as bright as its zenith; over 0.1 it was 0.55x as bright (a dark band).
    albedo: float = GROUND_ALBEDO
    # Mean-square slope of a sea under the layer (Cox & Munk), -1 over land: a sea mirrors the
    # sky's light into the layer from below (the lobe, sky/haze_lobe.glsl haze_sky_lobe), a land
    # surface's reflection stays the two-stream's isotropic upwelling.
    sea_mss: float = -1.0

    def __post_init__(self):
        # The layer's own read-only copy of its extinction: the key below is computed once.
        beta = np.array(self.beta)
        beta.flags.writeable = False
        object.__setattr__(self, "beta", beta)

    @cached_property
    def key(self) -> tuple:
        """Every field, exactly: what a value derived from the layer is cached under (a field added
        here joins every such key by itself). The layer is immutable, so it is found once."""
        return tuple(v.tobytes() if isinstance(v, np.ndarray) else v for v in
                     (getattr(self, f.name) for f in fields(self)))

    # --- profile ------------------------------------------------------------------------------
    def density(self, h):
        h = np.asarray(h, dtype=np.float64)
        return np.where(h <= self.top, 1.0, np.exp(-np.minimum(np.maximum(h - self.top, 0.0) / self.edge, 80.0)))

    def column(self, h):
        """Integral of the density from h to infinity (m). Both exponents stop at 80 edges, as in the
        shader's haze_density() and haze_column(): column / density (the local scale length) stays the
        edge at any height, where two underflows gave 0 / 0 from ~745 edges up (a sun below the
        horizon seen from 10,000 km: a NaN sun-disk luminance, passed to the shaders)."""
        h = np.asarray(h, dtype=np.float64)
        return np.where(h <= self.top, self.top - h + self.edge,
                        self.edge * np.exp(-np.minimum(np.maximum(h - self.top, 0.0) / self.edge, 80.0)))

    def tau_above(self, h) -> np.ndarray:
        return np.asarray(self.column(h))[..., None] * self.beta

    def slant_mu(self, mu: float, h) -> np.ndarray:
        """The cosine that turns tau_above(h) into a beam's optical depth from the sky down to h on
        the round earth. For an exponential layer of scale length H the path is Chapman's
        sqrt(pi x / 2) erfcx(sqrt(x / 2) mu), x = R / H; erfcx(y) ~ 2 / (sqrt(pi) (y + sqrt(y^2 + 4 /
        pi))) (its upper bound, within 2 %) makes that 1 / slant_mu with
            slant_mu = (mu + sqrt(mu^2 + 8 H / (pi R))) / 2,
        exact overhead and at the horizon (sqrt(pi R / 2H) airmasses), H = column / density the
        layer's local scale length. Flat, tau / mu grows without bound as the sun sets: at 1 deg
        through the haze it was 1.37x the sphere's path, so the low haze got 7-9x too little sun at
        sunrise (30 km visibility). Shape (..., 1) for array h (it broadcasts against tau's RGB)."""
        h = np.asarray(h, dtype=np.float64)
        scale = self.column(h) / np.maximum(self.density(h), 1e-12)
        mu = max(mu, 0.0)
        return (0.5 * (mu + np.sqrt(mu * mu + 8.0 * scale / (math.pi * EARTH_RADIUS_M))))[..., None]

    def tau_below(self, h) -> np.ndarray:
        return (self.column(0.0) - np.asarray(self.column(h)))[..., None] * self.beta

    # --- two-stream light --------------------------------------------------------------------------
    def transmission(self, tau, mu0):
        """Total (direct + diffuse) downward flux fraction of a beam at cosine mu0 through tau (mu0 a
        beam's slant_mu: its path's cosine, scalar or broadcasting against tau)."""
        g = self.g
        mu0 = np.maximum(mu0, 1e-3)
        t_d = np.exp(-np.minimum((1.0 - g * g) * tau / mu0, 80.0))
        b0 = 0.5 + 0.75 * g / (1.0 + g) * mu0
        c = 0.75 * (1.0 - g) * b0 / (0.5 + 0.75 * mu0)
        return t_d + (1.0 - t_d) * b0 / (1.0 + c * tau)

    def reflectance_below(self, tau_below, mu0: float = SKY_MU0):
        """Reflectance of the layer below a height plus the ground seen through it, for light
        arriving at cosine mu0 (SKY_MU0: diffuse)."""
        t_beam = self.transmission(tau_below, mu0)
        t = self.transmission(tau_below, SKY_MU0)
        r = 1.0 - t
        a = self.albedo
        return (1.0 - t_beam) + t_beam * t * a / (1.0 - a * r)

    def fluxes(self, h: float, sun_normal, mu_s: float, sky_horizontal, moon_normal=(0.0, 0.0, 0.0),
               mu_m: float = -1.0) -> dict:
        """Fluxes (lux, RGB) at height h under clear-air light arriving at the layer's top:
        down (total), up, beam_true (the visible sun/moon direct, horizontal), beam_delta (direct
        plus forward peak, the light that casts sharp shadows, horizontal)."""
        ta, tb = self.tau_above(h), self.tau_below(h)
        sun, moon, sky = np.asarray(sun_normal, float), np.asarray(moon_normal, float), np.asarray(sky_horizontal, float)
        ms, mm = max(mu_s, 0.0), max(mu_m, 0.0)
        slant_s, slant_m = self.slant_mu(ms, h), self.slant_mu(mm, h)  # the beams' paths on the sphere
        incoming = sun * ms * self.transmission(ta, slant_s) + sky * self.transmission(ta, SKY_MU0)
        incoming = incoming + moon * mm * self.transmission(ta, slant_m)
        r_below = self.reflectance_below(tb)
        r_above = 1.0 - self.transmission(ta, SKY_MU0)
        down = incoming / (1.0 - r_below * r_above)

        def beam(e, mu, slant, scale):
            return e * mu * np.exp(-np.minimum(scale * ta / slant, 80.0)) if mu > 0 else np.zeros_like(ta)
        beam_true = beam(sun, ms, slant_s, 1.0) + beam(moon, mm, slant_m, 1.0)
        sun_delta = beam(sun, ms, slant_s, 1.0 - self.g ** 2)
        moon_delta = beam(moon, mm, slant_m, 1.0 - self.g ** 2)
        # Up: the diffuse part reflects as diffuse light, each beam at its own angle.
        up = r_below * np.maximum(down - sun_delta - moon_delta, 0.0)
        up = up + self.reflectance_below(tb, max(ms, 1e-3)) * sun_delta + self.reflectance_below(tb, max(mm, 1e-3)) * moon_delta
        return {"down": down, "up": up, "beam_true": beam_true, "beam_delta": sun_delta + moon_delta}

    def tau_view(self, h0: float, dirs: np.ndarray) -> np.ndarray:
        """(N, 3) optical depth of whole view rays (mirror of haze_sky(): to the flat ground below,
        to space above over slant_mu, the beams' round-earth path)."""
        z = np.asarray(dirs, float)[:, 2]
        c = float(self.column(h0))
        hc = c / max(float(self.density(h0)), 1e-6)
        zp = np.maximum(z, 0.0)
        up = 2.0 * c / (zp + np.sqrt(zp * zp + 8.0 * hc / (math.pi * EARTH_RADIUS_M)))
        below = float(self.column(0.0)) - c  # column between the ground and the camera
        down = below / np.maximum(-z, 1e-9) if h0 > 0.0 else np.full_like(z, np.inf)
        col = np.where(z >= 0.0, up, down)
        return np.minimum(col[:, None] * self.beta, 1e4)

    def source(self, h: float, dirs: np.ndarray, flux: dict, sun_dir, sun_normal, moon_dir, moon_normal) -> np.ndarray:
        """(N, 3) in-scattered radiance source S(h, dir) (cd/m^2), the mirror of haze_source_phased()."""
        dirs = np.asarray(dirs, float)
        ta = self.tau_above(h)
        w_down = 0.5 + 0.5 * dirs[:, 2:3]
        out = (flux["up"] * (1.0 - w_down) + np.maximum(flux["down"] - flux["beam_true"], 0.0) * w_down) / math.pi
        for d, e in ((sun_dir, sun_normal), (moon_dir, moon_normal)):
            mu = float(d[2])
            if mu > 0.0:
                out = out + np.asarray(e) * np.exp(-np.minimum(ta / self.slant_mu(mu, h), 80.0)) * hg_phase(
                    self.g, dirs @ np.asarray(d))[:, None]
        return self.omega * out

    def table_top(self) -> float:
        """Height (m) above which the layer no longer matters (density < exp(-8))."""
        return self.top + 8.0 * self.edge

    def source_table(self, sun_normal, mu_s: float, sky_horizontal, moon_normal, mu_m: float) -> np.ndarray:
        """(4, HAZE_TABLE_SIZE, 4) float32 per-frame table of the layer's light against height,
        0 .. table_top(): rows diffuse down, up, sun beam (normal), moon beam (normal), all before
        the single-scattering albedo; the shader's haze_source_terms() reads it instead of evaluating the
        two-stream model per pixel (the same formulas, tabulated once per frame)."""
        h = np.linspace(0.0, self.table_top(), HAZE_TABLE_SIZE)
        f = self.fluxes(h, sun_normal, mu_s, sky_horizontal, moon_normal, mu_m)
        ta = self.tau_above(h)
        out = np.zeros((4, HAZE_TABLE_SIZE, 4), np.float32)
        out[0, :, :3] = np.maximum(f["down"] - f["beam_true"], 0.0)
        out[1, :, :3] = f["up"]
        for row, (e, mu) in ((2, (sun_normal, mu_s)), (3, (moon_normal, mu_m))):
            if mu > 0.0:
                out[row, :, :3] = np.asarray(e) * np.exp(-np.minimum(ta / self.slant_mu(mu, h), 80.0))
        return out

    def uniforms(self, base_altitude_m: float) -> dict:
        return {
            "u_haze_beta": tuple(float(b) for b in self.beta),
            "u_haze_top": float(self.top),
            "u_haze_edge": float(self.edge),
            "u_haze_base": float(base_altitude_m),
            "u_haze_g": float(self.g),
            "u_haze_omega": float(self.omega),
            "u_haze_ground_albedo": float(self.albedo),
            "u_haze_table_top": float(self.table_top()),
            "u_haze_sea_mss": float(self.sea_mss),
        }


def haze_layer(visibility_m: float, turbidity: float, fog_top: float | None,
               clear_ground_extinction_per_m: float, ground_albedo: float = GROUND_ALBEDO,
               sea_mss: float = -1.0) -> HazeLayer:
    fog = _fog_fraction(visibility_m)
    alpha = 1.3 * (1.0 - fog)
    beta_550 = max(KOSCHMIEDER / visibility_m - clear_ground_extinction_per_m, 0.0)
    beta = beta_550 * (WAVELENGTHS_NM / 550.0) ** -alpha
    if fog_top is not None:
        top, edge = float(fog_top), max(0.1 * float(fog_top), 5.0)
    else:
        top, edge = 0.0, 1200.0 * turbidity / 2.0
    return HazeLayer(beta=beta, top=top, edge=edge, g=0.7 + 0.15 * fog, omega=0.9 + 0.1 * fog,
                     albedo=float(ground_albedo), sea_mss=float(sea_mss))


def hg_phase(g: float, nu) -> np.ndarray:
    """Henyey-Greenstein phase function (1/sr)."""
    nu = np.asarray(nu, dtype=np.float64)
    return (1.0 - g * g) / (4.0 * math.pi * np.maximum(1.0 + g * g - 2.0 * g * nu, 1e-6) ** 1.5)


class HazeTransition:
    """Eases the applied haze extinction toward the host's value so a visibility change never pops:
    log(beta) moves along a smoothstep over ``duration`` seconds of sim_time. The state lives in the
    renderer (one per render process). Why ease at all: the host may step V in large jumps, and a
    stream must not pop. Why sim_time: a frame is a function of the state the host sent and of the
    time it stands at (the IG clock runs sim_time in real time by itself); a frame at the same
    sim_time as the last (a paused clock, a re-render) shows the new state at once, so renders
    stay deterministic."""

    def __init__(self):
        self._from: np.ndarray | None = None
        self._to: np.ndarray | None = None
        self._progress = 1.0
        self._last_sim: float | None = None
        self._settled: tuple[np.ndarray, np.ndarray] | None = None  # (host's value, applied value) once settled

    def apply(self, target_beta: np.ndarray, duration: float, sim_time: float) -> np.ndarray:
        raw = np.asarray(target_beta, float)
        if self._settled is not None and self._progress >= 1.0 and np.array_equal(raw, self._settled[0]):
            # Settled on the same value (a stream whose haze does not change): the value it gave; from
            # a settled state every branch of _step gives it again.
            self._last_sim = sim_time
            return self._settled[1].copy()
        beta = self._step(raw, duration, sim_time)
        self._settled = (raw.copy(), beta) if self._progress >= 1.0 else None
        return beta

    def _step(self, raw: np.ndarray, duration: float, sim_time: float) -> np.ndarray:
        target = np.log(np.maximum(raw, 1e-12))
        if self._to is None or duration <= 0.0:
            self._from = self._to = target
            self._progress = 1.0
        else:
            dt = 0.0 if self._last_sim is None else sim_time - self._last_sim
            if dt <= 0.0 or dt > max(duration, 1.0):
                # Same instant (paused clock, re-render), time went back, or a gap longer than the
                # transition (not one continuous stream): the new state at once.
                self._progress = 1.0
                self._from = self._to = target
            else:
                self._progress = min(self._progress + dt / duration, 1.0)
            current = self._current()
            if not np.allclose(target, self._to, rtol=0.0, atol=1e-9):
                self._from, self._to, self._progress = current, target, 0.0
        self._last_sim = sim_time
        beta = np.exp(self._current())
        return np.where(beta < 1e-10, 0.0, beta)  # no layer left: the shaders skip it

    def _current(self) -> np.ndarray:
        p = self._progress
        s = p * p * (3.0 - 2.0 * p)
        return self._from + (self._to - self._from) * s

    @property
    def settled(self) -> bool:
        return self._progress >= 1.0
