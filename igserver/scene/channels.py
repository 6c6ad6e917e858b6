"""Channels: N views of one world state (docs/channels.md).

A channel is one display of a multi-display installation (a ship's bridge, a cockpit's windows): a
view from the camera's position (the shared eyepoint) turned by its own heading/pitch/roll offsets,
through its own asymmetric frustum (four half-angles, as CIGI's View Definition), at its own size.
An empty list is the single camera of ``Scene.camera``.

Pure model code (no GL): the service and the render process's client import it.
"""

from __future__ import annotations

from typing import NamedTuple

from pydantic import BaseModel, ConfigDict, Field, model_validator

MAX_CHANNELS = 16
CHANNEL_ID_PATTERN = r"^[A-Za-z0-9_-]{1,32}$"


class Channel(BaseModel):
    """One view of the shared eyepoint. Angles are offsets in the camera's own frame: heading turns
    right (clockwise seen from above), pitch raises the view, roll turns it right-wing-down, applied
    as roll, then pitch, then heading, after the camera's orientation."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)

    id: str = Field(..., pattern=CHANNEL_ID_PATTERN, description="channel name, 1-32 of A-Z a-z 0-9 _ -")
    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg, offset from the camera's heading, right positive")
    pitch: float = Field(0.0, ge=-90.0, le=90.0, description="deg, offset from the camera's pitch, up positive")
    roll: float = Field(0.0, ge=-180.0, le=180.0, description="deg, offset from the camera's roll, right wing down positive")
    fov_left: float = Field(30.0, gt=0.0, le=89.0, description="deg, half-angle from the channel's axis to its left edge")
    fov_right: float = Field(30.0, gt=0.0, le=89.0, description="deg, half-angle from the axis to the right edge")
    fov_up: float = Field(18.0, gt=0.0, le=89.0, description="deg, half-angle from the axis to the top edge")
    fov_down: float = Field(18.0, gt=0.0, le=89.0, description="deg, half-angle from the axis to the bottom edge")
    width: int = Field(640, ge=16, le=7680, description="px")
    height: int = Field(360, ge=16, le=4320, description="px")
    near: float | None = Field(None, ge=1e-3, le=1e4, description="m, near clip distance; None = camera.near")
    far: float | None = Field(None, ge=1.0, le=1e7, description="m, draw distance of entities, lights and effects; "
                              "None = camera.far")

    @model_validator(mode="after")
    def _clip_order(self) -> "Channel":
        if self.near is not None and self.far is not None and not self.far > self.near:
            raise ValueError("channel far must be greater than near")
        return self


def check_clips(channels: list[Channel], camera) -> list[Channel]:
    """Each channel's far beyond its near, the camera's filling in what the channel leaves unset."""
    for i, channel in enumerate(channels):
        near = channel.near if channel.near is not None or camera is None else camera.near
        far = channel.far if channel.far is not None or camera is None else camera.far
        if near is not None and far is not None and not far > near:
            raise ValueError(f"channels.{i} ({channel.id!r}): far ({far:g} m) must be greater than near ({near:g} m; "
                             "camera.near/far fill in what a channel leaves unset)")
    return channels


def channel_sizes(scene) -> list[tuple[str, int, int]]:
    """[(id, width, height)] of what a frame of ``scene`` delivers: its channels, or the camera as ``""``."""
    if not scene.channels:
        return [("", scene.camera.width, scene.camera.height)]
    return [(c.id, c.width, c.height) for c in scene.channels]


class Size(NamedTuple):
    width: int
    height: int


def mosaic_layout(scene) -> tuple[Size, list[tuple[str, int, int, int]]]:
    """The channels side by side in list order, top-aligned: (Size of the mosaic, [(id, x0, width, height)])."""
    x, height, layout = 0, 0, []
    for cid, w, h in channel_sizes(scene):
        layout.append((cid, x, w, h))
        x += w
        height = max(height, h)
    return Size(x, height), layout


def total_pixels(scene) -> int:
    return sum(w * h for _, w, h in channel_sizes(scene))
