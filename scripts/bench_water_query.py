"""Host water-height query cost: per-call medians (thread CPU time, or wall with CLOCK=wall) for 100..10000
points, open sea and the test beach, wind 12 m/s.

    OPENBLAS_NUM_THREADS=1 taskset -c 1 .venv/bin/python scripts/bench_water_query.py [BASELINE_SURFACE_PY]

With a path to an older igserver/water/surface.py (e.g. `git show c313b53:igserver/water/surface.py >
/tmp/surface_base.py`), runs it interleaved with the current one (A/B) and prints the ratio and the
largest differences of the answers. RUNS (21) and SIZES (100,1000,4000,10000) from the environment."""

import importlib.util
import os
import sys
import time

import numpy as np

from igserver.scene.model import Ocean, Weather
import igserver.water.surface as current

CLOCK = time.thread_time if os.environ.get("CLOCK", "cpu") == "cpu" else time.perf_counter
BEACH = {"type": "slope", "depth": 30.0, "slope": 0.03, "shore_distance": 800.0, "shore_heading": 90.0}
RUNS = int(os.environ.get("RUNS", 21))
SIZES = [int(s) for s in os.environ.get("SIZES", "100,1000,4000,10000").split(",")]

modules = {"now": current}
if len(sys.argv) > 1:
    spec = importlib.util.spec_from_file_location("igserver.water.surface_base", sys.argv[1])
    base = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = base
    spec.loader.exec_module(base)
    modules = {"before": base, "now": current}

for name, bathy, lo, hi in (("uniform", None, -1000, 1000), ("beach", BEACH, -400, 790)):
    ocean = Ocean(enabled=True, bathymetry=bathy) if bathy else Ocean(enabled=True)
    seas = {k: m.sea_surface(ocean, Weather(wind_speed=12.0)) for k, m in modules.items()}
    for n in SIZES:
        xy = np.random.default_rng(5).uniform(lo, hi, (n, 2))
        times = {k: [] for k in seas}
        for sea in seas.values():
            sea.query(xy, 55.5)  # warm: caches and buffers
        for r in range(RUNS):
            for k in (list(seas) if r % 2 == 0 else list(seas)[::-1]):
                t0 = CLOCK()
                seas[k].query(xy, 55.5)
                times[k].append(CLOCK() - t0)
        med = {k: float(np.median(v)) * 1e3 for k, v in times.items()}
        line = f"{name:8s} n={n:6d} " + "  ".join(f"{k} {v:7.2f} ms" for k, v in med.items())
        if "before" in seas:
            a, b = seas["before"].query(xy, 55.5), seas["now"].query(xy, 55.5)
            line += (f"  ratio {med['before'] / med['now']:5.2f}  max|dh| {np.max(np.abs(a['height'] - b['height'])):.1e} m"
                     f"  |dn| {np.max(np.abs(a['normal'] - b['normal'])):.1e}")
        print(line, flush=True)
