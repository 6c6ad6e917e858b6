"""``igserver bench --channels N``: the cost of N channels of one state against one channel.

A stream's frames (sim_time advancing 1/30 s a frame, so animated world work is redone) of N
channels side by side, ahead in the middle (headings ``(i - (N-1)/2) * 60`` deg, 30 deg half-angles
each way, 16:9 half-angles up and down), against the same frames through the centre channel alone.
The two are interleaved frame by frame (each drawn by a renderer of its own, which keeps its views'
state as an IG showing one set of channels does), so both see the same load on a shared machine.
The ratio of the medians is what N channels cost in units of one: N when nothing is shared, near 1 when the world
work dominates. Target on llvmpipe for 3 x 640x360 on the demo: <= 2.4 (docs/channels.md).
"""

from __future__ import annotations

import json
import statistics
import time

from .bench import percentile
from .scene import apply_patch, load_scene, patch_from_assignments

HALF_WIDTH_DEG = 30.0
HALF_HEIGHT_DEG = 18.0  # with 30 deg across: 16:9 within 0.05 %


def channel_list(n: int, width: int, height: int) -> list[dict]:
    """``n`` adjacent channels sharing their edges, the middle one (or the pair around it) ahead."""
    return [{"id": f"c{i}", "heading": (i - (n - 1) / 2) * 2 * HALF_WIDTH_DEG, "fov_left": HALF_WIDTH_DEG,
             "fov_right": HALF_WIDTH_DEG, "fov_up": HALF_HEIGHT_DEG, "fov_down": HALF_HEIGHT_DEG,
             "width": width, "height": height} for i in range(n)]


def bench_channels(renderers: dict, scene, n: int, width: int, height: int, frames: int, warmup: int = 3) -> dict:
    """``renderers``: {"one": Renderer, "many": Renderer}, each drawing one of the two streams (as an IG
    drawing one channel set would: its per-view state kept from frame to frame)."""
    many = apply_patch(scene, {"channels": channel_list(n, width, height)})
    one = apply_patch(scene, {"channels": [dict(channel_list(1, width, height)[0], heading=0.0)]})
    ms: dict[str, list[float]] = {"one": [], "many": []}
    cpu: dict[str, list[float]] = {"one": [], "many": []}  # CPU ms of all the process's threads
    t0 = scene.time.sim_time
    for i in range(warmup + frames):
        t = t0 + i / 30.0
        for key, s in (("one", one), ("many", many)):
            s = apply_patch(s, {"time": {"sim_time": t}})
            start, cpu0 = time.perf_counter(), time.process_time()
            result = renderers[key].render(s)
            if i >= warmup:
                ms[key].append((time.perf_counter() - start) * 1e3)
                cpu[key].append((time.process_time() - cpu0) * 1e3)
    row = {k: {"median": statistics.median(v), "p99": percentile(v, 99)} for k, v in ms.items()}
    row.update(channels=n, resolution=f"{width}x{height}", passes=result.passes,
               ratio=row["many"]["median"] / row["one"]["median"],
               # on llvmpipe the work itself (every thread's CPU time): what a busy machine shares out
               cpu_ratio=statistics.median(cpu["many"]) / statistics.median(cpu["one"]))
    return row


def run_channels(scenes: list[str], resolutions: list[tuple[int, int]], frames: int, assignments: list[str],
                 n: int, json_path: str | None = None) -> dict:
    from .render.renderer import Renderer

    renderers = {"one": Renderer(), "many": Renderer()}
    renderer = renderers["many"]
    report = {"renderer": renderer.caps.renderer, "gl_version": renderer.caps.version, "frames": frames, "runs": []}
    print(f"renderer: {renderer.caps.renderer} | GL {renderer.caps.version} | {frames} frames, medians (p99) in ms")
    patch = patch_from_assignments(assignments)
    for name in scenes:
        base = apply_patch(load_scene(name), patch)
        for width, height in resolutions:
            row = bench_channels(renderers, base, n, width, height, frames)
            row["scene"] = name
            report["runs"].append(row)
            print(f"{name:18s} {n} x {width}x{height}  frame {row['many']['median']:.1f} ({row['many']['p99']:.1f})"
                  f"  one channel {row['one']['median']:.1f} ({row['one']['p99']:.1f})  ratio {row['ratio']:.2f}"
                  f"  (CPU time ratio {row['cpu_ratio']:.2f})",
                  flush=True)
            if json_path:
                with open(json_path, "w") as fh:
                    json.dump(report, fh, indent=2)
    for r in renderers.values():
        r.release()
    return report
