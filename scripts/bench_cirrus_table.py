"""The cirrus table per change against per frame (sky.py CIRRUS_REDRAW_PX against 0), interleaved in one
process: two renderers, a still camera, N frames at 30 Hz, timed renders; medians of the frame's wall and
process CPU and of the sky pass's CPU (calling thread + workers), and the tables each drew.

    PYTHONPATH=$PWD .venv/bin/python scripts/bench_cirrus_table.py demo "{}" 40
    PYTHONPATH=$PWD .venv/bin/python scripts/bench_cirrus_table.py sky_only '{"time": {"utc": "2026-06-21T19:00:00Z"}, "camera": {"heading": 300.0, "pitch": 8.0, "width": 640, "height": 360}, "weather": {"cirrus_coverage": 0.6}}' 40
"""
import json
import sys, time, statistics, numpy as np
from igserver.render.renderer import Renderer
from igserver.scene.files import load_scene
from igserver.scene.patch import apply_patch
name, patch, n = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3])
base = apply_patch(load_scene(name), patch)
A, B = Renderer(), Renderer()
A.graph.passes["sky"].cirrus_redraw_px = 0.0  # before: drawn every frame
res = {"A": ([], [], []), "B": ([], [], [])}
t0 = base.time.sim_time
for i in range(n + 3):
    s = apply_patch(base, {"time": {"sim_time": t0 + i / 30.0}})
    for k, r in (("A", A), ("B", B)) if i % 2 else (("B", B), ("A", A)):
        w, c = time.perf_counter(), time.process_time()
        rt = r.render(s, timed=True)
        w, c = time.perf_counter() - w, time.process_time() - c
        if i >= 3:
            res[k][0].append(w * 1e3); res[k][1].append(c * 1e3)
            res[k][2].append(rt.pass_cpu_ms["sky"][0] + rt.pass_cpu_ms["sky"][1])
draws = B.graph.passes["sky"].cirrus_draws, A.graph.passes["sky"].cirrus_draws
m = {k: [statistics.median(x) for x in v] for k, v in res.items()}
print(f"sky pass CPU ms (calling+workers) A {m['A'][2]:.1f} B {m['B'][2]:.1f} ({m['B'][2]/m['A'][2]:.3f}x)")
print(f"{name}: wall A {m['A'][0]:.1f} B {m['B'][0]:.1f} ({m['B'][0]/m['A'][0]:.3f}x) | process CPU A {m['A'][1]:.1f} B {m['B'][1]:.1f} ({m['B'][1]/m['A'][1]:.3f}x) | table draws B {draws[0]} A {draws[1]} over {n+3} frames")
