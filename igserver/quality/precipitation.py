"""``igserver quality weather`` (particle part; also ``igserver quality precipitation``): error of the
rain/snow particles against run time (DESIGN §6).

Knobs: drops per streak m (the particle count per cube is the visible drops in it over m, so the
drawn count goes like 1/m) x cube (tile) size L. Reference: the same frame with m = 2 and 8 m cubes
and no cost cap: 32x the default particle count; the default's particles are a subset of the
reference's (the pool is prefix-stable), so the error is the thinning's, not another random draw's.

What is measured, on the precipitation's own contribution (frame minus the same frame dry):
  * bias: mean contribution / reference mean - 1. The opacity of a streak carries its m drops,
    so the mean coverage is conserved for any m; bias comes only from the opacity clamp at 1;
  * lowpass: 8-bit sRGB RMSE after a 9x9 box blur: where the rain is dense or thin on the scale the
    eye reads as "how hard it rains" (coverage statistics);
  * rmse: per-pixel 8-bit sRGB RMSE: the graininess (fewer, bolder streaks);
  * block cv: coefficient of variation of the contribution over 32x32 px blocks, against the
    reference's (uniformity: an empty slab or a sparse level shows as a high cv).
Time: median ms of the precipitation pass (CPU particle update + light compute + streak draw) over
frames with advancing sim_time.

Usage: igserver quality weather [--out out/quality_weather.md] [--size 640x360] [--frames 3]
       [--drops 8,16,32,64,128,256] [--tiles 2,4,8] [--scene rain_harbour|snow]
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

from .volumes import box_blur

REFERENCE_DROPS = 2.0
REFERENCE_TILE = 8.0
LOWPASS_LIMIT = 1.0  # 8-bit levels: a rain-density error below one level is invisible
BIAS_LIMIT = 0.1


def _luminance(hdr: np.ndarray) -> np.ndarray:
    return hdr[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def block_cv(contribution: np.ndarray, block: int = 32) -> float:
    h, w = (s // block * block for s in contribution.shape)
    means = np.abs(contribution[:h, :w]).reshape(h // block, block, w // block, block).mean(axis=(1, 3))
    return float(means.std() / max(means.mean(), 1e-12))


def run(argv: list[str]) -> int:
    from ..render.precip.particles import PrecipSettings
    from ..render.renderer import Renderer
    from ..scene import apply_patch, load_scene

    ap = argparse.ArgumentParser(prog="igserver quality weather")
    ap.add_argument("--out", default="out/quality_weather.md")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--drops", default="8,16,32,64,128,256")
    ap.add_argument("--tiles", default="2,4,8")
    ap.add_argument("--scene", default="rain_harbour")
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    drops = [float(v) for v in args.drops.split(",")]
    tiles = [float(v) for v in args.tiles.split(",")]

    scene = apply_patch(load_scene(args.scene), {"camera": {"width": width, "height": height}})
    kind = scene.weather.precipitation.type
    renderer = Renderer()
    ppass = renderer.graph.passes["precip"]
    default = PrecipSettings()

    def settings(m: float, tile: float, cap: int = default.max_streaks) -> PrecipSettings:
        return PrecipSettings(tile_size=tile, drops_per_streak={kind: m}, max_streaks=cap,
                              fade_distance=default.fade_distance, lod_distance=default.lod_distance)

    def frame(s, config):
        ppass.settings = config
        result = renderer.render(s, timed=True)
        return result, renderer.read_hdr()

    dry = scene.model_copy(update={"weather": scene.weather.model_copy(update={
        "precipitation": scene.weather.precipitation.model_copy(update={"type": "none"})})})
    dry_result, dry_hdr = frame(dry, default)
    ref_result, ref_hdr = frame(scene, settings(REFERENCE_DROPS, REFERENCE_TILE, cap=10**9))
    ref_streaks = ppass.stats["streaks"]
    ref_contrib = _luminance(ref_hdr - dry_hdr)
    ref_mean = float(np.abs(ref_contrib).mean())
    ref_cv = block_cv(ref_contrib)
    ref_rgb = ref_result.rgba[..., :3].astype(np.float64)

    rows = []
    for tile in tiles:
        for m in drops:
            config = settings(m, tile)
            result, hdr = frame(scene, config)
            stats = dict(ppass.stats)
            contrib = _luminance(hdr - dry_hdr)
            rgb = result.rgba[..., :3].astype(np.float64)
            ms = []
            for i in range(args.frames):
                moving = apply_patch(scene, {"time": {"sim_time": scene.time.sim_time + (i + 1) / 30.0}})
                ms.append(frame(moving, config)[0].pass_ms["precip"])
            rows.append({
                "drops_per_streak": m, "tile": tile, "particles_per_tile": stats["particles"],
                "streaks": stats["streaks"], "capped": stats["drops_per_streak"] > m * 1.01,
                "bias": float(np.abs(contrib).mean()) / ref_mean - 1.0,
                "lowpass": float(np.sqrt(np.mean((box_blur(rgb) - box_blur(ref_rgb)) ** 2))),
                "rmse": float(np.sqrt(np.mean((rgb - ref_rgb) ** 2))),
                "block_cv": block_cv(contrib), "ms": statistics.median(ms),
            })
            r = rows[-1]
            print(f"L {tile:4.1f} m {m:6.1f}  particles/tile {r['particles_per_tile']:6d}  streaks {r['streaks']:7d}  "
                  f"bias {r['bias']:+.3f}  lowpass {r['lowpass']:5.2f}  rmse {r['rmse']:5.2f}  "
                  f"cv {r['block_cv']:.2f}  ms {r['ms']:7.1f}", flush=True)
    ppass.settings = PrecipSettings()

    good = [r for r in rows if r["lowpass"] <= LOWPASS_LIMIT and abs(r["bias"]) <= BIAS_LIMIT]
    choice = min(good, key=lambda r: r["ms"]) if good else min(rows, key=lambda r: r["lowpass"])
    report = {"renderer": renderer.caps.renderer, "scene": args.scene, "kind": kind, "size": f"{width}x{height}",
              "reference": {"drops_per_streak": REFERENCE_DROPS, "tile": REFERENCE_TILE, "streaks": ref_streaks,
                            "block_cv": ref_cv, "ms": ref_result.pass_ms["precip"]},
              "rows": rows, "recommended": choice,
              "default": {"drops_per_streak": default.drops(kind), "tile": default.tile_size}}
    lines = [
        f"# Precipitation: error against run time ({args.scene}, {kind}, {width}x{height}, {renderer.caps.renderer})",
        "",
        f"Reference: {REFERENCE_DROPS:g} drops per streak, {REFERENCE_TILE:g} m cubes, no cap: {ref_streaks} streaks, "
        f"{ref_result.pass_ms['precip']:.0f} ms; block cv {ref_cv:.2f}.",
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
    lines += ["", f"Recommended (cheapest with lowpass <= {LOWPASS_LIMIT} and |bias| <= {BIAS_LIMIT}): "
                  f"{choice['drops_per_streak']:g} drops per streak, {choice['tile']:g} m cubes. "
                  f"Default in use: {default.drops(kind):g} drops per streak, {default.tile_size:g} m cubes."]
    text = "\n".join(lines) + "\n"
    print(text)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    out.with_suffix(".json").write_text(json.dumps(report, indent=2))
    renderer.release()
    return 0
