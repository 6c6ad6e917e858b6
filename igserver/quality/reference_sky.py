"""Float64 reference sky for the precomputed tables: per wavelength (the R, G, B channels at 610,
550, 440 nm), brute-force ray marching of the same atmosphere (atmosphere_model.py).

  L(x, v) = L_1(x, v) + L_ms(x, v)

* Single scattering L_1, exact up to quadrature: the view ray is marched to the top (or the
  ground) with 240 samples squeezed toward the observer; at each sample the sun's optical depth is
  integrated along its own ray with 240 samples (earth-blocked rays give zero), the view ray's
  optical depth is a cumulative trapezoid. No table, no float32, no parameterisation.
* Multiple scattering L_ms (orders >= 2): taken from the GPU tables at moderate size with many
  orders, as (full - single) of those tables. Multiple scattering is smooth in every angle, so
  table resolution errors concentrate in single scattering (aureole, horizon, terminator), which
  the reference computes exactly. This is the reference's documented limitation: it does not
  check the orders >= 2 of the high preset themselves.
"""

from __future__ import annotations

import math

import numpy as np

from ..render.sky.atmosphere_model import SOLAR_ILLUMINANCE, AtmosphereParameters, optical_depth_to_top


def rayleigh_phase(nu):
    return 3.0 / (16.0 * math.pi) * (1.0 + nu * nu)


def mie_phase(g, nu):
    k = 3.0 / (8.0 * math.pi) * (1.0 - g * g) / (2.0 + g * g)
    return k * (1.0 + nu * nu) / np.maximum(1.0 + g * g - 2.0 * g * nu, 1e-6) ** 1.5


def single_scattering(params: AtmosphereParameters, altitude_m: float, dirs: np.ndarray, sun_dir: np.ndarray,
                      samples: int = 240, chunk: int = 128) -> np.ndarray:
    """(N, 3) single-scattered radiance (cd/m^2) along unit ENU directions ``dirs``."""
    rg, rt = params.bottom_radius_km, params.top_radius_km
    r0 = rg + max(altitude_m, 1.0) / 1000.0
    cam = np.array([0.0, 0.0, r0])
    out = np.zeros((len(dirs), 3))
    beta_r = np.array(params.rayleigh_scattering_km)
    beta_m = np.array(params.mie_scattering_km)
    t = np.linspace(0.0, 1.0, samples + 1) ** 2
    for start in range(0, len(dirs), chunk):
        v = dirs[start:start + chunk]
        mu = v[:, 2]
        disc_b = (r0 * mu) ** 2 - (r0 - rg) * (r0 + rg)
        hits = (mu < 0) & (disc_b >= 0)
        d_ground = -r0 * mu - np.sqrt(np.maximum(disc_b, 0.0))
        d_top = -r0 * mu + np.sqrt(np.maximum((r0 * mu) ** 2 - (r0 - rt) * (r0 + rt), 0.0))
        length = np.where(hits, d_ground, d_top)  # km
        d = length[:, None] * t[None, :]  # (n, S+1)
        p = cam + d[..., None] * v[:, None, :]  # (n, S+1, 3)
        r = np.linalg.norm(p, axis=-1)
        h = r - rg
        ext = params.extinction_km(h)  # (n, S+1, 3)
        seg = 0.5 * (ext[:, 1:] + ext[:, :-1]) * np.diff(d, axis=1)[..., None]
        tau_view = np.concatenate([np.zeros((len(v), 1, 3)), np.cumsum(seg, axis=1)], axis=1)
        mu_s = (p @ sun_dir) / r
        # Sun blocked by the earth at the sample?
        disc_s = (r * mu_s) ** 2 - (r - rg) * (r + rg)
        blocked = (mu_s < 0) & (disc_s >= 0)
        tau_sun = optical_depth_to_top(params, r, mu_s, samples=samples)
        t_total = np.exp(-np.minimum(tau_view + tau_sun, 200.0)) * (~blocked)[..., None]
        rho_r = np.exp(-h / params.rayleigh_scale_height_km)[..., None]
        rho_m = params.mie_density(h)[..., None]
        nu = v @ sun_dir
        src = t_total * (beta_r * rho_r * rayleigh_phase(nu)[:, None, None]
                         + beta_m * rho_m * mie_phase(params.mie_g, nu)[:, None, None])
        out[start:start + chunk] = np.trapezoid(src, d[..., None], axis=1)
    return out * SOLAR_ILLUMINANCE


