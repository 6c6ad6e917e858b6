"""Latency of the protocol as a host sees it: state sent -> frame of that state received (``igclient bench``,
``igserver bench --service``)."""

from __future__ import annotations

import math
import re
import statistics
import threading
import time
from collections import Counter

from .http import MJPEG_HEADERS, IGClient

_PART_QUALITY = re.compile(rb"X-IG-Quality: ([^\r]*)\r\n")


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    index = min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))
    return ordered[index]


def latency_bench(url: str, frames: int = 200, warmup: int = 10, mode: str = "ws", token: str | None = None,
                  rate_hz: float = 60.0) -> dict:
    """State sent -> frame of that state received: one at a time (a host stepping frame by frame), or a
    stream of states (ws-stream).

    ws: a patch over the WebSocket, wait for the frame carrying its host_frame.
    http: POST /v1/render (one request per frame).
    ws-stream: a host that sends a patch every 1/``rate_hz`` s without waiting for frames (faster than
    the IG draws: the stream is saturated, frames are in flight); per frame received, the time from the
    sending of the state it shows.
    mjpeg: GET /v1/stream.mjpg as a viewer reads it; per part, its arrival and its ``X-IG-Quality``
    header (the operating point the overload controller chose). No state is sent: only the rate counts.
    mjpeg-fire: the same stream, a fire started halfway through (``mjpeg_fire``).
    Returns e2e, render (render process) and encode (server) times in ms, per frame.
    """
    if mode == "mjpeg":
        return mjpeg_rate(url, frames, warmup, token)
    if mode == "mjpeg-fire":
        return mjpeg_fire(url, frames, warmup, token)
    e2e, render, encode = [], [], []
    with IGClient(url, token=token) as ig:
        base = ig.get_state().host_frame + 1
        if mode == "ws-stream":
            sent: dict[int, float] = {}  # host_frame -> perf_counter s when its state was sent
            arrivals: list[float] = []  # perf_counter s of each frame received after the warm-up
            stop = threading.Event()
            with ig.stream(credits=4) as stream:

                def host() -> None:
                    i, t0 = 0, time.perf_counter()
                    while not stop.is_set():
                        sent[base + i] = time.perf_counter()
                        stream.send_patch({"host_frame": base + i, "camera": {"heading": (i * 7) % 360}})
                        i += 1
                        time.sleep(max(0.0, t0 + i / rate_hz - time.perf_counter()))

                sender = threading.Thread(target=host, daemon=True)
                sender.start()
                try:
                    received = 0
                    while received < frames + warmup:
                        frame = stream.recv()
                        if frame.host_frame not in sent:
                            continue
                        received += 1
                        if received > warmup:
                            arrivals.append(frame.received_at)
                            e2e.append((frame.received_at - sent[frame.host_frame]) * 1e3)
                            render.append(frame.render_ms)
                            encode.append(frame.encode_ms)
                finally:
                    stop.set()
                    sender.join(5)
        elif mode == "ws":
            with ig.stream(credits=4) as stream:
                for i in range(frames + warmup):
                    host_frame = base + i
                    t0 = time.perf_counter()
                    stream.send_patch({"host_frame": host_frame, "camera": {"heading": (i * 7) % 360}})
                    while True:
                        frame = stream.recv()
                        if frame.host_frame >= host_frame:
                            break
                    if i >= warmup:
                        e2e.append((frame.received_at - t0) * 1e3)
                        render.append(frame.render_ms)
                        encode.append(frame.encode_ms)
        else:
            for i in range(frames + warmup):
                t0 = time.perf_counter()
                frame = ig.render({"host_frame": base + i, "camera": {"heading": (i * 7) % 360}})
                if i >= warmup:
                    e2e.append((frame.received_at - t0) * 1e3)
                    render.append(frame.render_ms)
                    encode.append(frame.encode_ms)
    result = {"mode": mode, "e2e_ms": e2e, "render_ms": render, "encode_ms": encode}
    if mode == "ws-stream" and len(arrivals) > 1:  # the stream's rate, saturated
        result["fps"] = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0])
    return result


def mjpeg_parts(ig: IGClient, frames: int):
    """(arrival perf_counter s, X-IG-Quality header) of each part of ``frames`` parts of the MJPEG stream,
    as a viewer reads it."""
    with ig.http.stream("GET", "/v1/stream.mjpg", params={"frames": frames}, headers=MJPEG_HEADERS) as response:
        response.raise_for_status()
        pending = b""
        for chunk in response.iter_bytes():
            pending += chunk
            while (match := _PART_QUALITY.search(pending)) is not None:
                yield time.perf_counter(), match.group(1).decode()
                pending = pending[match.end():]


def mjpeg_rate(url: str, frames: int, warmup: int, token: str | None = None) -> dict:
    """The MJPEG stream's frame intervals as a viewer sees them, and the operating points it showed."""
    with IGClient(url, token=token) as ig:
        parts = list(mjpeg_parts(ig, frames + warmup))[warmup:]
    arrivals, points = [t for t, _ in parts], [q for _, q in parts]
    intervals = [(b - a) * 1e3 for a, b in zip(arrivals, arrivals[1:])]
    result = {"mode": "mjpeg", "e2e_ms": [], "render_ms": [], "encode_ms": [], "interval_ms": intervals,
              "operating_points": Counter(points).most_common(3)}
    if len(arrivals) > 1:
        result["fps"] = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0])
    return result


