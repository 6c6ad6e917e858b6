"""``igserver bench``: frame time per pass and in total, per scene, resolution and quality preset.

Each pass is bracketed by ``ctx.finish()`` and a wall clock (llvmpipe has no usable timer queries);
``frame`` is the same frame rendered without the per-pass synchronisation, i.e. what a client sees.
Animation advances by 1/30 s per frame so time-dependent work (noise, flicker) is really done, the
way the IG clock steps a stream (``scene.at_sim_time``: the rest of the state stays the same objects).

Besides, per scene, after those frames:

- **Python ms** (``python_ms``): the frame's host time outside GL calls (Python and numpy), from a
  separate instrumented pass of as many frames, each counted with ``render.gl_count.GLCallCounter``:
  the calling thread's CPU time for the frame (``time.thread_time``) minus the CPU time spent inside
  moderngl calls (which on llvmpipe includes its vertex work and binning) minus the counting wrappers'
  own overhead (calls x one wrapper's cost, calibrated on a no-op). CPU time, not wall time: waiting
  for the driver is not counted, on either side.
- **GL calls** (``gl_calls``) and **GL objects created** (``gl_objects_created``) per frame, counted
  at moderngl's boundary in the same instrumented frames; objects created must be 0 in steady state.
- **fps in flight** (``fps_in_flight``): frames through ``Renderer.submit`` (each frame's pixels are
  copied out while the next is drawn), frames / wall s, readback included; ``fps_sync`` the same through
  ``render`` (draw, then read): blocks of each alternating twice, so both see the same machine load.
- **GPU ms per pass** (``gpu_pass_ms``), where GL timer queries work: each pass bracketed by a
  ``ctx.query(time=True)`` in one more pass of frames, each frame queued behind a GPU head start so
  that the queries count the GPU's work and not its idling while the host issues commands
  (``bench_gpu.py``; ``gpu_timing`` says how they were taken). llvmpipe has no GPU clock (its queries
  read 0): there the row says why not (``gpu_timer``).
"""

from __future__ import annotations

import json
import statistics
import time

import numpy as np
from pydantic import ValidationError

from .bench_gpu import gpu_pass_ms, timer_queries_unusable
from .render.gl_count import GLCallCounter
from .scene import apply_patch, at_sim_time, load_scene
from .scene.patch import patch_from_assignments

DEFAULT_SCENES = ["sky_only", "clear_noon_ocean", "demo", "night_fire", "high_altitude"]


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


def _instrumented(renderer, scenes) -> dict:
    """Python ms, GL calls and GL objects created per frame: one counted frame per scene."""
    python_ms, calls, created = [], [], []
    with GLCallCounter() as counter:
        for s in scenes:
            total, gl_cpu, made = counter.total, counter.gl_cpu_s, counter.created()
            cpu0 = time.thread_time()
            renderer.render(s)
            cpu = time.thread_time() - cpu0
            n = counter.total - total
            python_ms.append((cpu - (counter.gl_cpu_s - gl_cpu) - n * counter.wrapper_cost_s) * 1e3)
            calls.append(n)
            created.append(counter.created() - made)
    return {"python_ms": {"median": statistics.median(python_ms), "p99": percentile(python_ms, 99)},
            "gl_calls": int(statistics.median(calls)), "gl_objects_created": max(created)}


def _throughput(renderer, scenes) -> tuple[float, float]:
    """Frames per second one after another (``render``) and in flight (``submit``: each frame read while
    the next is drawn), in 4 blocks of ``scenes`` alternating, so both see the same load."""
    renderer.submit(scenes[0])  # the readback ring's buffers are made here, not in the timed loop
    renderer.collect()
    k = len(scenes) // 4
    seconds = {"sync": 0.0, "in_flight": 0.0}
    frames = dict.fromkeys(seconds, 0)
    for block in range(4):
        mode = ("sync", "in_flight", "in_flight", "sync")[block]
        chunk = scenes[block * k:(block + 1) * k]
        start = time.perf_counter()
        for s in chunk:
            if mode == "sync":
                renderer.render(s)
            else:
                renderer.submit(s)
        while renderer.in_flight:
            renderer.collect()
        seconds[mode] += time.perf_counter() - start
        frames[mode] += k
    return frames["sync"] / seconds["sync"], frames["in_flight"] / seconds["in_flight"]


