"""Point and spot lights and their flicker."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import EntityId, Strict, UnitColor, Vec3

MAX_LIGHTS = 256


class Flicker(Strict):
    enabled: bool = False
    frequency: float = Field(1.5, gt=0.0, le=50.0, description="Hz, peak frequency of the variation")
    amplitude: float = Field(0.3, ge=0.0, le=1.0, description="relative intensity variation")
    seed: int = Field(1, ge=0, le=2**31 - 1)


class Light(Strict):
    id: EntityId
    type: Literal["point", "spot"] = "point"
    position: Vec3 = (0.0, 0.0, 5.0)
    color: UnitColor = Field((1.0, 0.85, 0.6), description="linear RGB, 0..1")
    intensity: float = Field(1000.0, ge=0.0, le=1e8, description="cd, luminous intensity")
    range: float = Field(100.0, gt=0.0, le=1e5, description="m, distance where the light is cut off")
    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg, spot direction")
    pitch: float = Field(0.0, ge=-90.0, le=90.0, description="deg, spot direction")
    cone_inner: float = Field(10.0, ge=0.0, le=90.0, description="deg, spot full-intensity half-angle")
    cone_outer: float = Field(20.0, ge=0.0, le=90.0, description="deg, spot cut-off half-angle")
    flicker: Flicker = Field(default_factory=Flicker)

    @model_validator(mode="after")
    def _cone(self) -> "Light":
        if self.cone_outer < self.cone_inner:
            raise ValueError("cone_outer must be >= cone_inner")
        return self
