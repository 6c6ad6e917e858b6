"""``igserver quality fog``: the analytic fog layer's multiple scattering against a float64 Monte
Carlo slab, and the cost of a visibility change.

Reference (brute force, float64): photons enter a plane-parallel, non-absorbing layer of optical
thickness tau* at the sun's cosine mu0, scatter with the Henyey-Greenstein phase of the layer (g),
reflect off a Lambertian ground of albedo A, and are followed until they leave the top. Scored:
  * F_down(ground) / (mu0 E): the horizontal illuminance under the layer (every downward crossing
    of the ground plane, i.e. including the light bounced between ground and layer),
  * R = F_up(top) / (mu0 E): the layer's brightness from above,
  * L_zenith(ground) pi / (mu0 E): the zenith radiance seen from under the layer (photons crossing
    the ground plane downward within 10 deg of the vertical, per solid angle and cosine).
The analytic values are those of sky/haze.py (the same formulas the shaders evaluate). Also
measured through the renderer: the frame time of the first frames after a visibility change
against the steady frame time (the first frame within 2x: a visibility change must not freeze a stream).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from ..render.sky.haze import GROUND_ALBEDO, HazeLayer, haze_layer

CASES = [  # (visibility m, layer top m, sun elevation deg)
    (1000.0, 100.0, 60.0), (200.0, 100.0, 60.0), (200.0, 300.0, 60.0), (100.0, 300.0, 60.0),
    (50.0, 300.0, 60.0), (200.0, 300.0, 20.0),
]


def henyey_greenstein_cos(g: float, u: np.ndarray) -> np.ndarray:
    """Sample cos(theta) of the HG phase function from uniforms u (exact inversion)."""
    if abs(g) < 1e-6:
        return 1.0 - 2.0 * u
    s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    return (1.0 + g * g - s * s) / (2.0 * g)


def rotate(mu: np.ndarray, cos_t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """New direction cosine to the vertical after scattering by (theta, phi) from mu."""
    sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
    sin_mu = np.sqrt(np.maximum(1.0 - mu * mu, 0.0))
    return np.clip(mu * cos_t + sin_mu * sin_t * np.cos(phi), -1.0, 1.0)


def monte_carlo_slab(tau_star: float, mu0: float, g: float, albedo: float = GROUND_ALBEDO,
                     photons: int = 200_000, seed: int = 1, zenith_cone_deg: float = 10.0) -> dict:
    """Float64 Monte Carlo of a conservative slab over a Lambertian ground (vertical coordinate in
    optical depth from the top, 0..tau*; mu > 0 means travelling DOWN)."""
    rng = np.random.default_rng(seed)
    tau = np.zeros(photons)
    mu = np.full(photons, mu0)
    alive = np.ones(photons, dtype=bool)
    down_at_ground = 0.0
    up_at_top = 0.0
    zenith_hits = 0.0
    cos_cone = math.cos(math.radians(zenith_cone_deg))
    for _ in range(100_000):
        idx = np.nonzero(alive)[0]
        if len(idx) == 0:
            break
        t, m = tau[idx], mu[idx]
        step = -np.log(1.0 - rng.random(len(idx)))  # optical path to the next event
        new = t + step * m
        hit_ground = new >= tau_star
        leave_top = new <= 0.0
        inside = ~(hit_ground | leave_top)
        # Ground: score the downward crossing, reflect (Lambertian: mu = -sqrt(u)) or absorb.
        g_idx = idx[hit_ground]
        down_at_ground += len(g_idx)
        zenith_hits += np.count_nonzero(mu[g_idx] >= cos_cone)
        refl = rng.random(len(g_idx)) < albedo
        tau[g_idx] = tau_star
        mu[g_idx[refl]] = -np.sqrt(rng.random(np.count_nonzero(refl)))
        alive[g_idx[~refl]] = False
        t_idx = idx[leave_top]
        up_at_top += len(t_idx)
        alive[t_idx] = False
        s_idx = idx[inside]
        tau[s_idx] = new[inside]
        cos_t = henyey_greenstein_cos(g, rng.random(len(s_idx)))
        mu[s_idx] = rotate(mu[s_idx], cos_t, rng.random(len(s_idx)) * 2 * math.pi)
    n = float(photons)
    cone_solid_angle = 2 * math.pi * (1 - cos_cone)
    mean_cos = 0.5 * (1 + cos_cone)
    return {
        "down_ground": down_at_ground / n,
        "reflectance": up_at_top / n,
        # radiance * pi / (mu0 E): photons per (solid angle * cosine), times pi
        "zenith_radiance": zenith_hits / n / (cone_solid_angle * mean_cos) * math.pi,
        "std_down": math.sqrt(down_at_ground) / n,
    }


def analytic_slab(layer: HazeLayer, mu0: float) -> dict:
    """The same three quantities from the analytic layer (sky/haze.py) for a unit sun, no sky."""
    sun = np.ones(3)
    below = layer.fluxes(0.0, sun, mu0, np.zeros(3))
    above = layer.fluxes(layer.top + 20 * layer.edge, sun, mu0, np.zeros(3))
    # Zenith radiance from the ground: the layer's source looking up, gathered at the effective
    # height of haze_effective_height() (half the first optical depth's run), times 1 - T.
    beta = float(layer.beta[1])
    h_e = 0.5 / beta
    f = layer.fluxes(min(h_e, layer.top), sun, mu0, np.zeros(3))
    up_dir = np.array([[0.0, 0.0, 1.0]])
    sun_dir = np.array([math.sqrt(1 - mu0 * mu0), 0.0, mu0])
    src = layer.source(min(h_e, layer.top), up_dir, f, sun_dir, sun, np.array([0, 0, -1.0]), np.zeros(3))[0]
    tau_star = float(layer.tau_above(0.0)[1])
    zenith = src[1] * (1 - math.exp(-tau_star)) * math.pi / mu0
    return {"down_ground": float(below["down"][1] / mu0), "reflectance": float(above["up"][1] / mu0),
            "zenith_radiance": float(zenith)}


def run(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="igserver quality fog", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="out/quality", help="directory for fog.md / fog.json")
    ap.add_argument("--photons", type=int, default=200_000)
    ap.add_argument("--no-render", action="store_true", help="skip the frame-time part (no GL)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for vis, top, el in CASES:
        layer = haze_layer(vis, 2.0, top, 0.0)
        layer = HazeLayer(beta=layer.beta, top=layer.top, edge=1e-3, g=layer.g, omega=1.0)  # sharp top
        mu0 = math.sin(math.radians(el))
        tau_star = float(layer.tau_above(0.0)[1])
        t0 = time.perf_counter()
        mc = monte_carlo_slab(tau_star, mu0, layer.g, photons=args.photons)
        mc_s = time.perf_counter() - t0
        an = analytic_slab(layer, mu0)
        row = {"visibility_m": vis, "top_m": top, "sun_elevation": el, "tau": round(tau_star, 2), "g": layer.g,
               "mc_seconds": round(mc_s, 1)}
        for k in ("down_ground", "reflectance", "zenith_radiance"):
            row[f"mc_{k}"] = round(mc[k], 4)
            row[f"analytic_{k}"] = round(an[k], 4)
            row[f"rel_err_{k}"] = round(an[k] / max(mc[k], 1e-12) - 1.0, 3)
        rows.append(row)
        print(json.dumps(row))
    timing = None if args.no_render else _frame_times()
    (out / "fog.json").write_text(json.dumps({"slab": rows, "frame_times": timing}, indent=1))
    lines = ["# Fog: analytic layer vs float64 Monte Carlo slab", "",
             f"{args.photons} photons per case, ground albedo {GROUND_ALBEDO}, no sky light (unit sun).", "",
             "| V (m) | top (m) | sun | tau | F_down MC | analytic | err | R MC | analytic | err | L_zen MC | analytic | err |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['visibility_m']:.0f} | {r['top_m']:.0f} | {r['sun_elevation']:.0f} | {r['tau']} | "
                     f"{r['mc_down_ground']} | {r['analytic_down_ground']} | {r['rel_err_down_ground']:+.0%} | "
                     f"{r['mc_reflectance']} | {r['analytic_reflectance']} | {r['rel_err_reflectance']:+.0%} | "
                     f"{r['mc_zenith_radiance']} | {r['analytic_zenith_radiance']} | {r['rel_err_zenith_radiance']:+.0%} |")
    if timing:
        lines += ["", "Frame time through a visibility ramp 20 km -> 100 m in 50 steps (160x90, sim_time +1/30 s "
                  f"per frame): median {timing['median_ms']:.1f} ms, max {timing['max_ms']:.1f} ms "
                  f"(first frame after each change; no table rebuild: {timing['table_builds']} builds)."]
    (out / "fog.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def _frame_times() -> dict:
    from ..render.renderer import Renderer
    from ..render.sky.tables import AtmosphereTables
    from ..scene.model import Scene

    r = Renderer()
    try:
        base = {"camera": {"width": 160, "height": 90, "pitch": 5.0},
                "time": {"sun_override": {"elevation": 30.0, "azimuth": 180.0}}}
        r.render(Scene.model_validate(base))
        tables = AtmosphereTables._resident.get(r.ctx)
        times = []
        for i, vis in enumerate(np.geomspace(20_000.0, 100.0, 50)):
            s = Scene.model_validate({**base, "time": {**base["time"], "sim_time": i / 30.0},
                                      "atmosphere": {"visibility": float(vis)}})
            t0 = time.perf_counter()
            r.render(s)
            times.append((time.perf_counter() - t0) * 1e3)
        builds = int(AtmosphereTables._resident.get(r.ctx) is not tables)
        return {"median_ms": float(np.median(times)), "max_ms": float(np.max(times)), "table_builds": builds}
    finally:
        r.release()
