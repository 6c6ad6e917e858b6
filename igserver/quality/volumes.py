"""``igserver quality volumes``: error of the fire/smoke ray-march against run time (DESIGN §6).

Knobs: march steps (along the container's diagonal) x turbulence octaves x 3D-texture resolution.
Half-resolution marching is not implemented, so that axis has the single value "full".

The screen-size LOD of the texture is off here (the knob itself is measured); in use it only lowers
the resolution of containers that are small on screen.

Reference: the same frame with 1024 steps, 4 octaves and a 128-voxel texture (converged: doubling
the steps again changes the picture by less than the 8-bit step). Error in the 8-bit sRGB output
(0..255) over the covered pixels (where the reference differs from the frame without the effect):
  * rmse: per-pixel RMSE, includes the jitter's fine-grained noise;
  * lowpass: RMSE after a 9x9 box blur of both pictures: what is left is banding and bias, the
    errors the eye sees (the jitter's noise averages out).
Time: median ms of the volumes pass (modelling + march) over frames whose sim_time advances by
1/30 s (so the modelling stage really runs), and of the march alone (same state again).

Usage: igserver quality volumes [--out out/quality_volumes.md] [--size 640x360] [--frames 3]
       [--steps 16,32,48,64,128] [--octaves 2,3,4] [--res 16,32,64] [--scene night_fire_close]
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

LOWPASS_LIMIT = 2.0  # 8-bit levels: banding below this is hidden by the output dither and the noise
RMSE_LIMIT = 6.0
REFERENCE = {"steps": 1024, "octaves": 4, "resolution": 128, "lod": False}


def study_scene(name: str, width: int, height: int):
    from ..scene import Scene

    night = "2026-01-15T22:00:00Z"
    if name == "night_fire_close":
        data = {
            "camera": {"position": [0.0, -11.0, 2.5], "pitch": 12.0, "exposure_ev": 10.0},
            "time": {"utc": night, "sim_time": 100.0},
            "weather": {"wind_speed": 2.0, "wind_direction": 250.0},
            "effects": [{"id": "fire", "type": "fire", "diameter": 2.0, "emits_smoke": True, "seed": 3}],
            "entities": [{"id": "box", "model": "box", "position": [1.8, 1.0, -0.5], "scale": [1.5, 1.5, 1.5]}],
            "ground": {"level": -0.5},
        }
    elif name == "day_smoke":
        data = {
            "camera": {"position": [0.0, -30.0, 4.0], "pitch": 12.0},
            "time": {"utc": "2026-06-21T10:00:00Z", "sim_time": 100.0},
            "weather": {"wind_speed": 3.0},
            "effects": [{"id": "smoke", "type": "smoke", "diameter": 4.0, "seed": 5}],
        }
    else:
        raise ValueError(f"unknown study scene {name!r} (night_fire_close, day_smoke)")
    data["camera"].update(width=width, height=height)
    return Scene.model_validate(data)


def box_blur(img: np.ndarray, k: int = 9) -> np.ndarray:
    """Mean over a k x k window (edges clamped), per channel, via cumulative sums."""
    pad = k // 2
    p = np.pad(img, ((pad, pad), (pad, pad), (0, 0)), mode="edge").astype(np.float64)
    c = np.cumsum(np.cumsum(p, axis=0), axis=1)
    c = np.pad(c, ((1, 0), (1, 0), (0, 0)))
    h, w = img.shape[:2]
    s = c[k:k + h, k:k + w] - c[:h, k:k + w] - c[k:k + h, :w] + c[:h, :w]
    return s / (k * k)


def errors(img: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    a, b = img[..., :3].astype(np.float64), ref[..., :3].astype(np.float64)
    rmse = float(np.sqrt(np.mean((a - b)[mask] ** 2)))
    low = float(np.sqrt(np.mean((box_blur(a) - box_blur(b))[mask] ** 2)))
    return rmse, low


def run(argv: list[str]) -> int:
    from ..render.renderer import Renderer
    from ..render.volumes.volumes import PRESETS, VolumeSettings
    from ..scene import apply_patch

    ap = argparse.ArgumentParser(prog="igserver quality volumes")
    ap.add_argument("--out", default="out/quality_volumes.md")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--steps", default="16,32,48,64,128")
    ap.add_argument("--octaves", default="2,3,4")
    ap.add_argument("--res", default="16,32,64")
    ap.add_argument("--scene", default="night_fire_close")
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    steps = [int(v) for v in args.steps.split(",")]
    octaves = [int(v) for v in args.octaves.split(",")]
    resolutions = [int(v) for v in args.res.split(",")]

    renderer = Renderer()
    vpass = renderer.graph.passes["volumes"]
    scene = study_scene(args.scene, width, height)

    def render(settings, s=scene):
        vpass.settings = settings
        return renderer.render(s, timed=True)

    background = render(None, scene.model_copy(update={"effects": []})).rgba
    reference = render(VolumeSettings(**REFERENCE)).rgba
    mask = np.abs(reference[..., :3].astype(int) - background[..., :3].astype(int)).max(-1) > 2
    # Convergence check of the reference itself: 512 vs 1024 steps.
    half_ref = render(VolumeSettings(**{**REFERENCE, "steps": 512})).rgba
    ref_rmse, ref_low = errors(half_ref, reference, mask)

    rows = []
    for st in steps:
        for oc in octaves:
            for res in resolutions:
                settings = VolumeSettings(steps=st, octaves=oc, resolution=res, lod=False)
                rmse, low = errors(render(settings).rgba, reference, mask)
                total, march = [], []
                for i in range(args.frames):
                    moving = apply_patch(scene, {"time": {"sim_time": scene.time.sim_time + (i + 1) / 30.0}})
                    total.append(render(settings, moving).pass_ms["volumes"])
                    march.append(render(settings, moving).pass_ms["volumes"])
                rows.append({"steps": st, "octaves": oc, "resolution": res, "half_res": False,
                             "rmse": rmse, "lowpass": low,
                             "ms": statistics.median(total), "march_ms": statistics.median(march)})
                print(f"steps {st:4d} octaves {oc} res {res:3d} full  rmse {rmse:6.2f}  lowpass {low:5.2f}  "
                      f"ms {rows[-1]['ms']:7.1f}  (march {rows[-1]['march_ms']:6.1f})", flush=True)
    vpass.settings = None

    # Default: the cheapest point (by the march, the modelling cost is the texture's) whose banding
    # is under 2 levels of 8 bits and whose noise is under 6 levels: the knee of the curve.
    good = [r for r in rows if r["lowpass"] <= LOWPASS_LIMIT and r["rmse"] <= RMSE_LIMIT]
    choice = min(good, key=lambda r: r["ms"]) if good else min(rows, key=lambda r: r["lowpass"])

    report = {
        "renderer": renderer.caps.renderer, "scene": args.scene, "size": f"{width}x{height}",
        "reference": REFERENCE, "covered_fraction": float(mask.mean()),
        "reference_convergence": {"rmse_512_vs_1024": ref_rmse, "lowpass_512_vs_1024": ref_low},
        "rows": rows, "recommended": choice,
        "presets": {k: v.__dict__ for k, v in PRESETS.items()},
    }
    lines = [
        f"# Volumes: error against run time ({args.scene}, {width}x{height}, {renderer.caps.renderer})",
        "",
        f"Reference: {REFERENCE['steps']} steps, {REFERENCE['octaves']} octaves, {REFERENCE['resolution']}^3-class "
        f"texture, full resolution. Covered pixels: {100 * mask.mean():.1f} %. Reference convergence "
        f"(512 vs 1024 steps): rmse {ref_rmse:.2f}, lowpass {ref_low:.2f} (8-bit sRGB).",
        "Errors in 8-bit sRGB units over covered pixels; lowpass = after a 9x9 box blur (banding, bias).",
        "ms = volumes pass (modelling + march) with time running; march = same state again (no modelling).",
        "Half resolution: not implemented (all rows full).",
        "",
        "| steps | octaves | texture | res | rmse | lowpass | ms | march ms |",
        "|---:|---:|---:|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        mark = " **" if r is choice else ""
        lines.append(f"| {r['steps']} | {r['octaves']} | {r['resolution']} | full | {r['rmse']:.2f} | "
                     f"{r['lowpass']:.2f} | {r['ms']:.1f} | {r['march_ms']:.1f}{mark} |")
    lines += ["", f"Recommended default (cheapest with lowpass <= {LOWPASS_LIMIT} and rmse <= {RMSE_LIMIT}): steps {choice['steps']}, "
                  f"octaves {choice['octaves']}, texture {choice['resolution']}.",
              "Presets: " + ", ".join(f"{k} = {v.steps} steps / {v.octaves} oct / {v.resolution} tex"
                                       for k, v in PRESETS.items())]
    text = "\n".join(lines) + "\n"
    print(text)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    out.with_suffix(".json").write_text(json.dumps(report, indent=2))
    renderer.release()
    return 0
