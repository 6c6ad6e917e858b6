"""When and where: the clock (UTC for the sun, moon and stars; sim_time for animation), the sun's
override and the geodetic position of the scene origin."""

from __future__ import annotations

from datetime import datetime, timezone

from pydantic import Field, field_validator

from .base import Strict


class SunOverride(Strict):
    """Instructor override of the sun's position (replaces the ephemeris)."""

    elevation: float = Field(..., ge=-90.0, le=90.0, description="deg above the horizon")
    azimuth: float = Field(..., ge=-360.0, le=360.0, description="deg clockwise from north")


def _default_utc() -> datetime:
    return datetime(2026, 6, 21, 12, 0, tzinfo=timezone.utc)


class Time(Strict):
    utc: datetime = Field(default_factory=_default_utc, description="ISO 8601; drives sun, moon, stars")
    sim_time: float = Field(0.0, ge=0.0, le=1e12, description="s, drives animation (float64)")
    sun_override: SunOverride | None = Field(None, description="fix sun elevation/azimuth instead of the ephemeris")

    @field_validator("utc")
    @classmethod
    def _aware(cls, value: datetime) -> datetime:
        if value.tzinfo is None:
            value = value.replace(tzinfo=timezone.utc)
        # check the year after conversion: 1800-01-01T00:00+23:59 is 1799 in UTC
        try:
            value = value.astimezone(timezone.utc)
        except OverflowError:
            raise ValueError("utc year must be within 1800..2200") from None
        if not (1800 <= value.year <= 2200):
            raise ValueError("utc year must be within 1800..2200")
        return value


class Location(Strict):
    lat: float = Field(59.93, ge=-90.0, le=90.0, description="deg, geodetic latitude of the origin")
    lon: float = Field(30.31, ge=-180.0, le=180.0, description="deg, longitude of the origin")
    altitude: float = Field(0.0, ge=-500.0, le=9000.0, description="m above sea level of the origin")
