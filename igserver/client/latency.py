"""Latency of the protocol as a host sees it: state sent -> frame of that state received (``igclient bench``,
``igserver bench --service``)."""

from __future__ import annotations

import statistics
import threading
import time

from .http import IGClient


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
    Returns e2e, render (render process) and encode (server) times in ms, per frame.
    """
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


def summarize(result: dict) -> dict:
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
    return (
        f"{s['mode']:>4}: {s['frames']} frames  e2e p50 {s['e2e_p50']:.2f} ms  p99 {s['e2e_p99']:.2f} ms | "
        f"render p50 {s['render_p50']:.2f} p99 {s['render_p99']:.2f} ms | encode p50 {s['encode_p50']:.2f} ms | "
        f"service overhead p50 {s['overhead_p50']:.2f} ms  p99 {s['overhead_p99']:.2f} ms"
        + (f" | {s['fps']:.1f} frames/s" if "fps" in s else "")
    )
