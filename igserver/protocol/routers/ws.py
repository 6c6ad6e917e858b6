"""WebSocket ``/v1/ws``: msgpack both ways, credit-based flow control.

Client -> server (binary msgpack maps):
  ``{"type": "hello", "credits": 2, "format": "jpeg", "quality": 85, "channels": ["port", "ahead"]}``
                                                    optional, first; sets the window, the format and the
                                                    channels each frame message carries (``[]``: all)
  ``{"type": "patch", "state": {...}, "id": 7}``   merge a partial state (``"replace"``: a whole state)
  ``{"type": "ack", "frame": 123}``                 one frame consumed: one credit back
  ``{"type": "credit", "n": 4}``                    grant more credits
  ``{"type": "query", "query": "water-height", "points": [[x, y], ...], "sim_time": t?, "id": 8}``
                                                    sea height/normal/velocity (routers/query.py)
Server -> client:
  ``{"type": "frame", "frame", "host_frame", "width", "height", "format", "data", "render_ms", "encode_ms", "ev100", "illuminance_lux", "quality"}``
      (the first channel, ``channel`` naming it when the state has channels), or after a hello with
      ``channels``: ``{"type": "frame", "frame", "host_frame", "format", "render_ms", "ev100", "illuminance_lux",
      "quality", "channels": {id: {"width", "height", "data", "encode_ms"}}, "missing"?: [ids]}``: every
      channel asked for, of one state, in one message (one credit)
  ``{"type": "error", "id": 7, "problem": {...}}``  a rejected message (RFC 9457 members); nothing changed
  ``{"type": "query_result", "id": 8, "query": "water-height", "sim_time", "height", "normal", "velocity"}``

Frames flow once the client's first message has arrived (a hello, or the first patch: then the window is
``ws_initial_credits``, 2 by default). Each frame sent costs one credit. With none left the server sends nothing; when a credit comes back it
sends the newest frame at that moment, never a queued old one. A slow client therefore sees fewer, fresh
frames, and the shared render loop never waits for it.

Memory: a client holds at most one frame in the server, the one being written. The next frame is chosen
(the newest then) only once the previous one has left the process; frames skipped meanwhile are counted
in ``igserver_frames_dropped_total{stream="ws"}``. At most ``max_ws_clients`` clients at once: one more
is accepted and closed at once with code 1013 (try again later).
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from types import SimpleNamespace

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from ..codec import MSGPACK, decode, encode
from ..dependencies import get_runtime
from ...render.memory import release_free_memory
from ..flow import drained, transport_of
from ..problems import ProblemError
from ..channels import choose, state_channel_ids
from ...scene.channels import MAX_CHANNELS
from .frames import channels_message, check_raw_channels, check_raw_size, frame_message

router = APIRouter(tags=["stream"])

FORMATS = ("jpeg", "png", "raw")


class Session:
    def __init__(self, websocket: WebSocket, runtime):
        self.ws = websocket
        self.runtime = runtime
        settings = runtime.settings
        self.credits = settings.ws_initial_credits
        self.max_credits = settings.ws_max_credits
        self.format = "jpeg"
        self.quality = settings.jpeg_quality
        self.credit_arrived = asyncio.Event()
        self.greeted = asyncio.Event()  # frames flow after the client's first message (normally hello)
        self.send_lock = asyncio.Lock()  # frames and error replies come from two tasks
        self.sent_raw = False
        self.channels: list[str] | None = None  # hello's channels ([]: all); None: the first channel alone

    async def send(self, value: dict) -> None:
        data = encode(value, MSGPACK)
        async with self.send_lock:
            await self.ws.send_bytes(data)

    def add_credits(self, n: int) -> None:
        self.credits = max(0, min(self.max_credits, self.credits + n))
        if self.credits:
            self.credit_arrived.set()

    # -- server -> client
    async def send_frames(self) -> None:
        runtime = self.runtime
        last_frame = -1  # numbers, not the frame: a sent frame is not kept alive by its client
        last_revision = -1
        transport = transport_of(self.ws.scope)
        await self.greeted.wait()
        with runtime.pump.subscription():
            while True:
                while self.credits <= 0:
                    self.credit_arrived.clear()
                    await self.credit_arrived.wait()
                # the previous frame must have left the process before the next one is built: a client
                # that does not read holds one frame (in the transport's buffer), not one per credit
                if not await drained(transport, runtime.stopping, kernel=False):
                    return
                seen = SimpleNamespace(ig_frame=last_frame) if last_frame >= 0 else None
                encoded = await runtime.pump.next_frame(seen, timeout=None)
                if last_frame >= 0 and encoded.ig_frame > last_frame + 1:
                    runtime.metrics.frames_dropped.inc(encoded.ig_frame - last_frame - 1, stream="ws")
                message = await self.message_of(encoded)
                self.credits -= 1
                await self.send(message)
                runtime.metrics.frames_sent.inc(stream="ws")
                if encoded.revision != last_revision:
                    if last_frame >= 0:
                        runtime.metrics.latency_ms.observe((time.perf_counter() - encoded.accepted_at) * 1e3,
                                                           stream="ws")
                    last_revision = encoded.revision
                last_frame = encoded.ig_frame
                del encoded, message

    async def message_of(self, encoded) -> dict:
        """The frame message this client asked for: the first channel's image (no ``channels`` in hello), or
        the asked channels of the frame in one map (``missing``: asked channels the frame has not)."""
        runtime = self.runtime
        ids = encoded.channel_ids
        wanted = [ids[0]] if self.channels is None else [c for c in (self.channels or ids) if c in ids]
        if self.format == "raw":
            try:
                parts = [encoded.part(c) for c in wanted]
                check_raw_size(runtime, "raw", 0, 0, pixels=sum(p.width * p.height for p in parts),
                               what="the frame's width/height or the channels asked for")
            except ProblemError as problem:  # the frame grew past the raw limit: go on in jpeg
                self.format = "jpeg"
                await self.send({"type": "error", "problem": problem.document("/v1/ws")})
        if self.format == "raw":  # the pixels themselves go into the message: no raw copy cached
            images = {c: (memoryview(encoded.part(c).rgba).cast("B"), 0.0) for c in wanted}
            self.sent_raw = True
        else:
            images = await encoded.encoded_channels(self.format, self.quality, wanted, runtime.metrics)
        if self.channels is None:
            return frame_message(encoded, self.format, *images[wanted[0]], wanted[0])
        message = channels_message(encoded, self.format, images)
        missing = [c for c in self.channels if c not in ids]
        if missing:
            message["missing"] = missing
        return message

    # -- client -> server
    async def receive_messages(self) -> None:
        limits = self.runtime.settings.limits
        while True:
            message = await self.ws.receive()
            if message["type"] == "websocket.disconnect":
                raise WebSocketDisconnect(message.get("code", 1000))
            request_id = None
            try:
                if message.get("bytes") is None:
                    raise ProblemError("unsupported_media_type", "send binary msgpack messages, not text")
                tree = decode(message["bytes"], MSGPACK, limits)
                if isinstance(tree, dict):
                    request_id = tree.get("id")
                if isinstance(tree, dict) and tree.get("type") == "query":
                    await self.send(await self.answer_query(tree))
                else:
                    self.handle(tree)
            except ProblemError as problem:
                self.runtime.metrics.protocol_errors.inc(kind=problem.kind)
                reply = {"type": "error", "problem": problem.document("/v1/ws")}
                if isinstance(request_id, (int, str)):
                    reply["id"] = request_id
                await self.send(reply)
            finally:
                self.greeted.set()

    async def answer_query(self, tree: dict) -> dict:
        from .query import answer_water_height

        if tree.get("query") != "water-height":
            raise ProblemError("validation", "unknown query", [{"pointer": "#/query", "detail": "expected water-height"}])
        body = {k: v for k, v in tree.items() if k not in ("type", "query", "id")}
        result = await answer_water_height(self.runtime, body)
        answer = {"type": "query_result", "query": "water-height", **result}
        if isinstance(tree.get("id"), (int, str)):
            answer["id"] = tree["id"]
        return answer

    def handle(self, tree) -> None:
        if not isinstance(tree, dict) or not isinstance(tree.get("type"), str):
            raise ProblemError("malformed", 'a message is a map with a "type"',
                               [{"pointer": "#/type", "detail": "required"}])
        kind = tree["type"]
        store = self.runtime.store
        if kind in ("patch", "replace"):
            state = tree.get("state")
            # errors point into the message: #/state/camera/pitch
            scene = (store.validate_patch if kind == "patch" else store.validate_replace)(state, ("state",))
            store.set_validated(scene, state)
            self.runtime.metrics.state_updates.inc(method=f"ws_{kind}")
        elif kind == "ack":
            self.add_credits(1)
        elif kind == "credit":
            n = tree.get("n", 1)
            if not isinstance(n, int) or isinstance(n, bool) or not 0 <= n <= self.max_credits:
                raise ProblemError("validation", f"n must be an integer 0..{self.max_credits}",
                                   [{"pointer": "#/n", "detail": "out of range"}])
            self.add_credits(n)
        elif kind == "hello":
            self.configure(tree)
        else:
            raise ProblemError("validation", f"unknown message type {kind!r}",
                               [{"pointer": "#/type", "detail": "expected hello, patch, replace, ack, credit or query"}])

    def configure(self, tree: dict) -> None:
        unknown = set(tree) - {"type", "credits", "format", "quality", "id", "channels"}
        if unknown:
            name = sorted(unknown)[0]
            raise ProblemError("validation", f"unknown field {name!r}", [{"pointer": f"#/{name}", "detail": "extra field"}])
        fmt = tree.get("format", self.format)
        if fmt not in FORMATS:
            raise ProblemError("validation", "format must be jpeg, png or raw", [{"pointer": "#/format", "detail": "invalid"}])
        quality = tree.get("quality", self.quality)
        if not isinstance(quality, int) or isinstance(quality, bool) or not 1 <= quality <= 100:
            raise ProblemError("validation", "quality must be 1..100", [{"pointer": "#/quality", "detail": "out of range"}])
        credits = tree.get("credits", self.credits)
        if not isinstance(credits, int) or isinstance(credits, bool) or not 0 <= credits <= self.max_credits:
            raise ProblemError("validation", f"credits must be 0..{self.max_credits}",
                               [{"pointer": "#/credits", "detail": "out of range"}])
        scene = self.runtime.store.scene
        channels = self.channels_asked(tree["channels"], scene) if "channels" in tree else self.channels
        ids = state_channel_ids(scene)
        check_raw_channels(self.runtime, fmt, scene,
                           [ids[0]] if channels is None else [c for c in (channels or ids) if c in ids])
        self.format, self.quality, self.channels = fmt, quality, channels
        self.credits = 0
        self.add_credits(credits)


    @staticmethod
    def channels_asked(value, scene) -> list[str]:
        """hello's ``channels``: ids of the current state's channels, each once (``[]``: every channel of
        each frame); a 422 naming the offending item otherwise."""
        if not isinstance(value, list) or len(value) > MAX_CHANNELS:
            raise ProblemError("validation", f"channels must be a list of at most {MAX_CHANNELS} channel ids",
                               [{"pointer": "#/channels", "detail": "expected a list of channel ids"}])
        ids = state_channel_ids(scene)
        for i, channel in enumerate(value):
            if not isinstance(channel, str):
                raise ProblemError("validation", f"#/channels/{i}: a channel id is a string",
                                   [{"pointer": f"#/channels/{i}", "detail": "expected a string"}])
            if channel in value[:i]:
                raise ProblemError("validation", f"#/channels/{i}: channel {channel!r} is asked for twice",
                                   [{"pointer": f"#/channels/{i}", "detail": "duplicate channel id"}])
            choose(ids, channel, f"#/channels/{i}")
        return list(value)


@router.websocket("/v1/ws")
async def frame_socket(websocket: WebSocket):
    runtime = get_runtime(websocket)
    await websocket.accept()
    limit = runtime.settings.max_ws_clients
    if runtime.stream_clients["ws"] >= limit:
        # accepted first: a close before the handshake would reach the client as HTTP 403, without the code
        runtime.metrics.protocol_errors.inc(kind="ws_clients")
        await websocket.close(code=1013, reason=f"too many WebSocket clients (max_ws_clients = {limit})")
        return
    session = Session(websocket, runtime)
    runtime.stream_clients["ws"] += 1
    tasks = (asyncio.create_task(session.send_frames()), asyncio.create_task(session.receive_messages()))
    failure = None
    try:
        done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        failure = next((task.exception() for task in done if not task.cancelled() and not isinstance(
            task.exception(), (type(None), WebSocketDisconnect, RuntimeError, OSError))), None)
        del done
    finally:
        runtime.stream_clients["ws"] -= 1
        for task in tasks:
            task.cancel()
        # gathered, not awaited one by one: an ended task's exception is not raised again in this frame,
        # whose traceback would then hold the frame and through it the task and its exception (a cycle
        # that keeps a frame-sized message alive until the cyclic collector happens to run)
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.gather(*tasks, return_exceptions=True)
        del tasks
        if session.sent_raw:  # frame-sized buffers were freed: give them back to the OS
            await asyncio.to_thread(release_free_memory)
    if failure is not None:
        try:
            raise failure
        finally:
            failure = None