def zenith_double_scattering(params: AtmosphereParameters, sun_dir: np.ndarray, n_theta: int = 24,
                             n_view: int = 6, samples: int = 60) -> np.ndarray:
    """(3,) radiance scattered exactly twice (cd/m^2) that reaches an observer at 2 m looking at the
    zenith, by brute force in float64, independent of the tables:

      L_2 = int_0^top T(0, s) J(s) ds,   J(s) = sum_{R,M} beta(s) int_4pi P(w.z) L_in(s, w) dw,
      L_in = L_1(s, w) (single_scattering from altitude s)
             + [w hits the ground] T(s, g) albedo / pi * E_sun(g)   (Lambertian ground, direct sun).

    The sphere is a midpoint grid of n_theta zenith angles x 2 n_theta azimuths; the zenith column
    has n_view midpoint samples squeezed toward the ground (s = D u^2). Order 2 of the tables
    (the ground's direct-sun bounce is order 2 there too) is what this checks."""
    rg, rt = params.bottom_radius_km, params.top_radius_km
    h0 = 0.002
    th = (np.arange(n_theta) + 0.5) / n_theta * math.pi
    ph = (np.arange(2 * n_theta) + 0.5) / (2 * n_theta) * 2.0 * math.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    w = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    dw = (np.sin(T) * (math.pi / n_theta) * (math.pi / n_theta)).reshape(-1)
    phase_r = rayleigh_phase(w[:, 2]) * dw
    phase_m = mie_phase(params.mie_g, w[:, 2]) * dw
    beta_r, beta_m = np.array(params.rayleigh_scattering_km), np.array(params.mie_scattering_km)
    top = rt - rg - h0
    u = (np.arange(n_view) + 0.5) / n_view
    tau_up0 = optical_depth_to_top(params, np.array(rg + h0), np.array(1.0))
    t = np.linspace(0.0, 1.0, samples + 1)
    out = np.zeros(3)
    for s, ds in zip(top * u * u, top * 2.0 * u / n_view):
        h = h0 + s
        r0 = rg + h
        l_in = single_scattering(params, h * 1000.0, w, sun_dir, samples=samples) / SOLAR_ILLUMINANCE
        mu = w[:, 2]
        disc = (r0 * mu) ** 2 - (r0 - rg) * (r0 + rg)
        hits = (mu < 0) & (disc >= 0)
        g_dist = np.where(hits, -r0 * mu - np.sqrt(np.maximum(disc, 0.0)), 0.0)
        g = np.array([0.0, 0.0, r0]) + g_dist[:, None] * w
        mu_s_g = np.clip((g @ sun_dir) / np.linalg.norm(g, axis=-1), -1.0, 1.0)
        e_sun = np.exp(-optical_depth_to_top(params, np.full(len(w), rg), np.maximum(mu_s_g, 0.0), samples=samples))
        d = g_dist[:, None] * t
        rr = np.linalg.norm(np.array([0.0, 0.0, r0]) + d[..., None] * w[:, None, :], axis=-1)
        tau = np.trapezoid(params.extinction_km(rr - rg), d[..., None], axis=1)
        lit = (hits & (mu_s_g > 0))[:, None]
        l_in += np.where(lit, np.exp(-np.minimum(tau, 80.0)) * e_sun * params.ground_albedo / math.pi
                         * np.maximum(mu_s_g, 0.0)[:, None], 0.0)
        j = (beta_r * math.exp(-h / params.rayleigh_scale_height_km) * (phase_r @ l_in)
             + beta_m * float(params.mie_density(np.array(h))) * (phase_m @ l_in))
        t_view = np.exp(-(tau_up0 - optical_depth_to_top(params, np.array(r0), np.array(1.0))))
        out += t_view * j * ds
    return out * SOLAR_ILLUMINANCE