def bench_scene(renderer, scene, frames: int, warmup: int = 3, gpu_timer: str | None = "not asked") -> dict:
    """One scene's row. ``gpu_timer``: None to time passes with GL timer queries, else why not."""
    per_pass: dict[str, list[float]] = {}
    per_pass_cpu: dict[str, list[tuple[float, float]]] = {}
    totals, frame_ms = [], []
    t0 = scene.time.sim_time
    for i in range(warmup + frames):
        s = at_sim_time(scene, t0 + i / 30.0)  # the IG clock's step: the rest of the state is the same objects
        result = renderer.render(s, timed=True)
        # A different sim_time, so time-animated work (volume modelling) is really redone.
        s_untimed = at_sim_time(scene, t0 + (i + 0.5) / 30.0)
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
    # The same clock steps again, after the frames above: the world is as warm as in a stream.
    later = [at_sim_time(scene, t0 + (warmup + frames + i) / 30.0) for i in range(frames)]
    extra = _instrumented(renderer, later)
    n = 4 * max(frames // 4, 2)  # 4 blocks of at least 2 frames: one frame in flight while one is drawn
    stream = [at_sim_time(scene, t0 + (warmup + frames + i) / 30.0) for i in range(n)]
    extra["fps_sync"], extra["fps_in_flight"] = _throughput(renderer, stream)
    if gpu_timer is None:
        extra.update(gpu_pass_ms(renderer, later, host_ms=statistics.median(frame_ms)))
    else:
        extra["gpu_timer"] = gpu_timer
    return {
        **extra,
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
    head = ["scene", "resolution", "preset", "frame median (p99)", "fps in flight", "Python ms", "GL calls",
            "GL objects made", *passes]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["runs"]:
        if "skipped" in r:
            lines.append(f"| `{r['scene']}` | {r['resolution']} | {r['preset']} | refused (over the render budget) |"
                         + " |" * (len(passes) + 4))
            continue
        cells = [f"`{r['scene']}`", r["resolution"], r["preset"],
                 f"{r['frame_ms']['median']:.1f} ({r['frame_ms']['p99']:.1f})", f"{r['fps_in_flight']:.1f}",
                 f"{r['python_ms']['median']:.1f}", str(r["gl_calls"]), str(r["gl_objects_created"]),
                 *(f"{r['pass_ms'][p]['median']:.1f}" if p in r["pass_ms"] else "–" for p in passes)]
        lines.append("| " + " | ".join(cells) + " |")
    gpu_runs = [r for r in runs if "gpu_pass_ms" in r]
    if gpu_runs:  # GPU time per pass from timer queries: only where the driver has them
        gpu_passes = [p for p in TABLE_PASSES if any(p in r["gpu_pass_ms"] for r in gpu_runs)]
        head = ["scene", "resolution", "preset", "GPU ms (sum of passes)", *(f"{p} GPU ms" for p in gpu_passes)]
        lines += ["", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in gpu_runs:
            g = r["gpu_pass_ms"]
            cells = [f"`{r['scene']}`", r["resolution"], r["preset"], f"{sum(g.values()):.2f}",
                     *(f"{g[p]:.2f}" if p in g else "–" for p in gpu_passes)]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _write_json(path: str, report: dict) -> None:
    with open(path, "w") as fh:
        json.dump(report, fh, indent=2)


def run(scenes: list[str], resolutions: list[tuple[int, int]], frames: int, assignments: list[str],
        json_path: str | None = None, presets: list[str] | None = None, markdown_path: str | None = None) -> dict:
    from .render.renderer import Renderer
    from .source_id import source_id

    renderer = Renderer()
    gpu_timer = timer_queries_unusable(renderer)
    report = {"renderer": renderer.caps.renderer, "gl_version": renderer.caps.version, "frames": frames,
              "gpu_timer": gpu_timer or "timer queries", "runs": []}
    report["source"] = source_id()  # which code was measured (source_id.py)
    print(f"renderer: {renderer.caps.renderer} | GL {renderer.caps.version} | {frames} frames, medians (p99) in ms"
          f" | source {report['source']}"
          f" | GPU ms per pass: {gpu_timer or 'timer queries'}")
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
                row = bench_scene(renderer, scene, frames, gpu_timer=gpu_timer)
                row.update(scene=name, resolution=f"{width}x{height}", preset=preset)
                report["runs"].append(row)
                if json_path:  # after every row, so a run cut short by a time limit still leaves its rows
                    _write_json(json_path, report)
                passes = "  ".join(f"{k} {v['median']:.2f} ({v['p99']:.2f})" for k, v in row["pass_ms"].items())
                extra = "".join(f"  |  {k}: " + ", ".join(f"{sk} {sv:.4g}" if isinstance(sv, float) else f"{sk} {sv}"
                                                           for sk, sv in v.items()) for k, v in row["stats"].items())
                cpu = "  ".join(f"{k} {v['calling_thread']:.1f}/{v['workers']:.1f}" for k, v in row["pass_cpu_ms"].items())
                gpu = (f"  |  GPU ms ({row['gpu_timing']}): " + "  ".join(f"{k} {v:.3f}" for k, v in row["gpu_pass_ms"].items())
                       if "gpu_pass_ms" in row else "")
                print(f"{name:18s} {width}x{height} {preset:6s}  frame {row['frame_ms']['median']:.2f} "
                      f"({row['frame_ms']['p99']:.2f})  fps in flight {row['fps_in_flight']:.1f} (one after another "
                      f"{row['fps_sync']:.1f})  Python "
                      f"{row['python_ms']['median']:.2f} ms  GL calls {row['gl_calls']}  GL objects made "
                      f"{row['gl_objects_created']}  sum-of-passes {row['total_ms']['median']:.2f} "
                      f"({row['total_ms']['p99']:.2f})  |  {passes}{extra}  |  cpu ms calling thread/workers: {cpu}{gpu}",
                      flush=True)
    if json_path:
        _write_json(json_path, report)
    table = markdown_table(report)
    print(f"\nrenderer: {report['renderer']}\n\n{table}")
    if markdown_path:
        with open(markdown_path, "w") as fh:
            fh.write(f"renderer: {report['renderer']} (GL {report['gl_version']}), {frames} frames\n\n{table}\n")
    renderer.release()
    return report
