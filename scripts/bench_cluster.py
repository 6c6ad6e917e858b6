"""Frame time and frame lock of a local cluster against one render process (docs/cluster.md#figures).

    PYTHONPATH=. .venv/bin/python scripts/bench_cluster.py --scene sky_only --size 320x180 --frames 60

N channels (headings spread 60 deg apart) rendered by N CPU workers on a local Ray instance, and the same
state by one render process (RenderService); the state's host_frame changes every frame (a host
stepping). Prints the median and 95th percentile of the frame time of each, and of the cluster's
completion-time spread across channels.
"""

from __future__ import annotations

import argparse
import statistics
import time


def percentile(values: list[float], q: float) -> float:
    values = sorted(values)
    return values[min(int(q * len(values)), len(values) - 1)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="sky_only")
    parser.add_argument("--size", default="320x180")
    parser.add_argument("--channels", type=int, default=2)
    parser.add_argument("--frames", type=int, default=60)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))

    import ray

    from igserver.cluster.config import ClusterConfig
    from igserver.cluster.service import ClusterService
    from igserver.render.worker import RenderService
    from igserver.scene import apply_patch, load_scene

    n = args.channels
    channels = [{"id": f"c{i}", "heading": 60.0 * (i - (n - 1) / 2), "width": width, "height": height}
                for i in range(n)]
    scene = apply_patch(load_scene(args.scene), {"channels": channels})
    ray.init(num_cpus=n, include_dashboard=False, log_to_driver=False)
    results = {}
    cluster = ClusterService(ClusterConfig(workers=n, channels=channels, barrier_timeout_ms=30_000), scene).start()
    spreads: list[float] = []
    observe = cluster.metrics.observe_spread
    cluster.metrics.observe_spread = lambda s: (spreads.append(s * 1e3), observe(s))
    with RenderService(scene) as single:
        for name, service in (("cluster", cluster), ("one process", single)):
            times = []
            for i in range(args.frames + 5):
                state = apply_patch(scene, {"host_frame": i + 1})
                t0 = time.perf_counter()
                frame = service.render(state)
                if i >= 5:  # warm-up: shaders, tables
                    times.append((time.perf_counter() - t0) * 1e3)
                assert frame.host_frame == i + 1 and not frame.missing
            results[name] = times
    cluster.stop()
    ray.shutdown()
    print(f"{n} x {width}x{height} channels of {args.scene}, {args.frames} frames")
    for name, times in results.items():
        print(f"  {name:12s} frame median {statistics.median(times):7.1f} ms  p95 {percentile(times, 0.95):7.1f} ms")
    spreads = spreads[5:]
    print(f"  cluster spread median {statistics.median(spreads):.2f} ms  p95 {percentile(spreads, 0.95):.2f} ms")


if __name__ == "__main__":
    main()
