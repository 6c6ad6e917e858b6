"""``igserver quality sky``: error of the sky tiers against the float64 reference, next to cost.

For table sizes x scattering orders x tiers, at sun zenith 30, 65, 88, 95, 100 deg, over a 64 x 32
dome of view directions (azimuth x elevation 0..90 deg, cell centres) seen from 2 m, of the CLEAR
air (what the table knobs change; visibility 200 km and the near-ground haze layer off: that layer
is analytic per pixel, the same for every table, and checked by `igserver quality fog`):
  * PSNR (dB) of the tone-mapped image: x = L * exposure (the frame's auto exposure),
    Reinhard x / (1 + x), sRGB encoded, peak 1;
  * mean relative radiance error: mean over the dome of |Y - Y_ref| / Y_ref (Y = luminance);
next to the tables' precompute seconds (computed fresh, no cache) and the sky pass milliseconds
at 640x360 (median of 5 timed frames). Also the RMS relative difference of the default sky's
luminance distribution (normalised to the zenith) against CIE standard clear skies 12 and 13
(ISO 15469 / CIE S 011) at sun elevations 20..60 deg. Writes markdown + json to --out.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..render.frame import build_frame
from ..photometry import LUMA
from ..render.renderer import Renderer
from ..render.sky import atmosphere_model as am
from ..render.shaders import set_uniforms
from ..render.sky.tables import AtmosphereTables, cache_dir
from ..scene.model import Scene
from .light import SkyEvaluator
from .reference_sky import single_scattering

SUN_ZENITHS = (30.0, 65.0, 88.0, 95.0, 100.0)
# Multiple scattering of the reference: smooth, so moderate tables with many orders (the density
# integral with the medium preset's 16 x 32 directions: fewer under-resolve the twilight's).
REFERENCE_MS = am.TableSizes((256, 64), (64, 16), 16, 64, 32, 8, 6, 16)
CLEAR_VISIBILITY_M = 200_000.0  # the longest the scene accepts: the clear tables' own ~210 km
CONFIGS = [("gradient", None, None), ("precomputed", "low", 2), ("precomputed", "low", 4),
           ("precomputed", "medium", 1), ("precomputed", "medium", 2), ("precomputed", "medium", 4),
           ("precomputed", "medium", 8), ("precomputed", "high", 4)]
CIE_TYPES = {12: (-1.0, -0.32, 10.0, -3.0, 0.45), 13: (-1.0, -0.32, 16.0, -3.0, 0.30)}


def dome(n_az: int = 64, n_el: int = 32) -> np.ndarray:
    az = (np.arange(n_az) + 0.5) / n_az * 2 * math.pi
    el = (np.arange(n_el) + 0.5) / n_el * (math.pi / 2)
    A, E = np.meshgrid(az, el)
    return np.stack([np.cos(E) * np.sin(A), np.cos(E) * np.cos(A), np.sin(E)], axis=-1).reshape(-1, 3)


def make_scene(sun_zenith: float, model: str = "precomputed", quality: str = "medium", orders: int = 4,
               width: int = 64, height: int = 36, clear: bool = False) -> Scene:
    atmosphere = {"model": model, "quality": quality, "scattering_orders": orders}
    if clear:
        atmosphere["visibility"] = CLEAR_VISIBILITY_M
    return Scene.model_validate({
        "camera": {"width": width, "height": height, "position": [0, 0, 2.0], "pitch": 10.0, "heading": 180.0},
        "time": {"sun_override": {"elevation": 90.0 - sun_zenith, "azimuth": 180.0}},
        "atmosphere": atmosphere,
    })


def _probe(renderer: Renderer, prog, uniforms: dict, dirs: np.ndarray) -> np.ndarray:
    """Run a sky_radiance compute probe over dirs: (N, 3) float64 cd/m^2."""
    set_uniforms(prog, {**uniforms, "u_count": len(dirs)})
    pts = np.zeros((len(dirs), 4), "f4")
    pts[:, :3] = dirs
    inp, out = renderer.ctx.buffer(pts.tobytes()), renderer.ctx.buffer(reserve=pts.nbytes)
    inp.bind_to_storage_buffer(0)
    out.bind_to_storage_buffer(1)
    prog.run((len(dirs) + 63) // 64)
    result = np.frombuffer(out.read(), "f4").reshape(-1, 4)[:, :3].astype(np.float64)
    inp.release()
    out.release()
    return result


class DomeEvaluator(SkyEvaluator):
    """sky_radiance(dir) of common/atmosphere.glsl for a list of directions, on the GPU, with the
    frame's exposure (the light study's evaluator, one compute probe for both studies). clear=True:
    the clear air alone (haze layer off), the quantity the float64 reference computes."""

    def __call__(self, scene: Scene, dirs: np.ndarray, clear: bool = False) -> tuple[np.ndarray, float]:
        frame = build_frame(self.r.ctx, scene)
        uniforms = {**frame.uniforms, "u_haze_beta": (0.0, 0.0, 0.0)} if clear else frame.uniforms
        return _probe(self.r, self.prog, uniforms, dirs), frame.exposure


def reference_radiance(renderer: Renderer, direct: SkyEvaluator, sun_zenith: float, dirs: np.ndarray,
                       ms_sizes: am.TableSizes = REFERENCE_MS) -> np.ndarray:
    """(N, 3) clear-air reference radiance (cd/m^2): float64 single scattering plus the orders >= 2
    of tables of ms_sizes (full minus single-order tables, both looked up per direction from the 4D
    tables: the ``direct`` probe, never the frame's sky-view table, which holds the scene's own)."""
    params = am.atmosphere_parameters()
    sun = np.array([0.0, -math.sin(math.radians(sun_zenith)), math.cos(math.radians(sun_zenith))])  # azimuth 180
    l1 = single_scattering(params, 2.0, dirs, sun)
    scene = make_scene(sun_zenith, clear=True)
    full = _tables_radiance(renderer, direct, scene, replace(params, sizes=ms_sizes), dirs)
    single = _tables_radiance(renderer, direct, scene, replace(params, sizes=replace(ms_sizes, orders=1)), dirs)
    return l1 + np.maximum(full - single, 0.0)


def tone_map(radiance: np.ndarray, exposure: float) -> np.ndarray:
    x = np.maximum(radiance * exposure, 0.0)
    x = x / (1.0 + x)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a - b) ** 2))
    return 99.0 if mse <= 1e-10 else 10.0 * math.log10(1.0 / mse)


def relative_error(y: np.ndarray, y_ref: np.ndarray) -> float:
    return float(np.mean(np.abs(y - y_ref) / np.maximum(y_ref, 1e-12)))


def cie_relative_luminance(kind: int, dirs: np.ndarray, sun_dir: np.ndarray) -> np.ndarray:
    """CIE standard sky: L / L_zenith = f(chi) phi(Z) / (f(Z_s) phi(0))."""
    a, b, c, d, e = CIE_TYPES[kind]
    Z = np.arccos(np.clip(dirs[:, 2], -1, 1))
    chi = np.arccos(np.clip(dirs @ sun_dir, -1, 1))
    Zs = math.acos(sun_dir[2])
    phi = 1 + a * np.exp(b / np.maximum(np.cos(Z), 1e-3))
    f = 1 + c * (np.exp(d * chi) - math.exp(d * math.pi / 2)) + e * np.cos(chi) ** 2
    f_zs = 1 + c * (math.exp(d * Zs) - math.exp(d * math.pi / 2)) + e * math.cos(Zs) ** 2
    return f * phi / (f_zs * (1 + a * math.exp(b)))


def sky_pass_ms(renderer: Renderer, scene: Scene, frames: int = 5) -> float:
    renderer.render(scene, timed=True)
    return float(np.median([renderer.render(scene, timed=True).pass_ms["sky"] for _ in range(frames)]))


def run(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="igserver quality sky", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="out/quality_sky.md", help="markdown path (json next to it)")
    ap.add_argument("--quick", action="store_true", help="skip the high preset and 8 orders")
    ap.add_argument("--az", type=int, default=64)
    ap.add_argument("--el", type=int, default=32)
    args = ap.parse_args(argv)
    rows, cie, ref_s, total_s, device = measure(args.quick, args.az, args.el)
    _write(Path(args.out), rows, cie, ref_s, total_s, device)
    return 0


def study(quick: bool = False):
    """The sky's curves for the combined report (igserver/quality/report.py): mean relative
    radiance error at sun zenith 65 deg against the sky pass's ms at 640x360."""
    from .report import Point, Study

    rows, _, ref_s, total_s, device = measure(quick, 32 if quick else 64, 16 if quick else 32)
    points = []
    for row in rows:
        setting = row["tier"] if row["tier"] == "gradient" else f"{row['quality']} tables, {row['orders']} orders"
        extra = {"PSNR 65° dB": row["psnr_65"], "PSNR 100° dB": row["psnr_100"], "precompute s": row["precompute_s"]}
        if row["tier"] == "gradient":
            knobs = ["tier"]
        else:
            knobs = (["orders"] if row["quality"] == "medium" else []) + (["tables"] if row["orders"] == 4 else [])
        for knob in knobs:
            default = row["tier"] == "precomputed" and row["quality"] == "medium" and row["orders"] == 4
            points.append(Point(knob, setting, row["rel_65"], row["sky_ms_640x360"],
                                "all presets" if default and knob == "orders" else None, extra))
    notes = [f"Reference: float64 single scattering + the orders >= 2 of {REFERENCE_MS.orders}-order tables, clear air "
             f"(visibility 200 km, haze layer off: the tables' share of the sky) ({ref_s:.0f} s); whole study {total_s:.0f} s.",
             "Table size and orders change the precompute seconds, not the sky pass's frame time, so every "
             "preset keeps the scene's `atmosphere.quality` tables (default medium, 4 orders)."]
    return Study("sky", "mean relative radiance error, sun zenith 65°", "ms, sky pass at 640x360 (median)",
                 points, notes, device)


