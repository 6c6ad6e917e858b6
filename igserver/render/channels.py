"""Channels: the camera of each view of one world state (docs/channels.md).

A channel's view is the camera's position (the shared eyepoint) with the orientation

    R_channel = R_camera · R(heading, pitch, roll of the channel)

(both ``body_to_world``: the channel's offsets are turns in the camera's own frame), through the
asymmetric frustum of its four half-angles (the projection of ``camera.reversed_infinite_projection``
built from (-left, right, -down, up): glFrustum's l, r, b, t at unit distance). Two channels whose
facing edges are the same plane (headings ±a with fov_right = fov_left = a, the common case of a
display wall) then share every ray along that edge exactly.

The channel's scene is the state with that camera and no channels: every pass draws it as it draws
any frame, and the world items every pass memoises (keyed on their inputs, render/memo.py) are the
same for all channels of the state.
"""

from __future__ import annotations

import math

import numpy as np

from ..scene.channels import Channel
from ..scene.model import Camera, Frustum, Scene
from .camera import body_to_world


def euler_of(rotation: np.ndarray) -> tuple[float, float, float]:
    """(heading, pitch, roll) in degrees of a ``body_to_world`` rotation (columns right, forward, up):
    forward = (sin h cos p, cos h cos p, sin p), and the up row's z is (-cos p sin r, sin p, cos p cos r)."""
    f = rotation[:, 1]
    pitch = math.degrees(math.asin(min(max(float(f[2]), -1.0), 1.0)))
    if math.hypot(float(f[0]), float(f[1])) > 1e-12:
        heading = math.degrees(math.atan2(float(f[0]), float(f[1])))
        roll = math.degrees(math.atan2(-float(rotation[2, 0]), float(rotation[2, 2])))
    else:  # straight up or down: heading and roll turn about the same axis; put it all in heading
        heading = math.degrees(math.atan2(-float(rotation[1, 0]), float(rotation[0, 0])))
        roll = 0.0
    return heading, pitch, roll


def channel_camera(camera: Camera, channel: Channel) -> Camera:
    """The camera of ``channel``: the eyepoint's position, the composed orientation, the channel's
    frustum, size and clip distances (the camera's where the channel leaves them unset)."""
    if channel.heading == channel.pitch == channel.roll == 0.0:
        heading, pitch, roll = camera.heading, camera.pitch, camera.roll
    else:
        rotation = (body_to_world(camera.heading, camera.pitch, camera.roll)
                    @ body_to_world(channel.heading, channel.pitch, channel.roll))
        heading, pitch, roll = euler_of(rotation)
    frustum = Frustum(left=-channel.fov_left, right=channel.fov_right, bottom=-channel.fov_down, top=channel.fov_up)
    # model_copy: every value is within the Camera's ranges (validated parts, atan2/asin results)
    return camera.model_copy(update={
        "heading": heading, "pitch": pitch, "roll": roll, "frustum": frustum,
        "width": channel.width, "height": channel.height,
        "near": camera.near if channel.near is None else channel.near,
        "far": camera.far if channel.far is None else channel.far,
    })


def channel_scene(scene: Scene, channel: Channel) -> Scene:
    """``scene`` seen through ``channel``: its camera, and no channels (a plain one-view scene)."""
    return scene.model_copy(update={"camera": channel_camera(scene.camera, channel), "channels": []})


def side_by_side(images: list[np.ndarray]) -> np.ndarray:
    """RGBA images in a row, top-aligned; rows below a shorter image are transparent black."""
    height = max(im.shape[0] for im in images)
    out = np.zeros((height, sum(im.shape[1] for im in images), 4), np.uint8)
    x = 0
    for im in images:
        out[:im.shape[0], x:x + im.shape[1]] = im
        x += im.shape[1]
    return out
