"""Time the aerial-perspective table (render/common/aerial_table.py) two ways, for A/B runs of two
checkouts (run it with PYTHONPATH set to each in turn, interleaved; compare ratios):

  fill   the fill alone: the scene's table refilled N times (ctx.finish() around each), median ms
  turn   a turning camera: N frames with the heading advancing --step degrees a frame (and a small
         ship-like roll/pitch sway), timed renders: the frame (sum of passes) and the surfaces pass
         (which fills the table), median and p99 ms, and the number of fills

  PYTHONPATH=$PWD .venv/bin/python scripts/bench_aerial.py fill --scenes demo,night_fire --frames 20
  PYTHONPATH=$PWD .venv/bin/python scripts/bench_aerial.py turn --scenes demo --frames 120 --step 1.5
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import numpy as np

from igserver.render import frame as frame_mod
from igserver.render.common import aerial_table
from igserver.render.renderer import Renderer
from igserver.scene import apply_patch, load_scene


def base_scene(name: str, size: str, preset: str):
    w, h = (int(v) for v in size.split("x"))
    return apply_patch(load_scene(name), {"camera": {"width": w, "height": h}, "quality": {"preset": preset}})


def bench_fill(renderer, scene, frames: int) -> dict:
    ctx = renderer.ctx
    frame = frame_mod.build_frame(ctx, scene)
    aerial_table.frame_aerial_table(frame)  # compile + first fill
    table = frame.resources["aerial_table"]
    d_max = aerial_table.table_range(frame.scene, frame.view)
    ms, cpu = [], []
    for _ in range(frames):
        table._key = None
        ctx.finish()
        t, c = time.perf_counter(), time.process_time()
        table.update(frame.uniforms, d_max, ("bench",))
        ctx.finish()
        ms.append((time.perf_counter() - t) * 1e3)
        cpu.append((time.process_time() - c) * 1e3)  # all of llvmpipe's threads: less load-dependent
    return {"median": statistics.median(ms), "min": min(ms), "cpu_median": statistics.median(cpu)}


def bench_turn(renderer, scene, frames: int, step: float, warmup: int = 3) -> dict:
    cam = scene.camera
    ms, surfaces, cpu = [], [], []
    t0 = scene.time.sim_time
    table = None
    fills0 = 0
    for i in range(warmup + frames):
        s = apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0},
                                "camera": {"heading": (cam.heading + step * i) % 360.0,
                                           "roll": cam.roll + 3.0 * math.sin(i / 9.0),
                                           "pitch": cam.pitch + 1.0 * math.sin(i / 13.0)}})
        result = renderer.render(s, timed=True)  # each pass bracketed by ctx.finish()
        if i >= warmup:
            ms.append(sum(result.pass_ms.values()))
            surfaces.append(result.pass_ms.get("surfaces", 0.0))
            cpu.append(sum(result.pass_cpu_ms.get("surfaces", (0.0, 0.0))))  # all threads: less load-dependent
        if i == warmup - 1:
            table = aerial_table.AerialTable._resident.get(renderer.ctx)
            fills0 = table.fills if table is not None else 0
    fills = (table.fills - fills0) if table is not None else 0
    return {"frame_median": statistics.median(ms), "frame_p99": float(np.percentile(ms, 99)),
            "surfaces_median": statistics.median(surfaces), "surfaces_p99": float(np.percentile(surfaces, 99)),
            "surfaces_cpu_median": statistics.median(cpu), "surfaces_cpu_p99": float(np.percentile(cpu, 99)),
            "fills": fills}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["fill", "turn"])
    ap.add_argument("--scenes", default="demo,night_fire")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--preset", default="medium")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--step", type=float, default=1.5)
    ap.add_argument("--no-spread", action="store_true",
                    help="no table filled ahead in parts: refill at once when the view leaves the table")
    args = ap.parse_args()
    if args.no_spread:
        aerial_table.AERIAL_AHEAD = 1.0  # the view is never past the whole guard band while inside
    renderer = Renderer()
    out = {}
    for name in args.scenes.split(","):
        scene = base_scene(name, args.size, args.preset)
        out[name] = (bench_fill(renderer, scene, args.frames) if args.mode == "fill"
                     else bench_turn(renderer, scene, args.frames, args.step))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
