"""What the protocol's messages are to a client: msgpack, states as trees, frames, and problems as ``IGError``."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import httpx
import msgpack

from igserver.scene import Scene

MSGPACK = "application/vnd.msgpack"
DEFAULT_URL = "http://127.0.0.1:8600"


class IGError(Exception):
    """The server rejected a request or message: ``status`` and the problem document."""

    def __init__(self, status: int, problem: dict):
        self.status = status
        self.problem = problem
        fields = "; ".join(f"{e.get('pointer')}: {e.get('detail')}" for e in problem.get("errors", []))
        super().__init__(f"{status} {problem.get('title', '')}: {problem.get('detail', '')}"
                         + (f" [{fields}]" if fields else ""))


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
    channel: str | None = None  # the channel shown, when the state has channels
    # every channel of the frame by id (a message of several channels): this frame's own fields are the
    # first channel's; each part has the same frame and host_frame
    channels: dict[str, "Frame"] | None = None

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
        if "channels" in message:  # several channels of one frame, keyed by channel id
            parts = {cid: cls(message["frame"], message["host_frame"], image["width"], image["height"],
                              message["format"], image["data"], message["render_ms"], image.get("encode_ms", 0.0),
                              channel=cid)
                     for cid, image in message["channels"].items()}
            first = next(iter(parts.values()), None)
            if first is None:  # every channel asked for left the state
                return cls(message["frame"], message["host_frame"], 0, 0, message["format"], b"",
                           message["render_ms"], channels={})
            return cls(first.frame, first.host_frame, first.width, first.height, first.format, first.data,
                       first.render_ms, first.encode_ms, channel=first.channel, channels=parts)
        return cls(message["frame"], message["host_frame"], message["width"], message["height"],
                   message["format"], message["data"], message["render_ms"], message.get("encode_ms", 0.0),
                   channel=message.get("channel"))

    @classmethod
    def from_response(cls, response: httpx.Response, fmt: str) -> "Frame":
        h = response.headers
        return cls(int(h["x-ig-frame"]), int(h["x-ig-host-frame"]), int(h["x-ig-width"]), int(h["x-ig-height"]),
                   fmt, response.content, float(h["x-ig-render-ms"]), float(h.get("x-ig-encode-ms", 0)),
                   channel=h.get("x-ig-channel"))


def scene_tree(state: Scene | dict) -> dict:
    """A state as the wire carries it. A ``Scene`` carries ``time.sim_time`` only when it was given: any
    sim_time in a message hands the IG clock to the host, so a scene without one (a scene file that has
    none) must not send the model's default 0 and freeze the clock there. Plain dicts go as they are."""
    if not isinstance(state, Scene):
        return state
    tree = state.model_dump(mode="json")
    if "sim_time" not in state.time.model_fields_set:
        del tree["time"]["sim_time"]
    return tree


def pack(value: Any) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def unpack(data: bytes) -> Any:
    return msgpack.unpackb(data, raw=False)


def check(response: httpx.Response) -> httpx.Response:
    """The response, or ``IGError`` with its problem document (msgpack, JSON, or what the body says)."""
    if response.status_code >= 400:
        ctype = response.headers.get("content-type", "")
        if "msgpack" in ctype:
            problem = unpack(response.content)
        elif "json" in ctype:
            problem = response.json()
        else:
            problem = {"title": response.reason_phrase, "detail": response.text[:200]}
        raise IGError(response.status_code, problem)
    return response


def decode(response: httpx.Response) -> Any:
    if not response.content:
        return None
    if "msgpack" in response.headers.get("content-type", ""):
        return unpack(response.content)
    return response.json()


def frame_of(message: dict) -> Frame:
    """A WebSocket message that should be a frame; an error message raises its problem."""
    if message.get("type") == "error":
        problem = message.get("problem", {})
        raise IGError(problem.get("status", 400), problem)
    return Frame.from_message(message)
