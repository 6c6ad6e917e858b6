"""A rendered frame plus its encodings, made once and shared by every client that sends it, and the
headers that describe it."""

from __future__ import annotations

import asyncio
import threading
import time
from dataclasses import dataclass, field

from ..render.overload import quality_header
from .channels import frame_parts
from .imaging import encode_frame
from .metrics import ServiceMetrics


@dataclass
class EncodedFrame:
    """A rendered frame plus its encodings (made once, shared by every client that sends it)."""

    frame: object  # igserver.render.worker.Frame
    revision: int  # state revision it shows
    accepted_at: float  # perf_counter when that state was accepted
    render_call_ms: float  # wall time of RenderService.render in this process (render + IPC)
    rendered_at: float = field(default_factory=time.perf_counter)
    _encoded: dict = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def ig_frame(self) -> int:
        return self.frame.ig_frame

    @property
    def host_frame(self) -> int:
        return self.frame.host_frame

    def part(self, channel: str | None = None):
        """The Frame of one channel (None: the first; a scene without channels: the frame itself)."""
        parts = frame_parts(self.frame)
        return parts[next(iter(parts)) if channel is None else channel]

    @property
    def channel_ids(self) -> list[str]:
        return list(frame_parts(self.frame))

    def encoded(self, fmt: str, quality: int, metrics: ServiceMetrics | None = None,
                channel: str | None = None) -> tuple[bytes, float]:
        """(bytes, encode_ms) of one channel's image (None: the first), cached per (channel, format, quality).
        Blocking: call from a thread."""
        channel = self.channel_ids[0] if channel is None else channel
        key = (channel, fmt, quality if fmt == "jpeg" else 0)
        with self._lock:
            hit = self._encoded.get(key)
            if hit is None:
                t0 = time.perf_counter()
                data = encode_frame(self.part(channel).rgba, fmt, quality)
                hit = (data, (time.perf_counter() - t0) * 1e3)
                self._encoded[key] = hit
                if metrics is not None:
                    metrics.encode_ms.observe(hit[1], format=fmt)
        return hit

    async def encoded_async(self, fmt: str, quality: int, metrics: ServiceMetrics | None = None,
                            channel: str | None = None) -> tuple[bytes, float]:
        """``encoded`` off the event loop; a cached encoding is returned without a thread hop."""
        channel = self.channel_ids[0] if channel is None else channel
        hit = self._encoded.get((channel, fmt, quality if fmt == "jpeg" else 0))
        if hit is not None:
            return hit
        return await asyncio.to_thread(self.encoded, fmt, quality, metrics, channel)

    async def encoded_channels(self, fmt: str, quality: int, channels: list[str],
                               metrics: ServiceMetrics | None = None) -> dict[str, tuple[bytes, float]]:
        """{channel: (bytes, encode_ms)} of several channels, encoded side by side (the encoder releases the GIL)."""
        encodings = await asyncio.gather(*(self.encoded_async(fmt, quality, metrics, c) for c in channels))
        return dict(zip(channels, encodings))

    @property
    def sim_time(self) -> float:
        return self.frame.sim_time

    def headers(self, channel: str | None = None) -> dict[str, str]:
        """The frame's headers; X-IG-Width/Height are the channel's (None: the first), X-IG-Channel its id
        (empty: the camera of a scene without channels)."""
        part = self.part(channel)
        named = {"X-IG-Channel": self.channel_ids[0] if channel is None else channel}
        return {
            "X-IG-Host-Frame": str(self.host_frame),
            "X-IG-Frame": str(self.ig_frame),
            "X-IG-Sim-Time": f"{self.sim_time:.6f}",
            "X-IG-Render-Ms": f"{self.frame.render_ms:.3f}",
            "X-IG-Width": str(part.width),
            "X-IG-Height": str(part.height),
            "X-IG-EV100": f"{self.frame.ev100:.3f}",
            "X-IG-Illuminance-Lux": f"{self.frame.illuminance_lux:.6g}",
            **named,
            **quality_headers(self.frame),
        }



def quality_headers(frame) -> dict[str, str]:
    """``X-IG-Quality``: the frame's operating point (render/overload.py ``quality_header``)."""
    report = getattr(frame, "overload", None)
    return {"X-IG-Quality": quality_header(report)} if report else {}
