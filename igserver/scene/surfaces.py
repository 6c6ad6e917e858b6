"""Surfaces: entities (glTF models), their articulated parts, shadows (docs/surfaces.md), and the ground
plane."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from ..assets import ASSET_NAME_PATTERN
from ..assets.gltf import check_model
from .base import EntityId, Strict, UnitColor, Vec3

MAX_ENTITIES = 256
MAX_PARTS = 32
PART_NAME_PATTERN = r"^[A-Za-z0-9_.:-][A-Za-z0-9_.: -]{0,63}$"
PartName = Annotated[str, Field(pattern=PART_NAME_PATTERN)]


class PartPose(Strict):
    """Pose of an articulated part (a glTF node, by name) relative to its rest pose in the file:
    rotated about the node's own origin (its pivot), then moved; angles in the entity's frame
    conventions (heading about the part's up axis, clockwise seen from above)."""

    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg, turn about the part's up axis (a radar)")
    pitch: float = Field(0.0, ge=-180.0, le=180.0, description="deg, about the part's starboard axis (a hatch)")
    roll: float = Field(0.0, ge=-180.0, le=180.0, description="deg, about the part's forward axis (a door)")
    offset: tuple[
        Annotated[float, Field(ge=-1e3, le=1e3)],
        Annotated[float, Field(ge=-1e3, le=1e3)],
        Annotated[float, Field(ge=-1e3, le=1e3)],
    ] = Field((0.0, 0.0, 0.0), description="m, translation along the entity's x (starboard), y (forward), z (up)")


class Entity(Strict):
    id: EntityId
    model: str = Field(
        "box", pattern=ASSET_NAME_PATTERN,
        description="model asset name: `box` (built-in 1 m cube, base at z = 0) or a glTF 2.0 model "
                    "(`NAME` or `NAME.glb`/`NAME.gltf`) in the models directory (IGSERVER_ASSETS/models, then "
                    "the packaged models: patrol_boat, pier, buoy, crate, barrel); checked when sent")
    visible: bool = Field(True, description="draw the entity (hidden entities keep their state)")
    position: Vec3 = (0.0, 0.0, 0.0)
    heading: float = Field(0.0, ge=-360.0, le=360.0)
    pitch: float = Field(0.0, ge=-90.0, le=90.0)
    roll: float = Field(0.0, ge=-180.0, le=180.0)
    scale: tuple[
        Annotated[float, Field(gt=0.0, le=1e4)],
        Annotated[float, Field(gt=0.0, le=1e4)],
        Annotated[float, Field(gt=0.0, le=1e4)],
    ] = Field((1.0, 1.0, 1.0), description="factors along the model's x (starboard), y (forward), z (up); "
                                           "models are in metres, so the box's scale is its size in m")
    parts: dict[PartName, PartPose] = Field(
        default_factory=dict, max_length=MAX_PARTS,
        description="articulated parts by glTF node name, e.g. {radar = {heading = 30}}")
    color: UnitColor = Field((0.5, 0.5, 0.5), description="linear base colour (built-in box only)")
    metallic: float = Field(0.0, ge=0.0, le=1.0, description="built-in box only")
    roughness: float = Field(0.6, ge=0.02, le=1.0, description="built-in box only")

    @field_validator("model")
    @classmethod
    def _model_file(cls, v: str) -> str:
        check_model(v)  # pure Python: header check, cached by file identity
        return v

    @model_validator(mode="after")
    def _part_names(self) -> "Entity":
        if self.parts:
            known = check_model(self.model).node_names
            unknown = sorted(set(self.parts) - known)
            if unknown:
                raise ValueError(f"model {self.model!r} has no part (glTF node) named {unknown[0]!r}"
                                 f" (parts: {', '.join(sorted(known)[:20]) or 'none'})")
        return self


class Shadows(Strict):
    """Shadow maps and the paper's shadow terms (docs/design.md#surfaces): in shadow the diffuse light is scaled
    by (1 - d + d * colour) and the specular light is removed."""

    enabled: bool = Field(True, description="sun/moon and spot-light shadow maps (skipped when nothing casts)")
    density: float = Field(1.0, ge=0.0, le=1.0, description="d_sh: 1 = a shadow removes the light, 0 = no shadow")
    color: UnitColor = Field((0.0, 0.0, 0.0), description="c_sh: linear colour a full shadow leaves of the diffuse light")
    softness: float = Field(0.1, ge=0.0, le=5.0, description="m, radius of the soft shadow edge (PCF filter on the receiver)")
    resolution: Literal[512, 1024, 2048, 4096] = Field(1024, description="px, side of the sun/moon shadow map")
    distance: float = Field(400.0, ge=10.0, le=5000.0, description="m, casters farther from the camera cast no shadow")


class Ground(Strict):
    enabled: bool = Field(True, description="draw the flat ground plane at z = level")
    level: float = Field(-0.5, ge=-11_000.0, le=9000.0, description="m, ENU height of the plane")
    color: UnitColor = Field((0.25, 0.24, 0.2), description="linear base colour")
    roughness: float = Field(0.9, ge=0.02, le=1.0)
