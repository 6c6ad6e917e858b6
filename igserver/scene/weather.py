"""The air: the atmosphere (sky model, visibility, fog, scattering tables) and the weather (wind,
precipitation, cirrus)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Strict


class Atmosphere(Strict):
    model: Literal["gradient", "precomputed"] = Field(
        "precomputed", description="sky tier: the paper's gradient model or precomputed scattering"
    )
    visibility: float = Field(30_000.0, ge=50.0, le=200_000.0, description="m, meteorological visibility")
    turbidity: float = Field(
        2.0, ge=1.0, le=10.0, description="Linke-style turbidity of the surface layer (tables per class of 0.5)"
    )
    # --- atmosphere engineer: the fog/haze layer (render/sky/haze.py) ---
    fog_top: float | None = Field(
        None, ge=1.0, le=5_000.0,
        description="m above the ground, top of a fog layer of the given visibility; None = haze thinning with height",
    )
    visibility_transition: float = Field(
        1.0, ge=0.0, le=10.0, description="s, a visibility change eases in over this much sim_time (0 = at once)"
    )
    ozone: bool = Field(True, description="include ozone absorption")
    scattering_orders: int = Field(4, ge=1, le=32, description="multiple-scattering orders of the tables")
    quality: Literal["low", "medium", "high"] = Field(
        "medium", description="precomputed table sizes (see igserver quality sky for the error curve)"
    )


class Precipitation(Strict):
    """Rain or snow (docs/design.md#precipitation; drawn by render/precip, physics in igserver/weather.py)."""

    type: Literal["none", "rain", "snow"] = Field("none", description="what falls; none = no particle pass")
    rate: float = Field(
        0.0, ge=0.0, le=200.0, description="mm/h, liquid-water-equivalent rate (snow too); 0 = nothing falls"
    )
    lowers_visibility: bool = Field(
        True,
        description="add the rain/snow extinction to atmosphere.visibility (then the visibility of the air "
        "alone); false = the host's visibility already includes the precipitation",
    )
    streak_time: float = Field(
        1.0 / 60.0, ge=1e-3, le=0.1,
        description="s, exposure of a streak: each particle is drawn from its position this long ago to now "
        "(independent of frame rate and camera motion)",
    )


class Weather(Strict):
    wind_speed: float = Field(5.0, ge=0.0, le=80.0, description="m/s at 10 m")
    wind_direction: float = Field(270.0, ge=0.0, le=360.0, description="deg, direction the wind blows FROM")
    precipitation: Precipitation = Field(default_factory=Precipitation)
    cirrus_coverage: float = Field(0.0, ge=0.0, le=1.0, description="fraction of the sky")
    cirrus_altitude: float = Field(9_000.0, ge=5_000.0, le=14_000.0, description="m above sea level, cirrus layer")
    cirrus_wind_speed: float | None = Field(
        None, ge=0.0, le=120.0, description="m/s, wind at the cirrus layer; None = 4x the surface wind (jet level)"
    )
