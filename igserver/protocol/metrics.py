"""Prometheus metrics through prometheus-client: one registry per app, with the process collector.

Times are exported in seconds (Prometheus base units: ``igserver_frame_render_seconds``); the render and
encode code measures milliseconds, so the ``*_ms`` histograms here take milliseconds and convert.
``/metrics`` answers the text format 0.0.4, or OpenMetrics 1.0 to a scraper whose Accept asks for it.
"""

from __future__ import annotations

from typing import Callable

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, PlatformCollector, ProcessCollector
from prometheus_client import exposition as prom_exposition
from prometheus_client.openmetrics import exposition as openmetrics

CONTENT_TYPE = prom_exposition.CONTENT_TYPE_LATEST

# seconds: from sub-ms encodes to multi-second software renders of huge frames
SECONDS_BUCKETS = (0.0005, 0.001, 0.002, 0.003, 0.005, 0.0075, 0.01, 0.015, 0.02, 0.03, 0.05, 0.075, 0.1, 0.15,
                   0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0)


class LabelledCounter:
    """``inc(amount, **labels)`` over a prometheus-client Counter (labels by keyword, as the routes call it)."""

    def __init__(self, name: str, help_text: str, registry: CollectorRegistry, labelnames=()):
        self.labelnames = tuple(labelnames)
        self._metric = Counter(name, help_text, self.labelnames, registry=registry)

    def _child(self, labels: dict):
        return self._metric.labels(**{n: str(labels.get(n, "")) for n in self.labelnames}) if self.labelnames \
            else self._metric

    def inc(self, amount: float = 1.0, **labels: str) -> None:
        self._child(labels).inc(amount)


class MillisecondHistogram:
    """``observe(ms, **labels)``: takes milliseconds, exports seconds."""

    def __init__(self, name: str, help_text: str, registry: CollectorRegistry, labelnames=()):
        self.labelnames = tuple(labelnames)
        self._metric = Histogram(name, help_text, self.labelnames, registry=registry, buckets=SECONDS_BUCKETS)

    def observe(self, value_ms: float, **labels: str) -> None:
        child = self._metric.labels(**{n: str(labels.get(n, "")) for n in self.labelnames}) if self.labelnames \
            else self._metric
        child.observe(value_ms / 1e3)


class ServiceMetrics:
    """Everything /metrics exposes. One instance (and one registry) per app."""

    def __init__(self) -> None:
        self.registry = r = CollectorRegistry()
        ProcessCollector(registry=r)  # process_cpu_seconds_total, process_resident_memory_bytes, open fds
        PlatformCollector(registry=r)
        self.frames_rendered = LabelledCounter("igserver_frames_rendered", "Frames rendered by the render process", r)
        self.frames_sent = LabelledCounter("igserver_frames_sent", "Frames sent to clients", r, ["stream"])
        self.frames_dropped = LabelledCounter(
            "igserver_frames_dropped",
            "Frames a stream client skipped (busy socket or no credit): it got a newer one instead", r, ["stream"])
        self.frame_ms = MillisecondHistogram("igserver_frame_render_seconds",
                                             "Render time of a frame in the render process", r)
        self.pass_ms = MillisecondHistogram("igserver_pass_seconds", "Per-pass GPU/CPU time of a frame", r, ["pass"])
        self.encode_ms = MillisecondHistogram("igserver_encode_seconds", "Image encoding time", r, ["format"])
        self.latency_ms = MillisecondHistogram(
            "igserver_end_to_end_latency_seconds",
            "State accepted -> first frame showing it written to the client", r, ["stream"])
        self.state_updates = LabelledCounter("igserver_state_updates", "Accepted state messages", r, ["method"])
        self.protocol_errors = LabelledCounter("igserver_protocol_errors", "Rejected requests and messages", r,
                                               ["kind"])
        self.render_errors = LabelledCounter("igserver_render_errors", "Render calls that failed after retry", r)
        # Channels (docs/channels.md): every frame renders every channel of one state in one process, so the
        # channels' counts move together (frame lock is exact); a channel that leaves the state leaves here
        self.channel_frames = Counter("igserver_channel_frames_rendered",
                                      "Frames rendered per channel (\"\": the camera of a scene without channels)",
                                      ["channel"], registry=r)
        self._channel_ids: tuple[str, ...] = ()
        Gauge("igserver_channels", "Channels of the last frame rendered", registry=r).set_function(
            lambda: len(self._channel_ids))
        # The operating point of the last frame (render/overload.py); target_fps 0 while no target is held
        self.quality = {key: Gauge(f"igserver_quality_{key}", help_text, registry=r) for key, help_text in (
            ("scale", "Internal render scale of the last frame"),
            ("error", "Estimated picture error of the last frame (8-bit sRGB RMSE)"),
            ("target_fps", "Frame rate the scene holds (quality.target_fps)"),
            ("target_met", "1 when the last frame's point is predicted to fit the target, 0 when out of reach"),
            ("predicted_ms", "The controller's predicted frame time at the last frame's point"))}
        self.observe_quality(None)

    def observe_quality(self, report: dict | None) -> None:
        """The quality gauges from a frame's operating point (None, from a render service without one: NaN)."""
        values = {} if not report else {**report, "target_met": float(report["met"])}
        for key, gauge in self.quality.items():
            gauge.set(float(values.get(key, float("nan"))))

    def observe_channels(self, ids: list[str]) -> None:
        """One frame rendered of channels ``ids``; the series of channels no longer rendered are removed."""
        ids = tuple(ids)
        if ids != self._channel_ids:
            for gone in set(self._channel_ids) - set(ids):
                self.channel_frames.remove(gone)
            self._channel_ids = ids
        for channel in ids:
            self.channel_frames.labels(channel=channel).inc()

    def gauge(self, name: str, help_text: str, read: Callable[[], float]) -> None:
        """A value read at scrape time (connected clients, render-process restarts)."""
        def safe_read() -> float:
            try:
                return float(read())
            except Exception:  # a scrape must not fail because one source is down
                return float("nan")

        Gauge(name, help_text, registry=self.registry).set_function(safe_read)

    def value(self, name: str, **labels: str) -> float | None:
        """One sample's current value (tests and tools): ``value("igserver_frames_rendered_total")``."""
        return self.registry.get_sample_value(name, labels or None)

    def exposition(self, accept: str | None = None) -> tuple[bytes, str]:
        """(body, content type): OpenMetrics when the Accept header asks for it, else text 0.0.4."""
        if accept and "application/openmetrics-text" in accept:
            return openmetrics.generate_latest(self.registry), openmetrics.CONTENT_TYPE_LATEST
        return prom_exposition.generate_latest(self.registry), CONTENT_TYPE
