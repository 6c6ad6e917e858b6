"""The camera: the eyepoint's pose, its frustum, the image size and the exposure."""

from __future__ import annotations

from pydantic import Field, model_validator

from .base import Strict, Vec3


class Frustum(Strict):
    """Asymmetric frustum as signed half-angles from the view axis (degrees), for multi-channel displays."""

    left: float = Field(-30.0, ge=-89.0, le=89.0, description="deg, negative = left of axis")
    right: float = Field(30.0, ge=-89.0, le=89.0, description="deg")
    bottom: float = Field(-20.0, ge=-89.0, le=89.0, description="deg, negative = below axis")
    top: float = Field(20.0, ge=-89.0, le=89.0, description="deg")

    @model_validator(mode="after")
    def _ordered(self) -> "Frustum":
        if not self.right > self.left:
            raise ValueError("frustum.right must be greater than frustum.left")
        if not self.top > self.bottom:
            raise ValueError("frustum.top must be greater than frustum.bottom")
        return self


class Camera(Strict):
    position: Vec3 = Field((0.0, 0.0, 10.0), description="m, ENU world position (float64)")
    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg clockwise from north")
    pitch: float = Field(0.0, ge=-90.0, le=90.0, description="deg, nose up positive")
    roll: float = Field(0.0, ge=-180.0, le=180.0, description="deg, right wing down positive")
    fov_y: float = Field(60.0, gt=0.1, lt=170.0, description="deg, vertical field of view (symmetric frustum)")
    frustum: Frustum | None = Field(None, description="asymmetric frustum; overrides fov_y when set")
    near: float = Field(0.1, ge=1e-3, le=1e4, description="m, near clip distance (depth precision does not depend on it)")
    far: float = Field(
        1_000_000.0, ge=1.0, le=1e7,
        description="m, draw distance of entities, lights and effects; the sky and the earth's surface are "
        "drawn to the horizon whatever it is (reversed-Z depth, no far clip plane)",
    )
    width: int = Field(640, ge=16, le=7680, description="px")
    height: int = Field(360, ge=16, le=4320, description="px")
    exposure_ev: float | None = Field(
        None, ge=-20.0, le=20.0, description="EV100 exposure (absolute); None = automatic (an adapting eye)"
    )
    # --- atmosphere engineer: exposure like an eye (render/post/exposure.py) ---
    adaptation: bool = Field(
        True, description="automatic exposure adapts over sim_time (0.4 s to light, 4 s to dark); false = steady state"
    )
    mesopic_vision: bool = Field(
        False, description="render night as the eye sees it: colour fades and shifts blue below ~3 cd/m^2 (Purkinje)"
    )

    @model_validator(mode="after")
    def _clip_order(self) -> "Camera":
        if not self.far > self.near:
            raise ValueError("camera.far must be greater than camera.near")
        return self