def measure(quick: bool, az: int, el: int):
    """(rows, cie, reference seconds, total seconds, device) of the whole sky study."""
    os.environ.setdefault("LP_NUM_THREADS", "2")
    # Fresh cache: precompute seconds are real computations, not loads.
    os.environ["IGSERVER_CACHE"] = tempfile.mkdtemp(prefix="igserver-quality-sky-")
    t_start = time.perf_counter()
    renderer = Renderer()
    evaluate = DomeEvaluator(renderer)
    direct = SkyEvaluator(renderer, direct=True)
    dirs = dome(az, el)

    # Reference per sun zenith: float64 single scattering + the multiple-scattering part.
    reference = {zen: reference_radiance(renderer, direct, zen, dirs) for zen in SUN_ZENITHS}
    ref_s = time.perf_counter() - t_start

    rows = []
    for model, quality, orders in CONFIGS:
        if quick and (quality == "high" or orders == 8):
            continue
        row = {"tier": model, "quality": quality or "-", "orders": orders or 0}
        if model == "precomputed":
            sizes = replace(am.PRESETS[quality], orders=orders)
            params = am.atmosphere_parameters(sizes=sizes)
            AtmosphereTables._resident.pop(renderer.ctx, None)
            shutil.rmtree(cache_dir(), ignore_errors=True)  # time a real computation, not a load
            tables = AtmosphereTables.get(renderer.ctx, params)
            row["precompute_s"] = round(tables.precompute_s, 2)
            row["sizes"] = f"T{sizes.transmittance[0]}x{sizes.transmittance[1]} S{sizes.r}x{sizes.mu}x{sizes.mu_s}x{sizes.nu}"
        else:
            row["precompute_s"] = 0.0
            row["sizes"] = "-"
        for zen in SUN_ZENITHS:
            scene = make_scene(zen, model, quality or "medium", orders or 4, clear=True)
            radiance, exposure = evaluate(scene, dirs, clear=True)
            ref = reference[zen]
            row[f"psnr_{zen:g}"] = round(psnr(tone_map(radiance, exposure), tone_map(ref, exposure)), 2)
            row[f"rel_{zen:g}"] = round(relative_error(radiance @ LUMA, ref @ LUMA), 4)
        row["sky_ms_640x360"] = round(sky_pass_ms(renderer, make_scene(65.0, model, quality or "medium",
                                                                     orders or 4, 640, 360)), 2)
        rows.append(row)
        print(_row_md(row), flush=True)

    # CIE standard clear skies vs the default precomputed sky.
    cie = []
    for el in (20.0, 30.0, 40.0, 50.0, 60.0):
        scene = make_scene(90.0 - el)
        sun = np.array([0.0, -math.cos(math.radians(el)), math.sin(math.radians(el))])
        radiance, _ = evaluate(scene, dirs)
        zenith, _ = evaluate(scene, np.array([[0.0, 0.0, 1.0]]))
        ours = (radiance @ LUMA) / float(zenith[0] @ LUMA)
        away = np.degrees(np.arccos(np.clip(dirs @ sun, -1, 1))) > 5.0  # outside the aureole
        entry = {"sun_elevation": el}
        for kind in CIE_TYPES:
            cie_l = cie_relative_luminance(kind, dirs, sun)
            entry[f"rms_type{kind}"] = round(float(np.sqrt(np.mean((ours[away] / cie_l[away] - 1.0) ** 2))), 3)
        cie.append(entry)
    total_s = time.perf_counter() - t_start
    device = renderer.caps.renderer
    renderer.release()
    return rows, cie, ref_s, total_s, device


