"""Python host client for igserver protocol v1 (sync and asyncio), and the ``igclient`` CLI.

    from igserver.client import IGClient
    with IGClient("http://127.0.0.1:8600", token=None) as ig:   # token: the server's IGSERVER_TOKEN, if it has one
        ig.patch_state({"host_frame": 1, "camera": {"heading": 90}})
        frame = ig.get_frame()                 # Frame: .data (JPEG), .host_frame, .frame, .render_ms
        with ig.stream(credits=2) as stream:   # WebSocket, msgpack both ways
            stream.send_patch({"host_frame": 2, "camera": {"pitch": 5}})
            frame = stream.recv()              # acks automatically: the server sends the next one

``AsyncIGClient`` / ``AsyncFrameStream`` are the same for asyncio. States are ``igserver.scene.Scene``
(or plain dicts); every message is validated by the server, and a rejection raises ``IGError`` carrying
the RFC 9457 problem (``.problem["errors"]`` lists the offending fields' JSON Pointers).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, AsyncIterator, Iterator

import httpx
import msgpack

from igserver.scene import Scene, load_scene, patch_from_assignments

MSGPACK = "application/vnd.msgpack"
DEFAULT_URL = "http://127.0.0.1:8600"


class IGError(Exception):
    """The server rejected a request or message: ``status`` and the problem document."""

    def __init__(self, status: int, problem: dict):
        self.status = status
        self.problem = problem
        fields = "; ".join(f"{e.get('pointer')}: {e.get('detail')}" for e in problem.get("errors", []))
        super().__init__(f"{status} {problem.get('title', '')}: {problem.get('detail', '')}" + (f" [{fields}]" if fields else ""))


@dataclass
class Frame:
    frame: int  # IG frame number
    host_frame: int  # host_frame of the state it shows
    width: int
    height: int
    format: str  # jpeg | png | raw
    data: bytes
    render_ms: float
    encode_ms: float = 0.0
    received_at: float = field(default_factory=time.perf_counter)

    def rgba(self):
        """Decoded pixels, (height, width, 4) uint8 numpy array, top row first."""
        import numpy as np

        if self.format == "raw":
            return np.frombuffer(self.data, np.uint8).reshape(self.height, self.width, 4)
        import io

        from PIL import Image

        return np.asarray(Image.open(io.BytesIO(self.data)).convert("RGBA"))

    @classmethod
    def from_message(cls, message: dict) -> "Frame":
        return cls(message["frame"], message["host_frame"], message["width"], message["height"],
                   message["format"], message["data"], message["render_ms"], message.get("encode_ms", 0.0))

    @classmethod
    def from_response(cls, response: httpx.Response, fmt: str) -> "Frame":
        h = response.headers
        return cls(int(h["x-ig-frame"]), int(h["x-ig-host-frame"]), int(h["x-ig-width"]), int(h["x-ig-height"]),
                   fmt, response.content, float(h["x-ig-render-ms"]), float(h.get("x-ig-encode-ms", 0)))


def _tree(state: Scene | dict) -> dict:
    return state.model_dump(mode="json") if isinstance(state, Scene) else state


def _pack(value: Any) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def _unpack(data: bytes) -> Any:
    return msgpack.unpackb(data, raw=False)


def _check(response: httpx.Response) -> httpx.Response:
    if response.status_code >= 400:
        ctype = response.headers.get("content-type", "")
        if "msgpack" in ctype:
            problem = _unpack(response.content)
        elif "json" in ctype:
            problem = response.json()
        else:
            problem = {"title": response.reason_phrase, "detail": response.text[:200]}
        raise IGError(response.status_code, problem)
    return response


def _decode(response: httpx.Response) -> Any:
    if not response.content:
        return None
    if "msgpack" in response.headers.get("content-type", ""):
        return _unpack(response.content)
    return response.json()


class _Requests:
    """What the sync and async clients share: how each call is spelled on the wire."""

    def __init__(self, url: str, token: str | None = None):
        self.url = url.rstrip("/")
        self.headers = {"Accept": MSGPACK}
        if token:
            self.headers["Authorization"] = f"Bearer {token}"

    def body(self, value: Any) -> dict:
        return {"content": _pack(value), "headers": {"Content-Type": MSGPACK, "Accept": MSGPACK}}

    @staticmethod
    def minimal(minimal: bool) -> dict:
        return {"Prefer": "return=minimal"} if minimal else {}

    def ws_url(self) -> str:
        return "ws" + self.url[len("http"):] + "/v1/ws"

    def auth_headers(self) -> dict:
        return {k: v for k, v in self.headers.items() if k == "Authorization"}


class IGClient(_Requests):
    """Blocking client (httpx, one keep-alive connection). ``token``: the server's bearer token, if it has one."""

    def __init__(self, url: str = DEFAULT_URL, timeout: float = 30.0, token: str | None = None):
        super().__init__(url, token)
        self.http = httpx.Client(base_url=self.url, timeout=timeout, headers=self.headers)

    def __enter__(self) -> "IGClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.http.close()

    def _send(self, method: str, path: str, value: Any = None, headers: dict | None = None, **kw) -> httpx.Response:
        if value is not None:
            request = self.body(value)
            request["headers"].update(headers or {})
            return _check(self.http.request(method, path, **request, **kw))
        return _check(self.http.request(method, path, headers=headers, **kw))

    # -- health
    def health(self) -> dict:
        return _decode(self._send("GET", "/v1/health"))

    def ready(self) -> dict:
        response = self.http.get("/v1/ready")
        return response.json()

    def wait_ready(self, timeout: float = 120.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            try:
                info = self.ready()
                if info.get("ready"):
                    return info
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                raise TimeoutError(f"igserver at {self.url} not ready after {timeout} s")
            time.sleep(0.1)

    # -- state
    def get_state(self) -> Scene:
        return Scene.model_validate(_decode(self._send("GET", "/v1/state")))

    def put_state(self, state: Scene | dict, minimal: bool = False) -> Scene | dict:
        reply = _decode(self._send("PUT", "/v1/state", _tree(state), self.minimal(minimal)))
        return reply if minimal else Scene.model_validate(reply)

    def patch_state(self, patch: dict, minimal: bool = False) -> Scene | dict:
        reply = _decode(self._send("PATCH", "/v1/state", patch, self.minimal(minimal)))
        return reply if minimal else Scene.model_validate(reply)

    # -- frames
    def get_frame(self, format: str = "jpeg", quality: int = 85) -> Frame:
        response = self._send("GET", "/v1/frame", params={"format": format, "quality": quality},
                              headers={"Accept": "*/*"})
        return Frame.from_response(response, format)

    def render(self, state: Scene | dict, replace: bool = False, format: str = "jpeg", quality: int = 85) -> Frame:
        """The frame of exactly this state (a patch, or a whole state with replace=True)."""
        response = self._send("POST", "/v1/render", _tree(state),
                              params={"replace": replace, "format": format, "quality": quality})
        return Frame.from_message(_unpack(response.content))

    def mjpeg(self, frames: int = 0, fps: float = 0) -> Iterator[bytes]:
        """JPEG images of the MJPEG stream, parsed from the multipart body."""
        params = {"frames": frames, "fps": fps}
        with self.http.stream("GET", "/v1/stream.mjpg", params=params, headers={"Accept": "*/*"}) as response:
            _check(response)
            yield from iter_multipart_jpegs(response.iter_bytes())

    # -- effects
    def effects(self) -> list[dict]:
        return _decode(self._send("GET", "/v1/effects"))

    def add_effect(self, effect: dict) -> dict:
        return _decode(self._send("POST", "/v1/effects", effect))

    def patch_effect(self, effect_id: str, patch: dict) -> dict:
        return _decode(self._send("PATCH", f"/v1/effects/{effect_id}", patch))

    def delete_effect(self, effect_id: str, immediate: bool = False) -> dict | None:
        return _decode(self._send("DELETE", f"/v1/effects/{effect_id}", params={"immediate": immediate}))

    def water_height(self, points, sim_time: float | None = None) -> dict:
        """Sea surface at ENU points [(x, y), ...]: {"sim_time", "height", "normal", "velocity"} (the
        renderer's own wave maths and bathymetry; sim_time None = the current state's)."""
        body = {"points": [list(map(float, p)) for p in points]}
        if sim_time is not None:
            body["sim_time"] = float(sim_time)
        return _decode(self._send("POST", "/v1/query/water-height", body))

    def metrics(self) -> str:
        return self.http.get("/metrics").text

    # -- stream
    def stream(self, credits: int = 2, format: str = "jpeg", quality: int = 85, auto_ack: bool = True) -> "FrameStream":
        return FrameStream(self.ws_url(), credits, format, quality, auto_ack, self.auth_headers())


class AsyncIGClient(_Requests):
    """asyncio client (httpx.AsyncClient). Same methods as IGClient, awaited (``mjpeg`` is an async iterator)."""

    def __init__(self, url: str = DEFAULT_URL, timeout: float = 30.0, token: str | None = None):
        super().__init__(url, token)
        self.http = httpx.AsyncClient(base_url=self.url, timeout=timeout, headers=self.headers)

    async def __aenter__(self) -> "AsyncIGClient":
        return self

    async def __aexit__(self, *exc) -> None:
        await self.http.aclose()

    async def _send(self, method: str, path: str, value: Any = None, headers: dict | None = None, **kw):
        if value is not None:
            request = self.body(value)
            request["headers"].update(headers or {})
            return _check(await self.http.request(method, path, **request, **kw))
        return _check(await self.http.request(method, path, headers=headers, **kw))

    async def close(self) -> None:
        await self.http.aclose()

    async def health(self) -> dict:
        return _decode(await self._send("GET", "/v1/health"))

    async def ready(self) -> dict:
        return (await self.http.get("/v1/ready")).json()

    async def wait_ready(self, timeout: float = 120.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            try:
                info = await self.ready()
                if info.get("ready"):
                    return info
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                raise TimeoutError(f"igserver at {self.url} not ready after {timeout} s")
            await asyncio.sleep(0.1)

    async def metrics(self) -> str:
        return (await self.http.get("/metrics")).text

    async def mjpeg(self, frames: int = 0, fps: float = 0) -> AsyncIterator[bytes]:
        """JPEG images of the MJPEG stream: ``async for jpeg in ig.mjpeg(frames=10)``."""
        params = {"frames": frames, "fps": fps}
        async with self.http.stream("GET", "/v1/stream.mjpg", params=params, headers={"Accept": "*/*"}) as response:
            _check(response)
            parser = MultipartJpegParser()
            async for chunk in response.aiter_bytes():
                for jpeg in parser.feed(chunk):
                    yield jpeg

    async def get_state(self) -> Scene:
        return Scene.model_validate(_decode(await self._send("GET", "/v1/state")))

    async def put_state(self, state: Scene | dict, minimal: bool = False):
        reply = _decode(await self._send("PUT", "/v1/state", _tree(state), self.minimal(minimal)))
        return reply if minimal else Scene.model_validate(reply)

    async def patch_state(self, patch: dict, minimal: bool = False):
        reply = _decode(await self._send("PATCH", "/v1/state", patch, self.minimal(minimal)))
        return reply if minimal else Scene.model_validate(reply)

    async def get_frame(self, format: str = "jpeg", quality: int = 85) -> Frame:
        response = await self._send("GET", "/v1/frame", params={"format": format, "quality": quality},
                                    headers={"Accept": "*/*"})
        return Frame.from_response(response, format)

    async def render(self, state: Scene | dict, replace: bool = False, format: str = "jpeg", quality: int = 85) -> Frame:
        response = await self._send("POST", "/v1/render", _tree(state),
                                    params={"replace": replace, "format": format, "quality": quality})
        return Frame.from_message(_unpack(response.content))

    async def water_height(self, points, sim_time: float | None = None) -> dict:
        body = {"points": [list(map(float, p)) for p in points]}
        if sim_time is not None:
            body["sim_time"] = float(sim_time)
        return _decode(await self._send("POST", "/v1/query/water-height", body))

    async def effects(self) -> list[dict]:
        return _decode(await self._send("GET", "/v1/effects"))

    async def add_effect(self, effect: dict) -> dict:
        return _decode(await self._send("POST", "/v1/effects", effect))

    async def patch_effect(self, effect_id: str, patch: dict) -> dict:
        return _decode(await self._send("PATCH", f"/v1/effects/{effect_id}", patch))

    async def delete_effect(self, effect_id: str, immediate: bool = False):
        return _decode(await self._send("DELETE", f"/v1/effects/{effect_id}", params={"immediate": immediate}))

    def stream(self, credits: int = 2, format: str = "jpeg", quality: int = 85, auto_ack: bool = True):
        return AsyncFrameStream(self.ws_url(), credits, format, quality, auto_ack, self.auth_headers())


class MultipartJpegParser:
    """Incremental parser of a multipart/x-mixed-replace body: ``feed(chunk)`` -> the JPEGs completed by it."""

    def __init__(self) -> None:
        self.buffer = b""

    def feed(self, chunk: bytes) -> list[bytes]:
        self.buffer += chunk
        out = []
        while True:
            head_end = self.buffer.find(b"\r\n\r\n")
            if head_end < 0:
                break
            headers = self.buffer[:head_end].decode("latin-1").lower()
            length = next((int(line.split(":", 1)[1]) for line in headers.split("\r\n")
                           if line.startswith("content-length:")), None)
            if length is None:
                raise ValueError("multipart part without Content-Length")
            end = head_end + 4 + length
            if len(self.buffer) < end:
                break
            out.append(self.buffer[head_end + 4:end])
            self.buffer = self.buffer[end:].lstrip(b"\r\n")
        return out


def iter_multipart_jpegs(chunks: Iterator[bytes]) -> Iterator[bytes]:
    """JPEG payloads of a multipart/x-mixed-replace body (uses each part's Content-Length)."""
    parser = MultipartJpegParser()
    for chunk in chunks:
        yield from parser.feed(chunk)


# --------------------------------------------------------------------------- WebSocket streams

class _StreamProtocol:
    def __init__(self, url: str, credits: int, format: str, quality: int, auto_ack: bool,
                 headers: dict | None = None):
        self.url, self.credits, self.format, self.quality, self.auto_ack = url, credits, format, quality, auto_ack
        self.headers = headers or {}
        self._next_id = 0
        self._early_frames: list[Frame] = []  # frames that arrived while waiting for a query result

    def query_message(self, points, sim_time: float | None) -> tuple[int, bytes]:
        self._next_id += 1
        body = {"type": "query", "query": "water-height", "points": [list(map(float, p)) for p in points],
                "id": self._next_id}
        if sim_time is not None:
            body["sim_time"] = float(sim_time)
        return self._next_id, _pack(body)

    def hello(self) -> bytes:
        return _pack({"type": "hello", "credits": self.credits, "format": self.format, "quality": self.quality})

    def state_message(self, kind: str, state: Scene | dict) -> bytes:
        self._next_id += 1
        return _pack({"type": kind, "state": _tree(state), "id": self._next_id})

    @staticmethod
    def parse(data: bytes) -> Frame:
        message = _unpack(data)
        if message.get("type") == "error":
            problem = message.get("problem", {})
            raise IGError(problem.get("status", 400), problem)
        return Frame.from_message(message)


class FrameStream(_StreamProtocol):
    """Blocking WebSocket stream (websockets.sync). Use as a context manager."""

    def __enter__(self) -> "FrameStream":
        from websockets.sync.client import connect

        # images do not deflate: no per-message compression
        self._connection = connect(self.url, compression=None, max_size=64 << 20, additional_headers=self.headers)
        self.ws = self._connection.__enter__()
        self.ws.send(self.hello())
        return self

    def __exit__(self, *exc) -> None:
        self._connection.__exit__(*exc)

    def send_patch(self, patch: dict) -> None:
        self.ws.send(self.state_message("patch", patch))

    def send_state(self, state: Scene | dict) -> None:
        self.ws.send(self.state_message("replace", state))

    def ack(self, frame: Frame | int) -> None:
        self.ws.send(_pack({"type": "ack", "frame": frame.frame if isinstance(frame, Frame) else frame}))

    def recv(self, timeout: float | None = 30.0) -> Frame:
        """The next frame (raises IGError when the server rejected one of our messages)."""
        if self._early_frames:
            return self._early_frames.pop(0)
        frame = self.parse(self.ws.recv(timeout))
        if self.auto_ack:
            self.ack(frame)
        return frame

    def water_height(self, points, sim_time: float | None = None, timeout: float | None = 30.0) -> dict:
        """Sea height / normal / velocity at ENU points [(x, y), ...] over the stream (see IGClient)."""
        qid, message = self.query_message(points, sim_time)
        self.ws.send(message)
        while True:
            reply = _unpack(self.ws.recv(timeout))
            if reply.get("type") == "query_result" and reply.get("id") == qid:
                return reply
            frame = self.parse(_pack(reply))  # an error raises; a frame waits for recv()
            if self.auto_ack:
                self.ack(frame)
            self._early_frames.append(frame)


class AsyncFrameStream(_StreamProtocol):
    async def __aenter__(self) -> "AsyncFrameStream":
        from websockets.asyncio.client import connect

        self.ws = await connect(self.url, compression=None, max_size=64 << 20, additional_headers=self.headers)
        await self.ws.send(self.hello())
        return self

    async def __aexit__(self, *exc) -> None:
        await self.ws.close()

    async def send_patch(self, patch: dict) -> None:
        await self.ws.send(self.state_message("patch", patch))

    async def send_state(self, state: Scene | dict) -> None:
        await self.ws.send(self.state_message("replace", state))

    async def ack(self, frame: Frame | int) -> None:
        await self.ws.send(_pack({"type": "ack", "frame": frame.frame if isinstance(frame, Frame) else frame}))

    async def recv(self, timeout: float | None = 30.0) -> Frame:
        frame = self.parse(await asyncio.wait_for(self.ws.recv(), timeout))
        if self.auto_ack:
            await self.ack(frame)
        return frame


# --------------------------------------------------------------------------- latency benchmark

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


# --------------------------------------------------------------------------- CLI

def _client(args) -> IGClient:
    return IGClient(args.url, token=args.token)


def _cmd_send(args) -> int:
    scene = load_scene(args.scene)
    with _client(args) as ig:
        ig.put_state(scene, minimal=True)
    print(f"sent {args.scene}")
    return 0


def _cmd_set(args) -> int:
    with _client(args) as ig:
        # a list item (effects.0.active=false) is set by sending the whole list with that item changed
        needs_base = any(k.isdigit() for a in args.assignments for k in a.split("=", 1)[0].split("."))
        base = ig.get_state().model_dump(mode="json") if needs_base else None
        reply = ig.patch_state(patch_from_assignments(args.assignments, base=base), minimal=True)
    print(json.dumps(reply))
    return 0


def _cmd_state(args) -> int:
    with _client(args) as ig:
        print(ig.get_state().model_dump_json(indent=2))
    return 0


FRAME_SUFFIXES = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg", ".raw": "raw", ".rgba": "raw"}


def _cmd_frame(args) -> int:
    suffix = Path(args.output).suffix.lower()
    if suffix not in FRAME_SUFFIXES:
        raise ValueError(f"{args.output}: unknown image type {suffix or '(none)'!r}; use .jpg, .png or .raw "
                         "(.raw: RGBA bytes, top row first)")
    fmt = FRAME_SUFFIXES[suffix]
    with _client(args) as ig:
        frame = ig.get_frame(fmt)
    Path(args.output).write_bytes(frame.data)
    layout = " RGBA8, top row first" if fmt == "raw" else ""
    print(f"{args.output}: frame {frame.frame}, host_frame {frame.host_frame}, {frame.width}x{frame.height}{layout}, "
          f"render {frame.render_ms:.1f} ms")
    return 0


def read_scenario(path: str) -> list[dict]:
    """JSON lines, one patch per line; blank lines and lines starting with # or // are comments."""
    patches = []
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        text = line.strip()
        if not text or text.startswith(("#", "//")):
            continue
        try:
            patch = json.loads(text)
        except ValueError as exc:
            raise ValueError(f"{path}:{number}: not a JSON patch ({exc.msg}): {text[:60]}") from None
        if not isinstance(patch, dict):
            raise ValueError(f"{path}:{number}: a patch is a JSON object, got {type(patch).__name__}")
        patches.append(patch)
    return patches


def _cmd_play(args) -> int:
    """Scenario file: JSON lines, one patch per line, sent at --rate; host_frame counts up unless given."""
    patches = read_scenario(args.scenario)
    period = 1.0 / args.rate
    with _client(args) as ig:
        host_frame = ig.get_state().host_frame
        start = time.perf_counter()
        for index, patch in enumerate(patches * args.loops):
            patch = dict(patch)
            host_frame = patch.get("host_frame", host_frame + 1)
            patch["host_frame"] = host_frame
            ig.patch_state(patch, minimal=True)
            time.sleep(max(0.0, start + (index + 1) * period - time.perf_counter()))
    print(f"played {len(patches) * args.loops} patches at {args.rate} Hz")
    return 0


def _cmd_record(args) -> int:
    count = 0
    target = args.mjpeg or args.png_dir
    try:
        with _client(args) as ig:
            if args.mjpeg:
                with open(args.mjpeg, "wb") as out:
                    for jpeg in ig.mjpeg(frames=args.frames, fps=args.fps):
                        # an .mjpg file of concatenated JPEGs: ffmpeg/ffplay read it with -f mjpeg
                        out.write(jpeg)
                        count += 1
            else:
                folder = Path(args.png_dir)
                folder.mkdir(parents=True, exist_ok=True)
                with ig.stream(credits=2, format="png") as stream:
                    for n in range(args.frames or 100):
                        frame = stream.recv()
                        (folder / f"frame_{n:05d}_{frame.host_frame}.png").write_bytes(frame.data)
                        count += 1
    except KeyboardInterrupt:  # Ctrl-C is how an open-ended recording ends: keep what was written
        print(f"{target}: stopped after {count} frames", file=sys.stderr)
        return 0
    print(f"{target}: {count} frames")
    return 0


def _cmd_effects(args) -> int:
    with _client(args) as ig:
        action = args.action
        if action == "list":
            effects = ig.effects()
            if not effects:
                print("no effects")
            for e in effects:
                print(f"{e['id']:<20} {e['type']:<8} {'active' if e.get('active') else 'inactive':<8} "
                      f"intensity {e.get('intensity', 1.0):g}")
            return 0
        if not args.id:
            raise ValueError(f"effects {action}: give the effect id")
        if action == "add":
            effect = {**patch_from_assignments(args.fields), "id": args.id}  # type=fire|smoke|gas_burner
            result = ig.add_effect(effect)
        elif action == "start":
            result = ig.patch_effect(args.id, {"active": True})
        elif action == "stop":
            result = ig.delete_effect(args.id)  # fades out
        elif action == "remove":
            result = ig.delete_effect(args.id, immediate=True)
        else:  # set
            result = ig.patch_effect(args.id, patch_from_assignments(args.fields))
    print(json.dumps(result) if result is not None else f"removed {args.id}")
    return 0


def _cmd_bench(args) -> int:
    with _client(args) as ig:
        ig.wait_ready()
        saved = ig.get_state()  # the benchmark moves the camera and host_frame: put the operator's state back
        try:
            if args.width or args.height:
                size = {k: v for k, v in (("width", args.width), ("height", args.height)) if v}
                ig.patch_state({"camera": size}, minimal=True)
            for mode in args.modes.split(","):
                print(format_summary(summarize(latency_bench(args.url, args.frames, mode=mode, token=args.token))))
        finally:
            ig.put_state(saved, minimal=True)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="igclient", description="igserver host client")
    parser.add_argument("--url", default=os.environ.get("IGSERVER_URL", DEFAULT_URL),
                        help=f"server URL (default $IGSERVER_URL or {DEFAULT_URL})")
    parser.add_argument("--token", default=os.environ.get("IGSERVER_TOKEN"),
                        help="bearer token (default $IGSERVER_TOKEN)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("send", help="replace the state with a scene file")
    p.add_argument("scene")
    p.set_defaults(run=_cmd_send)

    p = sub.add_parser("set", help="patch fields: igclient set camera.pitch=5 weather.wind_speed=12 effects.0.active=false")
    p.add_argument("assignments", nargs="+", metavar="PATH=VALUE")
    p.set_defaults(run=_cmd_set)

    p = sub.add_parser("state", help="print the current state")
    p.set_defaults(run=_cmd_state)

    p = sub.add_parser("frame", help="save a frame of the current state (.jpg, .png or .raw RGBA)")
    p.add_argument("output")
    p.set_defaults(run=_cmd_frame)

    p = sub.add_parser("play", help="play a scenario (JSON lines of patches; # comments) at a rate")
    p.add_argument("scenario")
    p.add_argument("--rate", type=float, default=30.0, help="patches per second")
    p.add_argument("--loops", type=int, default=1)
    p.set_defaults(run=_cmd_play)

    p = sub.add_parser("record", help="record the stream to an MJPEG file or a PNG sequence (Ctrl-C stops)")
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--mjpeg", help="output .mjpg file")
    target.add_argument("--png-dir", help="output folder for PNG frames")
    p.add_argument("--frames", type=int, default=100, help="frames to record (MJPEG: 0 = until interrupted)")
    p.add_argument("--fps", type=float, default=0, help="MJPEG rate cap")
    p.set_defaults(run=_cmd_record)

    p = sub.add_parser("effects", help="list, add, start, stop (fade), remove or change effects",
                       description="igclient effects list | add ID [type=smoke] [PATH=VALUE...] | start ID | "
                                   "stop ID | remove ID | set ID PATH=VALUE...")
    p.add_argument("action", nargs="?", default="list", choices=["list", "add", "start", "stop", "remove", "set"])
    p.add_argument("id", nargs="?")
    p.add_argument("fields", nargs="*", metavar="PATH=VALUE")
    p.set_defaults(run=_cmd_effects)

    p = sub.add_parser("bench", help="latency statistics: state sent -> frame received (the state is restored)")
    p.add_argument("--frames", type=int, default=200)
    p.add_argument("--modes", default="ws,http", help="ws, http or both")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.set_defaults(run=_cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except IGError as exc:
        print(f"igclient: rejected: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # bad assignment, scenario line, file type
        print(f"igclient: {exc}", file=sys.stderr)
        return 2
    except (httpx.TransportError, OSError) as exc:
        print(f"igclient: cannot reach {args.url}: {exc}" if isinstance(exc, httpx.TransportError)
              else f"igclient: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("igclient: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
