"""The WebSocket ``/v1/ws``: frames pushed under a credit window, states and queries sent, msgpack both ways.

The calls are written once (steps.py); ``FrameStream`` runs them on a blocking connection
(websockets.sync), ``AsyncFrameStream`` on an asyncio one. Both are context managers.
"""

from __future__ import annotations

import asyncio

from igserver.scene import Scene

from .api import water_query
from .steps import Receive, Run, Send, operation
from .wire import Frame, frame_of, pack, scene_tree, unpack

MAX_MESSAGE_BYTES = 64 << 20  # a raw 4K frame is 33 MB


def ack_message(frame: Frame | int) -> bytes:
    return pack({"type": "ack", "frame": frame.frame if isinstance(frame, Frame) else frame})


class StreamCalls:
    """What both streams send and how they read what comes back. ``auto_ack``: each frame received is
    acknowledged at once, so the server sends the next one."""

    def __init__(self, url: str, credits: int, format: str, quality: int, auto_ack: bool,
                 headers: dict | None = None, channels: list[str] | None = None):
        self.url, self.credits, self.format, self.quality, self.auto_ack = url, credits, format, quality, auto_ack
        self.headers = headers or {}
        self.channels = channels
        self._next_id = 0
        self._early_frames: list[Frame] = []  # frames that arrived while waiting for a query result

    def hello(self) -> bytes:
        hello = {"type": "hello", "credits": self.credits, "format": self.format, "quality": self.quality}
        if self.channels is not None:
            hello["channels"] = list(self.channels)
        return pack(hello)

    def _message(self, body: dict) -> tuple[int, bytes]:
        self._next_id += 1
        return self._next_id, pack({**body, "id": self._next_id})

    @operation
    def send_patch(self, patch: dict) -> None:
        yield Send(self._message({"type": "patch", "state": patch})[1])

    @operation
    def send_state(self, state: Scene | dict) -> None:
        yield Send(self._message({"type": "replace", "state": scene_tree(state)})[1])

    @operation
    def ack(self, frame: Frame | int) -> None:
        yield Send(ack_message(frame))

    @operation
    def recv(self, timeout: float | None = 30.0) -> Frame:
        """The next frame (raises IGError when the server rejected one of our messages)."""
        if self._early_frames:
            return self._early_frames.pop(0)
        frame = frame_of(unpack((yield Receive(timeout))))
        if self.auto_ack:
            yield Send(ack_message(frame))
        return frame

    @operation
    def water_height(self, points, sim_time: float | None = None, timeout: float | None = 30.0) -> dict:
        """Sea height / normal / velocity at ENU points [(x, y), ...] over the stream (see IGClient)."""
        query_id, message = self._message({"type": "query", "query": "water-height", **water_query(points, sim_time)})
        yield Send(message)
        while True:
            reply = unpack((yield Receive(timeout)))
            if reply.get("type") == "query_result" and reply.get("id") == query_id:
                return reply
            frame = frame_of(reply)  # an error raises; a frame waits for recv()
            if self.auto_ack:
                yield Send(ack_message(frame))
            self._early_frames.append(frame)


class FrameStream(StreamCalls):
    """Blocking WebSocket stream (websockets.sync)."""

    def __enter__(self) -> "FrameStream":
        from websockets.sync.client import connect

        # images do not deflate: no per-message compression
        self._connection = connect(self.url, compression=None, max_size=MAX_MESSAGE_BYTES,
                                   additional_headers=self.headers)
        self.ws = self._connection.__enter__()
        self.ws.send(self.hello())
        return self

    def __exit__(self, *exc) -> None:
        self._connection.__exit__(*exc)

    def _drive(self, steps):
        run = Run(steps)
        for step in run:
            run.reply = self.ws.send(step.data) if isinstance(step, Send) else self.ws.recv(step.timeout)
        return run.value


class AsyncFrameStream(StreamCalls):
    """asyncio WebSocket stream: the same methods, awaited."""

    async def __aenter__(self) -> "AsyncFrameStream":
        from websockets.asyncio.client import connect

        self.ws = await connect(self.url, compression=None, max_size=MAX_MESSAGE_BYTES,
                                additional_headers=self.headers)
        await self.ws.send(self.hello())
        return self

    async def __aexit__(self, *exc) -> None:
        await self.ws.close()

    async def _drive(self, steps):
        run = Run(steps)
        for step in run:
            run.reply = await (self.ws.send(step.data) if isinstance(step, Send)
                               else asyncio.wait_for(self.ws.recv(), step.timeout))
        return run.value
