"""The sea: its state and waves, the swell and the sea floor under it."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from ..assets import ASSET_NAME_PATTERN, AssetError, resolve_asset
from .base import Coordinate, Strict


class Bathymetry(Strict):
    """Sea floor under the water (docs/design.md#water): depth shortens, refracts, shoals and breaks waves."""

    type: Literal["uniform", "slope", "map"] = Field(
        "uniform", description="uniform depth; a plane beach (slope); a height-map image asset (map)")
    depth: float = Field(1000.0, ge=0.001, le=11_000.0,
                         description="m, depth (offshore depth for slope; depth around the map for map)")
    shore_distance: float = Field(500.0, ge=0.0, le=1e6, description="m, origin-to-shoreline distance (slope)")
    shore_heading: float = Field(0.0, ge=0.0, le=360.0, description="deg, direction from origin to shore")
    slope: float = Field(0.02, gt=0.0, le=1.0, description="bottom slope dz/dx (slope)")
    berm_height: float = Field(2.0, ge=0.0, le=20.0,
                               description="m above the still water level, the beach's crest: the foreshore rises at "
                                           "the bottom's slope up to it (slope)")
    dune_height: float = Field(8.0, ge=0.0, le=50.0,
                               description="m, the foredune ridge behind the backshore (0: flat land) (slope)")
    map: str | None = Field(None, max_length=64, pattern=ASSET_NAME_PATTERN, validate_default=True,
                            description="bathymetry asset name: a grey PNG (map)")
    map_center: tuple[Coordinate, Coordinate] = Field((0.0, 0.0), description="m, ENU (x, y) of the image centre (map)")
    map_size: tuple[
        Annotated[float, Field(ge=1.0, le=1e6)], Annotated[float, Field(ge=1.0, le=1e6)]
    ] = Field((2000.0, 2000.0), description="m, ground size of the image across x (width) and y (height) (map)")
    map_heading: float = Field(0.0, ge=0.0, le=360.0, description="deg, compass direction of the image's top (map)")
    map_elevation: tuple[
        Annotated[float, Field(ge=-11_000.0, le=9000.0)], Annotated[float, Field(ge=-11_000.0, le=9000.0)]
    ] = Field((-50.0, 10.0), description="m, bottom elevation above the water level of black and of white (map)")

    @field_validator("map")
    @classmethod
    def _map(cls, value: str | None, info) -> str | None:
        # a field validator, so that its errors point at the map (#/ocean/bathymetry/map); ``type`` is
        # declared first, so it is in info.data when valid
        if value is None:
            if info.data.get("type") == "map":
                raise ValueError("bathymetry.type 'map' needs bathymetry.map (an asset name)")
            return value
        # the asset must exist: checked here, at the protocol edge, not at render time
        try:
            resolve_asset("bathymetry", value, (".png",))
        except AssetError as exc:
            raise ValueError(str(exc)) from None
        return value

    @model_validator(mode="after")
    def _map_elevation(self) -> "Bathymetry":
        if not self.map_elevation[1] > self.map_elevation[0]:
            raise ValueError("bathymetry.map_elevation must be (lower, higher)")
        return self


class Swell(Strict):
    """Long waves from a distant storm, travelling in their own direction (0 m = none)."""

    height: float = Field(0.0, ge=0.0, le=20.0, description="m, significant height of the swell")
    period: float = Field(10.0, ge=4.0, le=25.0, description="s, peak period")
    direction: float = Field(270.0, ge=0.0, le=360.0, description="deg, direction the swell comes FROM")


class Ocean(Strict):
    enabled: bool = False
    sea_state: int | None = Field(None, ge=0, le=9, description="WMO sea state; None = derived from wind")
    fetch_km: float | None = Field(
        None, ge=0.1, le=10_000.0, description="km, distance the wind has blown over open water (0.1 to 10000): "
        "the wind sea grows by the JONSWAP fetch law, capped at the Pierson-Moskowitz fully developed sea; "
        "None = not limiting (both None: the WMO/Beaufort probable height of the wind); a sea_state overrides it")
    duration_h: float | None = Field(
        None, ge=0.1, le=1000.0, description="h, how long the wind has blown (0.1 to 1000): the JONSWAP "
        "duration law; None = not limiting (with fetch_km also None: the WMO/Beaufort probable height); a "
        "sea_state overrides it")
    level: float = Field(0.0, ge=-500.0, le=9000.0, description="m, mean water level (ENU z)")
    bathymetry: Bathymetry = Field(default_factory=Bathymetry)
    swell: Swell = Field(default_factory=Swell)
    steepness: float = Field(
        0.6, ge=0.0, le=1.0, description="Gerstner steepness Q in deep water (0 round, 1 sharpest without loops)")
    wave_count: int = Field(24, ge=4, le=64, description="Gerstner waves displaced by the mesh (and the queries)")
    lod_error: float = Field(1.0, ge=0.25, le=16.0, description="px, screen-space error bound of the sea mesh LOD")
    detail_resolution: int = Field(128, ge=32, le=512, description="texels per side of each detail normal map (the nearest power of two is used)")
