"""What the cluster adds to ``/metrics``: frame lock, barrier misses, worker restarts.

The metrics are made unregistered and added to the server's registry when the runtime starts
(``ClusterService.register_metrics``), so the cluster's service carries its counts before and after.
"""

from __future__ import annotations

from prometheus_client import Counter, Gauge, Histogram

# seconds: the spread of completion times of one frame's channels, from a shared GPU's microseconds to a
# barrier timeout
SPREAD_BUCKETS = (0.0001, 0.00025, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)


class ClusterMetrics:
    def __init__(self) -> None:
        self.spread = Histogram(
            "igserver_cluster_frame_spread_seconds",
            "Frame lock: per frame, the latest minus the earliest completion time of its channels (each channel "
            "completes when its worker has read back its pixels; worker clocks)", buckets=SPREAD_BUCKETS,
            registry=None)
        self.last_spread = Gauge("igserver_cluster_frame_spread_last_seconds",
                                 "Frame lock: the completion-time spread of the last frame with two or more workers",
                                 registry=None)
        self.frames = Counter("igserver_cluster_frames", "Frames gathered at the barrier", registry=None)
        self.incomplete = Counter("igserver_cluster_frames_incomplete",
                                  "Frames that went out without a worker's channels (it missed the barrier)",
                                  registry=None)
        self.misses = Counter("igserver_cluster_barrier_misses",
                              "Frames a worker missed: not back within barrier_timeout_ms, busy with an older "
                              "frame, or failed", ["worker"], registry=None)
        self.restarts = Counter("igserver_cluster_worker_restarts",
                                "Workers Ray restarted (seen as a new process answering)", ["worker"], registry=None)
        self.redraws = Counter("igserver_cluster_exposure_redraws",
                               "Frames drawn again with the shared exposure (the first, a paused clock's jump)",
                               registry=None)
        self.workers = Gauge("igserver_cluster_workers", "Channel workers configured", registry=None)
        self.workers_alive = Gauge("igserver_cluster_workers_alive",
                                   "Channel workers not dead for good (Ray restarts the others)", registry=None)
        self.collectors = (self.spread, self.last_spread, self.frames, self.incomplete, self.misses, self.restarts,
                           self.redraws, self.workers, self.workers_alive)

    def register(self, registry) -> None:
        for collector in self.collectors:
            registry.register(collector)

    def observe_spread(self, seconds: float) -> None:
        self.spread.observe(seconds)
        self.last_spread.set(seconds)
