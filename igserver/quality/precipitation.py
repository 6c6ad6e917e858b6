"""``igserver quality weather`` (the particle part; quality/weather.py is the study's entry): error of
the rain/snow particles against run time (docs/design.md#quality).

Knobs: drops per streak m (the particle count per cube is the visible drops in it over m, so the
drawn count goes like 1/m) x cube (tile) size L. Reference: the same frame with m = 8 and 8 m cubes
and no cost cap: 8x the default particle count. Not denser: the HDR target is half float, and a
streak standing for fewer than ~8 drops has an opacity (~1e-4 at 30 m) below half-float resolution of
what lies behind it, so its blend rounds away - the m = 2 frame has ~30 % less rain than m = 8..64,
which agree within ~8 % (measured on a day sky, rain 8 mm/h).

What is measured, on the precipitation's own contribution (frame minus the same frame dry):
  * bias: mean contribution / reference mean - 1. The opacity of a streak carries its m drops,
    so the mean coverage is conserved for any m; bias comes only from the opacity clamp at 1;
  * lowpass: 8-bit sRGB RMSE after a 9x9 box blur: where the rain is dense or thin on the scale the
    eye reads as "how hard it rains" (coverage statistics);
  * rmse: per-pixel 8-bit sRGB RMSE: the graininess (fewer, bolder streaks);
  * block cv: coefficient of variation of the contribution over 32x32 px blocks, against the
    reference's (uniformity: an empty slab or a sparse level shows as a high cv).
Every statistic is the mean over --frames frames 1/30 s apart (one frame's bias is dominated by
the few bright streaks near a lamp). Time: median ms of the precipitation pass (CPU particle update
+ light compute + streak draw) over the same frames.

Usage: igserver quality weather [--out out/quality_weather.md] [--size 640x360] [--frames 4]
       [--drops 16,32,64,128,256] [--tiles 2,4,8] [--scene rain_harbour|snow] [--quick]
"""

from __future__ import annotations

import argparse
import json
import statistics
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..photometry import LUMA
from .volumes import box_blur

REFERENCE_DROPS = 8.0
REFERENCE_TILE = 8.0
# The default is the best point (lowest lowpass error) within a cost budget and a bias limit.
# Budget: 16 000 streaks, ~20 ms of a quiet 2-core llvmpipe at 640x360 (a quarter of a demo frame;
# measured ~27 ms of CPU time summed over llvmpipe's threads for 13 600 streaks); the cost is
# ~linear in the streak count. Bias: 15 %, below the uncertainty of the rate ->
# drop-spectrum relation itself (measured spectra scatter by more around Marshall-Palmer).
STREAK_BUDGET = 16_000
BIAS_LIMIT = 0.15
# Cubes smaller than 4 m repeat visibly (rows of identical flakes toward the horizon, looked at in
# the pictures); these statistics do not see repetition, so the choice is made among L >= 4 m.
MIN_TILE = 4.0


def _luminance(hdr: np.ndarray) -> np.ndarray:
    return hdr[..., :3] @ LUMA


