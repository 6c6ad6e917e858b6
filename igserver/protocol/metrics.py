"""Prometheus metrics in the text exposition format (0.0.4), without a client library.

The service needs counters, histograms and a few gauges read at scrape time; that is ~100 lines, and
keeps the server's dependency list to what the protocol already uses.
"""

from __future__ import annotations

import bisect
import math
import threading
from typing import Callable, Iterable

INF_LABEL = 'le="+Inf"'
CONTENT_TYPE = "text/plain; version=0.0.4; charset=utf-8"

# milliseconds: from sub-ms encodes to multi-second software renders of huge frames
MS_BUCKETS = (0.5, 1, 2, 3, 5, 7.5, 10, 15, 20, 30, 50, 75, 100, 150, 250, 500, 1000, 2500, 5000)


def _labels(names: tuple[str, ...], values: tuple[str, ...], extra: str = "") -> str:
    parts = [f'{n}="{_escape(v)}"' for n, v in zip(names, values)]
    if extra:
        parts.append(extra)
    return "{" + ",".join(parts) + "}" if parts else ""


def _escape(value: str) -> str:
    return str(value).replace("\\", "\\\\").replace("\n", "\\n").replace('"', '\\"')


def _number(value: float) -> str:
    if math.isinf(value):
        return "+Inf" if value > 0 else "-Inf"
    return repr(float(value)) if not float(value).is_integer() else str(int(value))


class _Metric:
    kind = ""

    def __init__(self, name: str, help_text: str, labelnames: Iterable[str] = ()):
        self.name = name
        self.help = help_text
        self.labelnames = tuple(labelnames)
        self._lock = threading.Lock()

    def header(self) -> list[str]:
        return [f"# HELP {self.name} {self.help}", f"# TYPE {self.name} {self.kind}"]


class Counter(_Metric):
    kind = "counter"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._values: dict[tuple[str, ...], float] = {}

    def inc(self, amount: float = 1.0, **labels: str) -> None:
        key = tuple(str(labels.get(n, "")) for n in self.labelnames)
        with self._lock:
            self._values[key] = self._values.get(key, 0.0) + amount

    def value(self, **labels: str) -> float:
        return self._values.get(tuple(str(labels.get(n, "")) for n in self.labelnames), 0.0)

    def render(self) -> list[str]:
        lines = self.header()
        with self._lock:
            items = sorted(self._values.items())
        if not items and not self.labelnames:
            items = [((), 0.0)]
        lines += [f"{self.name}{_labels(self.labelnames, k)} {_number(v)}" for k, v in items]
        return lines


class Gauge(_Metric):
    """A value read at scrape time from a callback (connected clients, render-process restarts)."""

    kind = "gauge"

    def __init__(self, name: str, help_text: str, read: Callable[[], float]):
        super().__init__(name, help_text)
        self._read = read

    def render(self) -> list[str]:
        try:
            value = float(self._read())
        except Exception:
            value = float("nan")
        return self.header() + [f"{self.name} {_number(value) if math.isfinite(value) else 'NaN'}"]


class Histogram(_Metric):
    kind = "histogram"

    def __init__(self, name: str, help_text: str, labelnames: Iterable[str] = (), buckets=MS_BUCKETS):
        super().__init__(name, help_text, labelnames)
        self.buckets = tuple(sorted(buckets))
        self._series: dict[tuple[str, ...], list] = {}  # key -> [bucket counts..., sum, count]

    def observe(self, value: float, **labels: str) -> None:
        key = tuple(str(labels.get(n, "")) for n in self.labelnames)
        index = bisect.bisect_left(self.buckets, value)
        with self._lock:
            series = self._series.setdefault(key, [0] * len(self.buckets) + [0.0, 0])
            if index < len(self.buckets):
                series[index] += 1
            series[-2] += value
            series[-1] += 1

    def count(self, **labels: str) -> int:
        series = self._series.get(tuple(str(labels.get(n, "")) for n in self.labelnames))
        return series[-1] if series else 0

    def render(self) -> list[str]:
        lines = self.header()
        with self._lock:
            items = sorted((k, list(v)) for k, v in self._series.items())
        for key, series in items:
            cumulative = 0
            for bound, n in zip(self.buckets, series):
                cumulative += n
                le = f'le="{_number(bound)}"'
                lines.append(f"{self.name}_bucket{_labels(self.labelnames, key, le)} {cumulative}")
            lines.append(f"{self.name}_bucket{_labels(self.labelnames, key, INF_LABEL)} {series[-1]}")
            lines.append(f"{self.name}_sum{_labels(self.labelnames, key)} {_number(series[-2])}")
            lines.append(f"{self.name}_count{_labels(self.labelnames, key)} {series[-1]}")
        return lines


class ServiceMetrics:
    """Everything /metrics exposes. One instance per app."""

    def __init__(self) -> None:
        self.frames_rendered = Counter("igserver_frames_rendered_total", "Frames rendered by the render process")
        self.frames_sent = Counter("igserver_frames_sent_total", "Frames sent to clients", ["stream"])
        self.frames_dropped = Counter(
            "igserver_frames_dropped_total",
            "Frames a stream client skipped (busy socket or no credit): it got a newer one instead",
            ["stream"],
        )
        self.frame_ms = Histogram("igserver_frame_render_ms", "Render time of a frame in the render process (ms)")
        self.pass_ms = Histogram("igserver_pass_ms", "Per-pass GPU/CPU time of a frame (ms)", ["pass"])
        self.encode_ms = Histogram("igserver_encode_ms", "Image encoding time (ms)", ["format"])
        self.latency_ms = Histogram(
            "igserver_end_to_end_latency_ms",
            "State accepted -> first frame showing it written to the client (ms)",
            ["stream"],
        )
        self.state_updates = Counter("igserver_state_updates_total", "Accepted state messages", ["method"])
        self.protocol_errors = Counter("igserver_protocol_errors_total", "Rejected requests and messages", ["kind"])
        self.render_errors = Counter("igserver_render_errors_total", "Render calls that failed after retry")
        self._gauges: list[Gauge] = []
        self._all = [
            self.frames_rendered, self.frames_sent, self.frames_dropped, self.frame_ms, self.pass_ms,
            self.encode_ms, self.latency_ms, self.state_updates, self.protocol_errors, self.render_errors,
        ]

    def gauge(self, name: str, help_text: str, read: Callable[[], float]) -> None:
        self._gauges.append(Gauge(name, help_text, read))

    def exposition(self) -> str:
        lines: list[str] = []
        for metric in self._all + self._gauges:
            lines += metric.render()
        return "\n".join(lines) + "\n"