FIRE_AHEAD_M = 60.0  # mjpeg-fire: where the fire starts, ahead of the camera (m), at its feet
FIRE_WINDOW_S = 3.0  # and how long after it the intervals are summed up


def fire_ahead(state) -> dict:
    """A smoking pool fire, lit at once, FIRE_AHEAD_M ahead of ``state``'s camera and 1.5 m below its eye
    (heading clockwise from north, pitch up: ENU)."""
    cam = state.camera
    h, p = math.radians(cam.heading), math.radians(cam.pitch)
    forward = (math.sin(h) * math.cos(p), math.cos(h) * math.cos(p), math.sin(p))
    x, y, z = (c + FIRE_AHEAD_M * f for c, f in zip(cam.position, forward))
    return {"id": "bench-fire", "type": "fire", "position": [x, y, z - 1.5], "diameter": 3.0,
            "emits_smoke": True, "fade": 0.0}


def mjpeg_fire(url: str, frames: int, warmup: int, token: str | None = None) -> dict:
    """The MJPEG stream's intervals when a host starts a fire halfway through (``fire_ahead``): the
    programs a new effect needs are compiled when it is first drawn unless the server compiled them
    ahead (render/rehearsal.py), and a frozen stream shows here as a long interval."""
    arrivals: list[float] = []
    start = float("inf")
    with IGClient(url, token=token) as ig:
        fire = fire_ahead(ig.get_state())
        for arrival, _ in mjpeg_parts(ig, frames + warmup):
            arrivals.append(arrival)
            if len(arrivals) == warmup + frames // 2:
                start = time.perf_counter()
                ig.add_effect(fire)
    before = [t for t in arrivals[warmup:] if t < start]
    after = [t for t in arrivals if start <= t < start + FIRE_WINDOW_S]
    intervals = [(b - a) * 1e3 for a, b in zip(before[-1:] + after, after)]
    return {"mode": "mjpeg-fire", "e2e_ms": [], "render_ms": [], "encode_ms": [],
            "interval_ms": [(b - a) * 1e3 for a, b in zip(before, before[1:])], "after_ms": intervals,
            "fps_before": (len(before) - 1) / (before[-1] - before[0]) if len(before) > 1 else float("nan"),
            "fps_after": len(after) / FIRE_WINDOW_S}


def summarize(result: dict) -> dict:
    if result["mode"] == "mjpeg-fire":
        return {"mode": "mjpeg-fire", "frames": len(result["interval_ms"]) + len(result["after_ms"]) + 1,
                "fps_before": result["fps_before"], "interval_p95_before": percentile(result["interval_ms"], 95),
                "fps_after": result["fps_after"], "longest_after": max(result["after_ms"], default=float("nan"))}
    if result["mode"] == "mjpeg":
        intervals = result["interval_ms"]
        return {"mode": "mjpeg", "frames": len(intervals) + 1, "interval_p50": percentile(intervals, 50),
                "interval_p95": percentile(intervals, 95), "fps": result.get("fps", float("nan")),
                "operating_points": result["operating_points"]}
    e2e, render, encode = result["e2e_ms"], result["render_ms"], result["encode_ms"]
    overhead = [a - b - c for a, b, c in zip(e2e, render, encode)]
    return {
        "mode": result["mode"],
        "frames": len(e2e),
        "e2e_p50": percentile(e2e, 50),
        "e2e_p99": percentile(e2e, 99),
        "render_p50": percentile(render, 50),
        "render_p99": percentile(render, 99),
        "encode_p50": percentile(encode, 50),
        "overhead_p50": percentile(overhead, 50),
        "overhead_p99": percentile(overhead, 99),
        "overhead_mean": statistics.fmean(overhead) if overhead else float("nan"),
        **({"fps": result["fps"]} if "fps" in result else {}),
    }


def format_summary(s: dict) -> str:
    if s["mode"] == "mjpeg-fire":
        return (f"mjpeg-fire: before the fire {s['fps_before']:.1f} frames/s, interval p95 "
                f"{s['interval_p95_before']:.1f} ms | the {FIRE_WINDOW_S:g} s after it {s['fps_after']:.1f} frames/s, "
                f"longest interval {s['longest_after']:.1f} ms")
    if s["mode"] == "mjpeg":
        shown = "; ".join(f"{n}x {point}" for point, n in s["operating_points"])
        return (f"mjpeg: {s['frames']} frames  {s['fps']:.1f} frames/s  interval p50 {s['interval_p50']:.1f} ms  "
                f"p95 {s['interval_p95']:.1f} ms | most shown: {shown}")
    return (
        f"{s['mode']:>4}: {s['frames']} frames  e2e p50 {s['e2e_p50']:.2f} ms  p99 {s['e2e_p99']:.2f} ms | "
        f"render p50 {s['render_p50']:.2f} p99 {s['render_p99']:.2f} ms | encode p50 {s['encode_p50']:.2f} ms | "
        f"service overhead p50 {s['overhead_p50']:.2f} ms  p99 {s['overhead_p99']:.2f} ms"
        + (f" | {s['fps']:.1f} frames/s" if "fps" in s else "")
    )