def block_cv(contribution: np.ndarray, block: int = 32) -> float:
    h, w = (s // block * block for s in contribution.shape)
    means = np.abs(contribution[:h, :w]).reshape(h // block, block, w // block, block).mean(axis=(1, 3))
    return float(means.std() / max(means.mean(), 1e-12))


def parse_args(argv: list[str]) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="igserver quality weather")
    ap.add_argument("--out", default="out/quality_weather.md")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--drops", default="16,32,64,128,256")
    ap.add_argument("--tiles", default="2,4,8")
    ap.add_argument("--scene", default="rain_harbour")
    ap.add_argument("--quick", action="store_true", help="320x180, 2 frames, 4 m cubes, 4 points (a minute)")
    args = ap.parse_args(argv)
    if args.quick:
        args.size, args.frames, args.drops, args.tiles = "320x180", 2, "32,64,128,256", "4"
    return args


def main(argv: list[str]) -> int:
    """The CLI (igserver quality weather): table and JSON under --out."""
    args = parse_args(argv)
    report, text = measure(args)
    print(text)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    out.with_suffix(".json").write_text(json.dumps(report, indent=2))
    return 0


def study(quick: bool = False):
    """Points for the combined report (igserver quality): lowpass error against the pass's ms per
    cube size, presets marked (low / medium / high = m x 2, m, m / 2 in 4 m cubes)."""
    from ..render.precip.particles import PRESETS
    from .report import Point, Study

    args = parse_args(["--quick"] if quick else ["--tiles", "4,8"])
    report, _ = measure(args)
    kind = report["kind"]
    marks = {getattr(settings, f"{kind}_drops"): level for level, settings in PRESETS.items()}
    points = [Point(f"m, {r['tile']:g} m cubes", f"m={r['drops_per_streak']:g} L={r['tile']:g}", r["lowpass"], r["ms"],
                    marks.get(r["drops_per_streak"]) if r["tile"] == PRESETS["medium"].tile_size else None,
                    {"bias": r["bias"], "rmse": r["rmse"], "streaks": r["streaks"]})
              for r in report["rows"]]
    return Study("precipitation", "8-bit sRGB RMSE after a 9x9 blur of the rain's contribution vs 8 drops/streak",
                 f"ms, precipitation pass ({report['size']}, {args.scene})", points,
                 [f"recommended: {report['recommended']['drops_per_streak']:g} drops per streak, "
                  f"{report['recommended']['tile']:g} m cubes"], report["renderer"])


def measure(args: argparse.Namespace) -> tuple[dict, str]:
    from ..render.precip.particles import PrecipSettings, particle_count
    from ..render.renderer import Renderer
    from ..scene import apply_patch, load_scene

    width, height = (int(v) for v in args.size.lower().split("x"))
    drops = [float(v) for v in args.drops.split(",")]
    tiles = [float(v) for v in args.tiles.split(",")]

    scene = apply_patch(load_scene(args.scene), {"camera": {"width": width, "height": height}})
    kind = scene.weather.precipitation.type
    renderer = Renderer()
    ppass = renderer.graph.passes["precip"]
    default = PrecipSettings()

    def settings(m: float, tile: float, cap: int = default.max_streaks) -> PrecipSettings:
        return replace(default, tile_size=tile, max_streaks=cap, **{f"{kind}_drops": m})

    def frame(s, config):
        ppass.settings = config
        result = renderer.render(s, timed=True)
        return result, renderer.read_hdr()

    times = [scene.time.sim_time + i / 30.0 for i in range(args.frames)]
    at = [apply_patch(scene, {"time": {"sim_time": t}}) for t in times]
    dry = [apply_patch(s, {"weather": {"precipitation": {"type": "none"}}}) for s in at]
    dry_hdr = [frame(s, default)[1] for s in dry]
    reference = settings(REFERENCE_DROPS, REFERENCE_TILE, cap=10**9)
    ref = []  # per frame: (8-bit rgb, contribution luminance, ms)
    for s, d in zip(at, dry_hdr):
        result, hdr = frame(s, reference)
        ref.append((result.rgba[..., :3].astype(np.float64), _luminance(hdr - d), result.pass_ms["precip"]))
    ref_streaks = ppass.stats["streaks"]
    ref_mean = float(np.mean([np.abs(c).mean() for _, c, _ in ref]))
    ref_cv = float(np.mean([block_cv(c) for _, c, _ in ref]))
    ref_ms = statistics.median(ms for _, _, ms in ref)

    rows = []
    for tile in tiles:
        for m in drops:
            config = settings(m, tile)
            frame(at[0], config)  # warm-up: programs, buffers
            means, lows, rmses, cvs, ms = [], [], [], [], []
            for s, d, (ref_rgb, _, _) in zip(at, dry_hdr, ref):
                result, hdr = frame(s, config)
                contrib = _luminance(hdr - d)
                rgb = result.rgba[..., :3].astype(np.float64)
                means.append(np.abs(contrib).mean())
                lows.append(np.sqrt(np.mean((box_blur(rgb) - box_blur(ref_rgb)) ** 2)))
                rmses.append(np.sqrt(np.mean((rgb - ref_rgb) ** 2)))
                cvs.append(block_cv(contrib))
                ms.append(result.pass_ms["precip"])
            stats = dict(ppass.stats)
            rows.append({
                "drops_per_streak": m, "tile": tile, "particles_per_tile": stats["particles"],
                "streaks": stats["streaks"], "capped": stats["particles"] < particle_count(kind, scene.weather.precipitation.rate, config),
                "bias": float(np.mean(means)) / ref_mean - 1.0, "lowpass": float(np.mean(lows)),
                "rmse": float(np.mean(rmses)), "block_cv": float(np.mean(cvs)), "ms": statistics.median(ms),
            })
            r = rows[-1]
            print(f"L {tile:4.1f} m {m:6.1f}  particles/tile {r['particles_per_tile']:6d}  streaks {r['streaks']:7d}  "
                  f"bias {r['bias']:+.3f}  lowpass {r['lowpass']:5.2f}  rmse {r['rmse']:5.2f}  "
                  f"cv {r['block_cv']:.2f}  ms {r['ms']:7.1f}", flush=True)
    ppass.settings = None

    good = [r for r in rows if r["streaks"] <= STREAK_BUDGET and abs(r["bias"]) <= BIAS_LIMIT
            and r["tile"] >= MIN_TILE]
    choice = min(good or rows, key=lambda r: r["lowpass"])
    report = {"renderer": renderer.caps.renderer, "scene": args.scene, "kind": kind, "size": f"{width}x{height}",
              "reference": {"drops_per_streak": REFERENCE_DROPS, "tile": REFERENCE_TILE, "streaks": ref_streaks,
                            "block_cv": ref_cv, "ms": ref_ms},
              "rows": rows, "recommended": choice,
              "default": {"drops_per_streak": default.drops(kind), "tile": default.tile_size}}
    lines = [
        f"# Precipitation: error against run time ({args.scene}, {kind}, {width}x{height}, {renderer.caps.renderer})",
        "",
        f"Reference: {REFERENCE_DROPS:g} drops per streak, {REFERENCE_TILE:g} m cubes, no cap: {ref_streaks} streaks, "
        f"{ref_ms:.0f} ms; block cv {ref_cv:.2f}. Statistics: mean over {args.frames} frames 1/30 s apart.",
        "bias = mean contribution vs reference; lowpass/rmse in 8-bit sRGB (lowpass: 9x9 blur); "
        "cv = spread of the contribution over 32 px blocks; ms = precipitation pass (median).",
        "",
        "| tile m | drops/streak | particles/tile | streaks | bias | lowpass | rmse | block cv | ms |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        mark = " **" if r is choice else ""
        cap = " (cap)" if r["capped"] else ""
        lines.append(f"| {r['tile']:g} | {r['drops_per_streak']:g} | {r['particles_per_tile']} | {r['streaks']}{cap} | "
                     f"{r['bias']:+.3f} | {r['lowpass']:.2f} | {r['rmse']:.2f} | {r['block_cv']:.2f} | {r['ms']:.1f}{mark} |")
    rule = (f"lowest lowpass with <= {STREAK_BUDGET} streaks, |bias| <= {BIAS_LIMIT}, cubes >= {MIN_TILE:g} m" if good
            else "no row within the budget: the lowest lowpass error")
    lines += ["", f"Recommended ({rule}): "
                  f"{choice['drops_per_streak']:g} drops per streak, {choice['tile']:g} m cubes. "
                  f"Default in use: {default.drops(kind):g} drops per streak, {default.tile_size:g} m cubes."]
    renderer.release()
    return report, "\n".join(lines) + "\n"
