"""Channels in the service (docs/channels.md#the-service): a frame's channel images, choosing one by id,
and what ``GET /v1/channels`` describes.

A frame of a scene with channels carries every channel of one state (``Frame.channels``, render/worker.py),
all with the frame's IG frame number and host_frame. A scene without channels has one implicit channel,
the camera, whose id is the empty string ``""`` (as ``scene.channels.channel_sizes`` names it).
"""

from __future__ import annotations

import math

from ..scene.model import Scene
from .problems import ProblemError

IMPLICIT = ""  # the id of the single camera of a scene without channels


def frame_parts(frame) -> dict:
    """{channel id: Frame} of a rendered frame, in the scene's order; the frame itself as the implicit
    channel when its scene had none."""
    channels = getattr(frame, "channels", None)
    return channels if channels else {IMPLICIT: frame}


def state_channel_ids(scene: Scene) -> list[str]:
    return [c.id for c in scene.channels] or [IMPLICIT]


def choose(ids: list[str], channel: str | None, pointer: str = "#/query/channel") -> str:
    """The channel ``channel`` names among ``ids`` (None: the first); unknown: a 422 naming the parameter."""
    if channel is None:
        return ids[0]
    if channel not in ids:
        known = ", ".join(repr(i) for i in ids)
        detail = f"no channel {channel!r} in this state (its channels: {known}; GET /v1/channels lists them)"
        raise ProblemError("validation", f"{pointer}: {detail}", [{"pointer": pointer, "detail": detail}])
    return channel


def _camera_half_angles(scene: Scene) -> dict[str, float]:
    """The camera's frustum as four positive half-angles (deg): its asymmetric frustum when set, else fov_y
    and the frame's aspect (square pixels)."""
    camera = scene.camera
    if camera.frustum is not None:
        f = camera.frustum
        return {"fov_left": -f.left, "fov_right": f.right, "fov_up": f.top, "fov_down": -f.bottom}
    half_y = math.radians(camera.fov_y) / 2
    half_x = math.degrees(math.atan(math.tan(half_y) * camera.width / camera.height))
    return {"fov_left": half_x, "fov_right": half_x, "fov_up": math.degrees(half_y), "fov_down": math.degrees(half_y)}


def describe(scene: Scene) -> list[dict]:
    """Every channel a frame of ``scene`` delivers, in order: id, size (px), attitude offsets from the camera
    and half-angles (deg), near/far in effect (m). A scene without channels: the camera as one implicit
    channel (id ``""``, ``implicit: true``)."""
    camera = scene.camera
    if not scene.channels:
        return [{"id": IMPLICIT, "implicit": True, "width": camera.width, "height": camera.height,
                 "heading": 0.0, "pitch": 0.0, "roll": 0.0,
                 **{k: round(v, 6) for k, v in _camera_half_angles(scene).items()},
                 "near": camera.near, "far": camera.far}]
    out = []
    for channel in scene.channels:
        item = channel.model_dump(mode="json")
        item["near"] = camera.near if channel.near is None else channel.near
        item["far"] = camera.far if channel.far is None else channel.far
        out.append({**item, "implicit": False})
    return out
