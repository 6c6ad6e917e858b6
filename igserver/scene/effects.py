"""Volumetric effects: fires and smoke plumes, each in its bounding container."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from ..assets import ASSET_NAME_PATTERN, AssetError, resolve_asset
from ..assets.images import ImageError, check_profile_image
from ..effect_kinds import EFFECT_TYPES, FUEL_NAMES
from .base import EntityId, Strict, Vec3

MAX_EFFECTS = 64


class Effect(Strict):
    """A volumetric effect in its bounding container (docs/design.md#fire-and-smoke)."""

    id: EntityId
    type: Literal[EFFECT_TYPES] = "fire"  # igserver/effect_kinds.py
    position: Vec3 = Field((0.0, 0.0, 0.0), description="m, ENU position of the container's base centre")
    diameter: float = Field(2.0, ge=0.0, le=500.0, description="m, base diameter of the fire / plume")
    height: float | None = Field(None, ge=0.0, le=2000.0, description="m, container height; None = Heskestad")
    intensity: float = Field(1.0, ge=0.0, le=10.0, description="relative heat release (1 = nominal)")
    fuel: Literal[FUEL_NAMES] = Field("oil", description="what a fire burns (igserver/effect_kinds.py FUELS): its "
                                      "heat release per pool area, the flame's soot, the smoke's soot and colour")
    heat_release_kw: float | None = Field(
        None, ge=0.0, le=1e7, description="kW, a fire's nominal heat release; None = the pool's area x the fuel's "
        "burning rate x heat of combustion (x intensity either way)")
    active: bool = Field(True, description="burning (fades in) or extinguished (fades out)")
    fade: float = Field(3.0, ge=0.0, le=600.0, description="s, fade-in/out duration")
    emits_smoke: bool = Field(False, description="fire also emits a smoke plume")
    seed: int = Field(1, ge=0, le=2**31 - 1, description="random seed of noise and flicker")
    profile: str | None = Field(
        None, pattern=ASSET_NAME_PATTERN, description="optional profile: the name of a `profiles` asset (PNG; "
        "a name, never a path: see docs/operations.md, Assets)"
    )
    changed_at: float | None = Field(
        None, ge=0.0, le=1e12, description="s, sim_time of the last activate/deactivate (set by the IG)"
    )


    @field_validator("profile")
    @classmethod
    def _profile_asset(cls, value: str | None) -> str | None:
        # the host names an asset; the server's asset directory decides which file (docs/design.md#service)
        if value is not None:
            try:
                # its size from the header: one too big for memory is refused here, not at render time
                check_profile_image(value, resolve_asset("profiles", value, (".png",)))
            except (AssetError, ImageError) as exc:
                raise ValueError(str(exc)) from None
        return value
