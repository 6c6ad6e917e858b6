"""Protocol v1's REST calls, each written once (steps.py): ``IGClient`` runs them blocking, ``AsyncIGClient``
awaited."""

from __future__ import annotations

import time
from typing import Any

import httpx

from igserver.scene import Scene

from .steps import Call, Pause, operation
from .wire import MSGPACK, Frame, check, decode, scene_tree, unpack


def answer(method: str, path: str, **call):
    """The decoded answer of one request (``IGError`` for a problem)."""
    return decode(check((yield Call(method, path, **call))))


def prefer(minimal: bool) -> dict:
    """RFC 7240: a 60 Hz host need not get the whole state back each time."""
    return {"Prefer": "return=minimal"} if minimal else {}


def water_query(points, sim_time: float | None) -> dict:
    body = {"points": [list(map(float, p)) for p in points]}
    if sim_time is not None:
        body["sim_time"] = float(sim_time)
    return body


def channel_param(channel: str | None) -> dict:
    return {} if channel is None else {"channel": channel}


class Api:
    """The calls both clients make. ``token``: the server's bearer token, if it has one."""

    def __init__(self, url: str, token: str | None = None):
        self.url = url.rstrip("/")
        self.headers = {"Accept": MSGPACK}
        if token:
            self.headers["Authorization"] = f"Bearer {token}"

    def ws_url(self) -> str:
        return "ws" + self.url[len("http"):] + "/v1/ws"

    def auth_headers(self) -> dict:
        return {k: v for k, v in self.headers.items() if k == "Authorization"}

    # -- health
    @operation
    def health(self) -> dict:
        return (yield from answer("GET", "/v1/health"))

    @operation
    def ready(self) -> dict:
        return (yield Call("GET", "/v1/ready")).json()  # 503 while not ready, with the same document

    @operation
    def wait_ready(self, timeout: float = 120.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            try:
                info = (yield Call("GET", "/v1/ready")).json()
                if info.get("ready"):
                    return info
            except httpx.TransportError:  # not listening yet
                pass
            if time.monotonic() > deadline:
                raise TimeoutError(f"igserver at {self.url} not ready after {timeout} s")
            yield Pause(0.1)

    @operation
    def metrics(self) -> str:
        return (yield Call("GET", "/metrics")).text

    # -- state
    @operation
    def get_state(self) -> Scene:
        return Scene.model_validate((yield from answer("GET", "/v1/state")))

    @operation
    def put_state(self, state: Scene | dict, minimal: bool = False) -> Scene | dict:
        """Replace the whole state. A Scene sends ``time.sim_time`` only if it was given (wire.scene_tree)."""
        reply = yield from answer("PUT", "/v1/state", body=scene_tree(state), headers=prefer(minimal))
        return reply if minimal else Scene.model_validate(reply)

    @operation
    def patch_state(self, patch: dict, minimal: bool = False) -> Scene | dict:
        reply = yield from answer("PATCH", "/v1/state", body=patch, headers=prefer(minimal))
        return reply if minimal else Scene.model_validate(reply)

    # -- the IG clock
    @operation
    def clock(self) -> dict:
        """{"mode": "free" | "host", "sim_time", "rate", "paused"}."""
        return (yield from answer("GET", "/v1/clock"))

    @operation
    def set_clock(self, mode: str | None = None, rate: float | None = None, paused: bool | None = None,
                  sim_time: float | None = None) -> dict:
        """Any subset: ``mode="free"`` takes the clock back from the host; rate in sim s per real s."""
        change = {k: v for k, v in (("mode", mode), ("rate", rate), ("paused", paused), ("sim_time", sim_time))
                  if v is not None}
        return (yield from answer("PATCH", "/v1/clock", body=change))

    # -- frames
    @operation
    def channels(self) -> list[dict]:
        """The current state's channels: id, width, height, attitude offsets, half-angles, near/far (a state
        without channels: the camera, id "", implicit)."""
        return (yield from answer("GET", "/v1/channels"))["channels"]

    @operation
    def get_frame(self, format: str = "jpeg", quality: int = 85, channel: str | None = None) -> Frame:
        """A frame of the current state: ``channel``'s image (None: the first channel, or the camera)."""
        params = {"format": format, "quality": quality, **channel_param(channel)}
        response = check((yield Call("GET", "/v1/frame", params=params, headers={"Accept": "*/*"})))
        return Frame.from_response(response, format)

    @operation
    def render(self, state: Scene | dict, replace: bool = False, format: str = "jpeg", quality: int = 85,
               channel: str | None = None) -> Frame:
        """The frame of exactly this state (a patch, or a whole state with replace=True). A state with
        channels answers every channel (``Frame.channels``, by id) unless ``channel`` names one."""
        params = {"replace": replace, "format": format, "quality": quality, **channel_param(channel)}
        response = check((yield Call("POST", "/v1/render", body=scene_tree(state), params=params)))
        return Frame.from_message(unpack(response.content))

    # -- effects
    @operation
    def effects(self) -> list[dict]:
        return (yield from answer("GET", "/v1/effects"))

    @operation
    def add_effect(self, effect: dict) -> dict:
        return (yield from answer("POST", "/v1/effects", body=effect))

    @operation
    def patch_effect(self, effect_id: str, patch: dict) -> dict:
        return (yield from answer("PATCH", f"/v1/effects/{effect_id}", body=patch))

    @operation
    def delete_effect(self, effect_id: str, immediate: bool = False) -> dict | None:
        """Fades it out, then it leaves the state (None: removed at once)."""
        return (yield from answer("DELETE", f"/v1/effects/{effect_id}", params={"immediate": immediate}))

    # -- queries
    @operation
    def water_height(self, points, sim_time: float | None = None) -> dict[str, Any]:
        """Sea surface at ENU points [(x, y), ...]: {"sim_time", "height", "normal", "velocity"} (the
        renderer's own wave maths and bathymetry; sim_time None = the current state's)."""
        return (yield from answer("POST", "/v1/query/water-height", body=water_query(points, sim_time)))
