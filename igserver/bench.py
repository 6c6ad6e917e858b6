"""``igserver bench``: frame time per pass and in total, per scene, resolution and quality preset.

Each pass is bracketed by ``ctx.finish()`` and a wall clock (llvmpipe has no usable timer queries);
``frame`` is the same frame rendered without the per-pass synchronisation, i.e. what a client sees.
Animation advances by 1/30 s per frame so time-dependent work (noise, flicker) is really done.
"""

from __future__ import annotations

import json
import statistics
import time

import numpy as np
from pydantic import ValidationError

from .scene import apply_patch, load_scene
from .scene.patch import patch_from_assignments

DEFAULT_SCENES = ["sky_only", "clear_noon_ocean", "demo", "night_fire", "high_altitude"]


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


def bench_scene(renderer, scene, frames: int, warmup: int = 3) -> dict:
    per_pass: dict[str, list[float]] = {}
    per_pass_cpu: dict[str, list[tuple[float, float]]] = {}
    totals, frame_ms = [], []
    t0 = scene.time.sim_time
    for i in range(warmup + frames):
        s = apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0}})
        result = renderer.render(s, timed=True)
        # A different sim_time, so time-animated work (volume modelling) is really redone.
        s_untimed = apply_patch(scene, {"time": {"sim_time": t0 + (i + 0.5) / 30.0}})
        start = time.perf_counter()
        renderer.render(s_untimed, timed=False)
        untimed = (time.perf_counter() - start) * 1e3
        if i < warmup:
            continue
        for name, ms in result.pass_ms.items():
            per_pass.setdefault(name, []).append(ms)
        for name, cpu in result.pass_cpu_ms.items():
            per_pass_cpu.setdefault(name, []).append(cpu)
        totals.append(sum(result.pass_ms.values()))
        frame_ms.append(untimed)
    # Passes that report geometry (e.g. water: triangles drawn, LOD error bound) add it to the row.
    stats = {name: dict(p.stats) for name, p in renderer.graph.passes.items()
             if name in result.passes and getattr(p, "stats", None)}
    return {
        "passes": result.passes,
        "stats": stats,
        "pass_ms": {k: {"median": statistics.median(v), "p99": percentile(v, 99)} for k, v in per_pass.items()},
        # Medians of CPU ms in the calling thread (on llvmpipe: vertex work, triangle setup, binning and
        # Python, one core) and in all other threads (llvmpipe's rasteriser workers): a pass whose
        # calling-thread share is large is bound by one core whatever the worker count.
        "pass_cpu_ms": {k: {"calling_thread": statistics.median(c for c, _ in v),
                            "workers": statistics.median(w for _, w in v)} for k, v in per_pass_cpu.items()},
        "total_ms": {"median": statistics.median(totals), "p99": percentile(totals, 99)},
        "frame_ms": {"median": statistics.median(frame_ms), "p99": percentile(frame_ms, 99)},
    }


TABLE_PASSES = ["sky", "surfaces", "water", "volumes", "precip", "post"]


def markdown_table(report: dict) -> str:
    """The README's performance table: per scene x resolution x preset, frame median (p99) and
    per-pass medians (ms)."""
    runs = [r for r in report["runs"] if "skipped" not in r]
    passes = [p for p in TABLE_PASSES if any(p in r["pass_ms"] for r in runs)]
    head = ["scene", "resolution", "preset", "frame median (p99)", *passes]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["runs"]:
        if "skipped" in r:
            lines.append(f"| `{r['scene']}` | {r['resolution']} | {r['preset']} | refused (over the render budget) |"
                         + " |" * len(passes))
            continue
        cells = [f"`{r['scene']}`", r["resolution"], r["preset"],
                 f"{r['frame_ms']['median']:.1f} ({r['frame_ms']['p99']:.1f})",
                 *(f"{r['pass_ms'][p]['median']:.1f}" if p in r["pass_ms"] else "–" for p in passes)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def run(scenes: list[str], resolutions: list[tuple[int, int]], frames: int, assignments: list[str],
        json_path: str | None = None, presets: list[str] | None = None, markdown_path: str | None = None) -> dict:
    from .render.renderer import Renderer

    renderer = Renderer()
    report = {"renderer": renderer.caps.renderer, "gl_version": renderer.caps.version, "frames": frames, "runs": []}
    print(f"renderer: {renderer.caps.renderer} | GL {renderer.caps.version} | {frames} frames, medians (p99) in ms")
    patch = patch_from_assignments(assignments)
    for name in scenes:
        base = apply_patch(load_scene(name), patch)
        for width, height in resolutions:
            for preset in presets or [base.quality.preset]:
                try:
                    scene = apply_patch(base, {"camera": {"width": width, "height": height},
                                               "quality": {"preset": preset}})
                except ValidationError as exc:  # e.g. over the render budget: the IG refuses it too
                    reason = "; ".join(e["msg"] for e in exc.errors())
                    print(f"{name:18s} {width}x{height} {preset:6s}  skipped: {reason}", flush=True)
                    report["runs"].append({"scene": name, "resolution": f"{width}x{height}", "preset": preset,
                                           "skipped": reason})
                    continue
                row = bench_scene(renderer, scene, frames)
                row.update(scene=name, resolution=f"{width}x{height}", preset=preset)
                report["runs"].append(row)
                passes = "  ".join(f"{k} {v['median']:.2f} ({v['p99']:.2f})" for k, v in row["pass_ms"].items())
                extra = "".join(f"  |  {k}: " + ", ".join(f"{sk} {sv:.4g}" if isinstance(sv, float) else f"{sk} {sv}"
                                                           for sk, sv in v.items()) for k, v in row["stats"].items())
                cpu = "  ".join(f"{k} {v['calling_thread']:.1f}/{v['workers']:.1f}" for k, v in row["pass_cpu_ms"].items())
                print(f"{name:18s} {width}x{height} {preset:6s}  frame {row['frame_ms']['median']:.2f} "
                      f"({row['frame_ms']['p99']:.2f})  sum-of-passes {row['total_ms']['median']:.2f} "
                      f"({row['total_ms']['p99']:.2f})  |  {passes}{extra}  |  cpu ms calling thread/workers: {cpu}",
                      flush=True)
    if json_path:
        with open(json_path, "w") as fh:
            json.dump(report, fh, indent=2)
    table = markdown_table(report)
    print(f"\nrenderer: {report['renderer']}\n\n{table}")
    if markdown_path:
        with open(markdown_path, "w") as fh:
            fh.write(f"renderer: {report['renderer']} (GL {report['gl_version']}), {frames} frames\n\n{table}\n")
    renderer.release()
    return report
