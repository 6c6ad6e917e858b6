"""``igserver quality light``: light levels from noon to night against published clear-sky
measurements, across table sizes, next to precompute time and frame time.

For sun elevations +60 .. -24 deg (moonless: 2026-03-19 00:00 UTC at the default site, the sun set
by ``time.sun_override``), at the sea surface with the default atmosphere:
  * E_h, the natural horizontal illuminance the renderer reports (lux), against the AMS Glossary
    of Meteorology (entries "civil twilight" and "astronomical twilight"): ~410-585 lx at 0 deg,
    ~2-3.5 lx at -6 deg, ~0.008 lx at -12 deg, ~6e-4 lx of scattered sunlight at -18 deg (then
    below starlight + airglow, so the total there is the night floor, ~1e-3 lx);
  * L_z, the zenith luminance (cd/m^2) of sky_radiance(), against the V-band zenith twilight sky
    brightness of Patat, Ugolnikov & Postylyakov (2006, A&A 455, 385; ESO Paranal, 2600 m): the
    quadratic fit m_V(z) = 11.84 + 1.518 (z - 95) - 0.057 (z - 95)^2 mag/arcsec^2 for sun zenith
    distances 95..105 deg (they find a sea-level site ~30 % brighter, applied), converted with
    L = 10.8e4 10^(-0.4 m) cd/m^2. The coefficients were first written from memory; the paper's
    table could not be read here, so they are checked against the V-band zenith points digitised
    from the paper's figure by the LSST sky-brightness project (lsst-sims/legacy_sims_skybrightness,
    doc/PatatTwi/vband.dat, PATAT_V_DIGITISED below): within 0.16 mag over z = 99..105 deg
    (tests/test_atmosphere_light.py); the study reports both;
  * the smoothness: the largest ratio of E_h and of L_z between elevations 0.1 deg apart
    (0 .. -18 deg), the issue's bound being 1.25;
  * per table preset (low / medium / high): the same curves and their error against the high
    preset, the preset's precompute seconds (fresh, no cache) and the sky pass's ms per frame;
  * the per-frame sky-view table against evaluating the 4D tables per pixel
    (ATMOSPHERE_DIRECT_TABLES): relative error of L_z and of a 64 x 16 dome.
Writes light.md / light.json to --out.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from ..photometry import LUMA
from ..render.frame import build_frame
from ..render.renderer import Renderer
from ..render.shaders import GLSL_VERSION, expand, set_uniforms
from ..render.sky.tables import AtmosphereTables
from ..scene.model import Scene

MOONLESS_UTC = "2026-03-19T00:00:00Z"
FULL_MOON_UTC = "2026-03-04T00:00:00Z"  # moon 30 deg up, 99.7 % lit at the default site
ELEVATIONS = (60.0, 30.0, 10.0, 5.0, 2.0, 0.0, -2.0, -4.0, -6.0, -8.0, -10.0, -12.0, -14.0, -16.0, -18.0, -20.0,
              -24.0)
# AMS Glossary of Meteorology: clear-sky horizontal illuminance (lux) at the named sun elevations;
# the geometric middle of the glossary's ranges.
AMS_ILLUMINANCE = {0.0: math.sqrt(410.0 * 585.0), -6.0: math.sqrt(2.0 * 3.5), -12.0: 0.008, -18.0: 1.0e-3}


# (sun zenith distance deg, V mag/arcsec^2) at Paranal, digitised from Patat et al. (2006)'s V-band
# zenith figure by the LSST sky-brightness project (legacy_sims_skybrightness doc/PatatTwi/vband.dat;
# rounded to 0.01). Past 105 deg the night sky (21.5) takes over.
PATAT_V_DIGITISED = ((99.06, 17.04), (100.02, 17.86), (100.93, 18.72), (101.89, 19.51), (102.84, 20.25),
                     (103.75, 20.78), (104.82, 21.19), (106.78, 21.44), (108.41, 21.52), (110.89, 21.52))


def patat_v_mag(zenith_distance: float) -> float:
    """The quadratic V-band fit (mag/arcsec^2) at a sun zenith distance of 95..105 deg."""
    x = zenith_distance - 95.0
    return 11.84 + 1.518 * x - 0.057 * x * x


def patat_digitised_luminance(sun_elevation: float) -> float | None:
    """Zenith luminance (cd/m^2, +30 % sea level) interpolated in the digitised points (99..111 deg)."""
    z = 90.0 - sun_elevation
    zs, ms = zip(*PATAT_V_DIGITISED)
    if not zs[0] <= z <= zs[-1]:
        return None
    return 1.3 * 10.8e4 * 10.0 ** (-0.4 * float(np.interp(z, zs, ms)))


def patat_zenith_luminance(sun_elevation: float) -> float | None:
    """Zenith luminance (cd/m^2) from Patat et al. (2006), V band, sea-level corrected (+30 %)."""
    z = 90.0 - sun_elevation
    if not 95.0 <= z <= 105.0:
        return None
    return 1.3 * 10.8e4 * 10.0 ** (-0.4 * patat_v_mag(z))


def light_scene(sun_elevation: float, quality: str = "medium", utc: str = MOONLESS_UTC, **extra) -> Scene:
    d = {"camera": {"width": 32, "height": 18, "position": [0.0, 0.0, 2.0], "pitch": 10.0, "adaptation": False},
         "time": {"utc": utc, "sun_override": {"elevation": sun_elevation, "azimuth": 180.0}},
         "atmosphere": {"quality": quality}}
    for k, v in extra.items():
        d.setdefault(k, {}).update(v)
    return Scene.model_validate(d)


class SkyEvaluator:
    """sky_radiance(dir) for a list of directions on the GPU, per frame table or direct tables."""

    def __init__(self, renderer: Renderer, direct: bool = False):
        self.r = renderer
        src = "\n".join([GLSL_VERSION, "#define COMPUTE_SHADER 1",
                         "#define ATMOSPHERE_DIRECT_TABLES 1" if direct else "",
                         "layout(local_size_x = 64) in;",
                         expand("common/frame.glsl"),
                         expand("common/atmosphere.glsl", frozenset({"common/frame.glsl"})),
                         "layout(std430, binding = 0) buffer Dirs { vec4 d[]; };",
                         "layout(std430, binding = 1) buffer Out { vec4 o[]; };",
                         "uniform int u_count;",
                         "void main() { uint i = gl_GlobalInvocationID.x; if (i >= uint(u_count)) return;",
                         "  o[i] = vec4(sky_radiance(d[i].xyz), 0.0); }"])
        self.prog = renderer.ctx.compute_shader(src)

    def __call__(self, scene: Scene, dirs: np.ndarray):
        frame = build_frame(self.r.ctx, scene)
        set_uniforms(self.prog, {**frame.uniforms, "u_count": len(dirs)})
        pts = np.zeros((len(dirs), 4), "f4")
        pts[:, :3] = dirs
        inp, out = self.r.ctx.buffer(pts.tobytes()), self.r.ctx.buffer(reserve=pts.nbytes)
        inp.bind_to_storage_buffer(0)
        out.bind_to_storage_buffer(1)
        self.prog.run((len(dirs) + 63) // 64)
        result = np.frombuffer(out.read(), "f4").reshape(-1, 4)[:, :3].astype(np.float64)
        inp.release()
        out.release()
        return result, frame


def zenith_and_illuminance(evaluator: SkyEvaluator, sun_elevation: float, quality: str = "medium",
                           utc: str = MOONLESS_UTC) -> tuple[float, float]:
    radiance, frame = evaluator(light_scene(sun_elevation, quality, utc), np.array([[0.0, 0.0, 1.0]]))
    return float(radiance[0] @ LUMA), float(frame.illuminance_lux)


def dome(n_az: int = 64, n_el: int = 16) -> np.ndarray:
    az = (np.arange(n_az) + 0.5) / n_az * 2 * math.pi
    el = (np.arange(n_el) + 0.5) / n_el * (math.pi / 2)
    A, E = np.meshgrid(az, el)
    return np.stack([np.cos(E) * np.sin(A), np.cos(E) * np.cos(A), np.sin(E)], axis=-1).reshape(-1, 3)


def max_step_ratio(values: list[float]) -> float:
    v = np.maximum(np.asarray(values), 1e-30)
    r = v[1:] / v[:-1]
    return float(np.max(np.maximum(r, 1.0 / r)))


def run(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="igserver quality light", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="out/quality", help="directory for light.md / light.json")
    ap.add_argument("--presets", default="low,medium,high")
    ap.add_argument("--step", type=float, default=0.1, help="deg, smoothness sweep step (0 .. -18)")
    ap.add_argument("--fresh", action="store_true", help="precompute every preset afresh (timed) in a private cache")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    renderer = Renderer()
    direct = SkyEvaluator(renderer, direct=True)
    lut = SkyEvaluator(renderer)
    presets = args.presets.split(",")
    report: dict = {"presets": {}, "curves": {}}
    # Precompute time of each preset, fresh (a private cache directory).
    old_cache = os.environ.get("IGSERVER_CACHE")
    with tempfile.TemporaryDirectory() as tmp:
        if args.fresh:
            os.environ["IGSERVER_CACHE"] = tmp
        try:
            for q in presets:
                AtmosphereTables._resident.pop(renderer.ctx, None)
                build_frame(renderer.ctx, light_scene(0.0, q))
                tables = AtmosphereTables._resident[renderer.ctx]
                s = light_scene(-6.0, q, camera={"width": 640, "height": 360})
                renderer.render(s)
                ms = []
                for _ in range(5):
                    ms.append(renderer.render(s, timed=True).pass_ms.get("sky", float("nan")))
                report["presets"][q] = {"precompute_s": round(tables.precompute_s, 1) if not tables.from_cache else None,
                                        "sky_pass_ms_640x360": round(float(np.median(ms)), 1),
                                        "sizes": tables.params.sizes.__dict__}
                curve = []
                for el in ELEVATIONS:
                    lz, eh = zenith_and_illuminance(lut, el, q)
                    curve.append({"sun": el, "zenith_cd_m2": lz, "illuminance_lux": eh})
                report["curves"][q] = curve
        finally:
            if old_cache is None:
                os.environ.pop("IGSERVER_CACHE", None)
            else:
                os.environ["IGSERVER_CACHE"] = old_cache
            AtmosphereTables._resident.pop(renderer.ctx, None)
    # Smoothness and the sky-view table's error, medium preset.
    sweep = np.round(np.arange(0.0, -18.0 - 1e-9, -args.step), 3)
    zs, es = [], []
    for el in sweep:
        lz, eh = zenith_and_illuminance(lut, float(el))
        zs.append(lz)
        es.append(eh)
    report["smoothness"] = {"step_deg": args.step, "max_zenith_ratio": max_step_ratio(zs),
                            "max_illuminance_ratio": max_step_ratio(es)}
    dirs = dome()
    lut_err = []
    for el in (45.0, 10.0, 0.0, -4.0, -8.0, -12.0):
        a, _ = lut(light_scene(el), dirs)
        b, _ = direct(light_scene(el), dirs)
        ya, yb = a @ LUMA, b @ LUMA
        lut_err.append({"sun": el, "mean_rel_err": float(np.mean(np.abs(ya - yb) / np.maximum(yb, 1e-30))),
                        "max_rel_err": float(np.max(np.abs(ya - yb) / np.maximum(yb, 1e-30)))})
    report["sky_view_vs_direct"] = lut_err
    moon = build_frame(renderer.ctx, light_scene(-30.0, utc=FULL_MOON_UTC)).illuminance_lux
    dark = build_frame(renderer.ctx, light_scene(-30.0)).illuminance_lux
    report["night"] = {"full_moon_30deg_lux": moon, "moonless_lux": dark}
    renderer.release()
    (out / "light.json").write_text(json.dumps(report, indent=1))
    md = _markdown(report, presets)
    (out / "light.md").write_text(md)
    print(md)
    return 0


def _markdown(report: dict, presets: list[str]) -> str:
    lines = ["# Light levels: noon to night", "",
             "Natural horizontal illuminance E_h (lux) and zenith luminance L_z (cd/m^2), moonless, sea level, "
             "default atmosphere; published: AMS Glossary (E_h), Patat et al. 2006 V band +30 % (L_z).", ""]
    head = ("| sun (deg) | " + " | ".join(f"E_h {q} | L_z {q}" for q in presets)
            + " | E_h published | L_z published (fit) | L_z published (figure) |")
    lines += [head, "|" + "---|" * (2 * len(presets) + 4)]

    def cell(v):
        return f"{v:.3g}" if v else ""
    for i, el in enumerate(ELEVATIONS):
        cells = []
        for q in presets:
            c = report["curves"][q][i]
            cells.append(f"{c['illuminance_lux']:.3g} | {c['zenith_cd_m2']:.3g}")
        published = [AMS_ILLUMINANCE.get(el), patat_zenith_luminance(el), patat_digitised_luminance(el)]
        lines.append(f"| {el:+.0f} | " + " | ".join(cells + [cell(v) for v in published]) + " |")
    lines += ["", "| preset | precompute (s, fresh) | sky pass (ms, 640x360) | sizes |", "|---|---|---|---|"]
    for q in presets:
        p = report["presets"][q]
        pre = "cached" if p["precompute_s"] is None else p["precompute_s"]
        lines.append(f"| {q} | {pre} | {p['sky_pass_ms_640x360']} | {p['sizes']} |")
    s = report["smoothness"]
    lines += ["", f"Smoothness 0 .. -18 deg at {s['step_deg']} deg steps (medium): largest ratio between neighbours "
              f"L_z x{s['max_zenith_ratio']:.3f}, E_h x{s['max_illuminance_ratio']:.3f} (bound: x1.25).", "",
              "Per-frame sky-view table vs 4D tables per pixel (64 x 16 dome, relative luminance error):", "",
              "| sun | mean | max |", "|---|---|---|"]
    for e in report["sky_view_vs_direct"]:
        lines.append(f"| {e['sun']:+.0f} | {e['mean_rel_err']:.2%} | {e['max_rel_err']:.2%} |")
    n = report["night"]
    lines += ["", f"Night, sun -30 deg: full moon 30 deg up {n['full_moon_30deg_lux']:.3g} lx; moonless "
              f"{n['moonless_lux']:.3g} lx (night sky floor 21.6 V mag/arcsec^2)."]
    return "\n".join(lines) + "\n"
