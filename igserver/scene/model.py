"""The scene model: one typed description of everything the IG draws.

The same model is the protocol's message schema, the scene-file format and the renderer's input.
Every field has a unit, a default and a valid range; NaN, Inf, unknown fields and out-of-range
values are rejected with a message naming the field (pydantic's error ``loc``).

Conventions (docs/design.md#conventions): world frame is local ENU at the scene origin (x east, y north, z up,
metres, float64); angles on the wire are degrees (heading clockwise from north, pitch nose-up,
roll right-wing-down); ``time.utc`` drives sun/moon/stars, ``time.sim_time`` drives animation.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from .base import ID_PATTERN, WORLD_LIMIT_M, Coordinate, EntityId, Strict, UnitColor, Vec3
from .camera import Camera, Frustum
from .channels import MAX_CHANNELS, Channel, check_clips
from .effects import MAX_EFFECTS, Effect
from .lights import MAX_LIGHTS, Flicker, Light
from .ocean import Bathymetry, Ocean, Swell
from .quality import PRESET_NAMES, PresetName, Quality, TargetFps
from .surfaces import MAX_ENTITIES, MAX_PARTS, PART_NAME_PATTERN, Entity, Ground, PartName, PartPose, Shadows
from .time_location import Location, SunOverride, Time
from .weather import Atmosphere, Precipitation, Weather

__all__ = [
    "Scene", "Strict", "WORLD_LIMIT_M", "ID_PATTERN", "Coordinate", "Vec3", "UnitColor", "EntityId",
    "Camera", "Frustum", "Time", "SunOverride", "Location", "Atmosphere", "Precipitation", "Weather",
    "Ocean", "Bathymetry", "Swell", "Effect", "MAX_EFFECTS", "Light", "Flicker", "MAX_LIGHTS",
    "Entity", "PartPose", "PartName", "PART_NAME_PATTERN", "MAX_PARTS", "MAX_ENTITIES", "Shadows", "Ground",
    "Quality", "PresetName", "PRESET_NAMES", "TargetFps", "Channel", "MAX_CHANNELS",
]


def _unique_ids(items: list, what: str) -> list:
    seen: set[str] = set()
    for item in items:
        if item.id in seen:
            raise ValueError(f"duplicate {what} id {item.id!r}")
        seen.add(item.id)
    return items


class Scene(Strict):
    """The whole state the IG renders. Also the protocol's message body."""

    version: Literal[1] = 1
    host_frame: int = Field(0, ge=0, le=2**63 - 1, description="host frame number this state belongs to")
    camera: Camera = Field(default_factory=Camera)
    time: Time = Field(default_factory=Time)
    location: Location = Field(default_factory=Location)
    atmosphere: Atmosphere = Field(default_factory=Atmosphere)
    weather: Weather = Field(default_factory=Weather)
    ocean: Ocean = Field(default_factory=Ocean)
    ground: Ground = Field(default_factory=Ground)
    effects: list[Effect] = Field(default_factory=list, max_length=MAX_EFFECTS)
    lights: list[Light] = Field(default_factory=list, max_length=MAX_LIGHTS)
    entities: list[Entity] = Field(default_factory=list, max_length=MAX_ENTITIES)
    shadows: Shadows = Field(default_factory=Shadows)
    quality: Quality = Field(default_factory=Quality)
    channels: list[Channel] = Field(
        default_factory=list, max_length=MAX_CHANNELS,
        description="views of the camera's eyepoint rendered together (docs/channels.md); empty = the camera alone")

    @field_validator("effects")
    @classmethod
    def _effect_ids(cls, v):
        return _unique_ids(v, "effect")

    @field_validator("lights")
    @classmethod
    def _light_ids(cls, v):
        return _unique_ids(v, "light")

    @field_validator("entities")
    @classmethod
    def _entity_ids(cls, v):
        return _unique_ids(v, "entity")

    @field_validator("channels")
    @classmethod
    def _channels(cls, v, info):
        # camera is declared before channels: in info.data when it is valid
        return check_clips(_unique_ids(v, "channel"), info.data.get("camera"))

    # -- render budget (svc-runtime): every accepted state renders within a bounded cost (scene/budget.py)
    @model_validator(mode="after")
    def _within_budget(self):
        from .budget import over_budget

        problems = over_budget(self)
        if problems:
            raise ValidationError.from_exception_data("Scene", [
                InitErrorDetails(type=PydanticCustomError("over_budget", message), loc=loc, input=None)
                for loc, message in problems
            ])
        return self