def _tables_radiance(renderer: Renderer, direct: SkyEvaluator, scene: Scene, params, dirs) -> np.ndarray:
    """Clear-air sky_radiance from the 4D tables of explicit parameters. ``direct`` must be the
    per-direction table walk (ATMOSPHERE_DIRECT_TABLES): the frame path reads the sky-view table
    that build_frame fills from the SCENE's tables, whatever else is bound afterwards."""
    frame = build_frame(renderer.ctx, scene)  # makes the scene's tables resident; ours replace them
    tables = AtmosphereTables.get(renderer.ctx, params)
    tables.bind()
    uniforms = {**frame.uniforms, **tables.uniforms(), "u_haze_beta": (0.0, 0.0, 0.0)}
    return _probe(renderer, direct.prog, uniforms, dirs)


HEAD = ("| tier | quality | sizes | orders | precompute s | sky ms 640x360 | "
        + " | ".join(f"PSNR {z:g}° | rel {z:g}°" for z in SUN_ZENITHS) + " |")


def _row_md(row: dict) -> str:
    cells = [row["tier"], row["quality"], row["sizes"], str(row["orders"] or "-"), f"{row['precompute_s']:.2f}",
             f"{row['sky_ms_640x360']:.2f}"]
    for z in SUN_ZENITHS:
        cells += [f"{row[f'psnr_{z:g}']:.1f}", f"{row[f'rel_{z:g}']:.3f}"]
    return "| " + " | ".join(cells) + " |"


