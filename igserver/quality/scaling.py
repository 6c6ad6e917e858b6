"""``igserver quality scaling``: the internal render scale's error against a full-resolution render.

Each scale draws the frame at scale x the requested size and upscales it (render/scaling.py); the
reference is the same frame drawn at the requested size. The error is the picture's: PSNR (dB, of
the 8-bit sRGB RGB values) and SSIM (the mean structural similarity of the luma, Wang et al. 2004:
an 11-tap Gaussian window of sigma 1.5, K1 = 0.01, K2 = 0.03, L = 255), for the upscaler and for a
plain bilinear upscale as the baseline. Time: ms per frame (the median of frames rendered alone).

Usage: igserver quality scaling [--scene demo] [--size 640x360] [--frames 5] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

from ..scene import apply_patch, load_scene
from .report import Point, Study

LUMA_601 = np.array([0.299, 0.587, 0.114])  # Rec. 601 weights, as the SSIM paper's grey images (not photometry.LUMA)
SSIM_SIGMA = 1.5
SSIM_RADIUS = 5  # 11 taps
K1, K2, PEAK = 0.01, 0.03, 255.0


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """dB, 10 log10(255^2 / MSE) over the RGB values of two uint8 frames (inf when equal)."""
    d = a[..., :3].astype(np.float64) - b[..., :3].astype(np.float64)
    mse = float(np.mean(d * d))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(PEAK * PEAK / mse)


def _gaussian_blur(x: np.ndarray) -> np.ndarray:
    """Separable Gaussian window (the SSIM paper's), 'valid' region only: no padding enters the means."""
    t = np.arange(-SSIM_RADIUS, SSIM_RADIUS + 1, dtype=np.float64)
    w = np.exp(-0.5 * (t / SSIM_SIGMA) ** 2)
    w /= w.sum()
    n = len(w)
    rows = sum(w[i] * x[:, i:x.shape[1] - n + 1 + i] for i in range(n))
    return sum(w[i] * rows[i:rows.shape[0] - n + 1 + i, :] for i in range(n))


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean SSIM of the luma of two uint8 frames: per window, (2 mu_a mu_b + C1)(2 cov + C2) /
    ((mu_a^2 + mu_b^2 + C1)(var_a + var_b + C2)), C1 = (K1 L)^2, C2 = (K2 L)^2; 1 = identical."""
    x = a[..., :3].astype(np.float64) @ LUMA_601
    y = b[..., :3].astype(np.float64) @ LUMA_601
    c1, c2 = (K1 * PEAK) ** 2, (K2 * PEAK) ** 2
    mx, my = _gaussian_blur(x), _gaussian_blur(y)
    vx = _gaussian_blur(x * x) - mx * mx
    vy = _gaussian_blur(y * y) - my * my
    cov = _gaussian_blur(x * y) - mx * my
    s = (2 * mx * my + c1) * (2 * cov + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return float(np.mean(s))


def render_at(renderer, scene, scale: float, bilinear: bool = False, frames: int = 1) -> tuple[np.ndarray, float]:
    """The frame of ``scene`` drawn at ``scale`` and upscaled (the plain bilinear filter if asked),
    and the median ms of ``frames`` renders. The eye's adaptation starts afresh each time, so every
    scale is metered from its own frame, as a stream at that scale would be."""
    from ..render.frame import FrameState
    from ..render.scaling import Upscaler

    renderer.render_scale = scale
    if scale < 1.0:
        renderer._upscaler = Upscaler(renderer.ctx, renderer.programs, bilinear=bilinear)
    times, rgba = [], None
    for _ in range(frames + 1):  # the first frame builds the targets and programs: not timed
        renderer.frame_state = FrameState()
        result = renderer.render(scene)
        times.append(result.total_ms)
        rgba = result.rgba
    renderer.render_scale = 1.0
    renderer._upscaler = None
    return rgba, statistics.median(times[1:])


def measure(scene_name: str, width: int, height: int, scales, frames: int) -> list[dict]:
    """Rows of (scale, filter, PSNR, SSIM, ms) against the scale-1 frame."""
    from ..render.renderer import Renderer

    scene = apply_patch(load_scene(scene_name), {"camera": {"width": width, "height": height}})
    renderer = Renderer()
    try:
        reference, ms = render_at(renderer, scene, 1.0, frames=frames)
        rows = [{"scale": 1.0, "filter": "-", "psnr": float("inf"), "ssim": 1.0, "ms": ms}]
        for scale in scales:
            for bilinear in (False, True):
                rgba, ms = render_at(renderer, scene, scale, bilinear, frames=frames)
                rows.append({"scale": scale, "filter": "bilinear" if bilinear else "catmull-rom, 2x2 clamp",
                             "psnr": psnr(rgba, reference), "ssim": ssim(rgba, reference), "ms": ms})
    finally:
        renderer.release()
    return rows


def markdown(rows: list[dict], scene: str, width: int, height: int) -> str:
    lines = [f"Scene {scene} at {width}x{height}; reference: the same frame at scale 1.0.", "",
             "| scale | pixels | upscale filter | PSNR dB | SSIM | ms/frame |", "|---|---|---|---|---|---|"]
    for r in rows:
        psnr_s = "∞" if r["psnr"] == float("inf") else f"{r['psnr']:.2f}"
        lines.append(f"| {r['scale']:.2f} | {r['scale'] ** 2:.0%} | {r['filter']} | {psnr_s} | {r['ssim']:.4f} "
                     f"| {r['ms']:.1f} |")
    return "\n".join(lines) + "\n"


def _parse(argv: list[str]) -> argparse.Namespace:
    from ..render.operating_points import SCALES

    ap = argparse.ArgumentParser(prog="igserver quality scaling")
    ap.add_argument("--scene", default="demo")
    ap.add_argument("--size", default="640x360", help="WxH of the requested frame")
    ap.add_argument("--scales", default=",".join(str(s) for s in SCALES[1:]))
    ap.add_argument("--frames", type=int, default=5, help="timed frames per point")
    ap.add_argument("--out", default="out/quality/scaling")
    return ap.parse_args(argv)


def run(argv: list[str]) -> int:
    args = _parse(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    rows = measure(args.scene, width, height, [float(s) for s in args.scales.split(",")], args.frames)
    text = markdown(rows, args.scene, width, height)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "scaling.md").write_text(text)
    (out / "scaling.json").write_text(json.dumps(rows, indent=1, default=str))
    print(text)
    return 0


def study(quick: bool = False) -> Study:
    """The combined report's points: error = 100 (1 - SSIM) against ms per frame, one curve per filter."""
    from ..render.operating_points import SCALES

    size = (320, 180) if quick else (640, 360)
    rows = measure("demo", *size, SCALES[1:], 2 if quick else 5)
    points = [Point("filter=" + r["filter"], f"scale={r['scale']:.2f}", 100.0 * (1.0 - r["ssim"]), r["ms"],
                    extra={"psnr": r["psnr"]}) for r in rows]
    return Study("scaling", "100 (1 - SSIM) of the luma against the scale-1 frame",
                 f"ms per frame, demo at {size[0]}x{size[1]}", points)