def _write(md_path: Path, rows, cie, ref_s, total_s, device) -> None:
    md_path.parent.mkdir(parents=True, exist_ok=True)
    lines = ["# Sky quality: error against the float64 reference vs run time", "",
             f"Device: {device}. Reference (float64 single scattering + multiple scattering of "
             f"{REFERENCE_MS.orders}-order tables, clear air: visibility 200 km, haze layer off) took {ref_s:.1f} s; "
             f"whole run {total_s:.1f} s.",
             "PSNR of the Reinhard/sRGB tone-mapped 64x32 dome at the frame's auto exposure; rel = mean "
             "|Y - Y_ref| / Y_ref. Sun zenith angles in the column heads.", "", HEAD,
             "|" + "---|" * (6 + 2 * len(SUN_ZENITHS))]
    lines += [_row_md(r) for r in rows]
    lines += ["", "## CIE standard clear skies (relative luminance, zenith-normalised, RMS of ratio - 1, "
              "outside 5° of the sun)", "", "| sun elevation | type 12 | type 13 |", "|---|---|---|"]
    lines += [f"| {c['sun_elevation']:g}° | {c['rms_type12']:.3f} | {c['rms_type13']:.3f} |" for c in cie]
    text = "\n".join(lines) + "\n"
    md_path.write_text(text)
    md_path.with_suffix(".json").write_text(json.dumps({"rows": rows, "cie": cie, "reference_s": ref_s,
                                                        "total_s": total_s, "device": device}, indent=1))
    print(text)


if __name__ == "__main__":
    import sys

    raise SystemExit(run(sys.argv[1:]))
