"""Environment packets -> scene fields: time of day, atmosphere, global weather, the sea.

Global scope (0) is rendered; regional (1) and entity (2) scope are kept in the session and counted
as not rendered, as are the fields the scene has no place for (air temperature, pressure, ...).
Where CIGI's range is wider than the scene's (visibility "unlimited", a swell period of 0) the value is
clamped to the scene's bounds, and the table in docs/cigi.md says so; everything else is validated.
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING

from .codec import Malformed
from .packets_host import (AtmosphereControl, CelestialSphereControl, EnvironmentalRegionControl,
                           MaritimeSurfaceConditionsControl, WaveControl, WeatherControl)

if TYPE_CHECKING:
    from .mapping import Work

VISIBILITY_M = (50.0, 200_000.0)  # the scene's atmosphere.visibility bounds
CIRRUS_TYPES = (3, 4, 5)  # cirrocumulus, cirrostratus, cirrus: the cloud layer the sky draws
CIRRUS_ALTITUDE_M = (5_000.0, 14_000.0)
FOG_TOP_M = (1.0, 5_000.0)
# Weather Control severity 0..5 -> precipitation rate (mm/h): light drizzle .. cloudburst
SEVERITY_RATE = (0.5, 2.0, 5.0, 12.0, 30.0, 80.0)
PRECIPITATION_LAYERS = {4: "rain", 5: "snow", 6: "snow", 7: "rain"}  # rain, snow, sleet (as snow), hail (as rain)
# WMO sea state code by significant wave height (m, upper bounds of codes 0..8; above = 9)
SEA_STATE_HEIGHTS = (0.0, 0.1, 0.5, 1.25, 2.5, 4.0, 6.0, 9.0, 14.0)
SWELL_PERIOD_S = (4.0, 25.0)


def clamp(value: float, bounds: tuple[float, float]) -> float:
    return min(max(value, bounds[0]), bounds[1])


def celestial(work: "Work", p: CelestialSphereControl) -> None:
    work.session.celestial = {"ephemeris": p.ephemeris_enable, "sun": p.sun_enable, "moon": p.moon_enable,
                              "stars": p.star_enable, "star_intensity": p.star_intensity}
    if not (p.sun_enable and p.moon_enable and p.star_enable) or p.star_intensity != 100.0:
        work.plan.not_rendered["celestial_enables"] += 1
    if not p.date_time_valid:
        return
    month, day, year = p.date // 1_000_000, p.date // 10_000 % 100, p.date % 10_000
    try:
        utc = dt.datetime(year, month, day, p.hour, p.minute, tzinfo=dt.timezone.utc)
    except ValueError as exc:
        raise Malformed("out_of_range", f"Celestial Sphere Control date {p.date}: {exc}") from None
    work.set("time", "utc", utc.isoformat())


def humidity_turbidity(humidity: float) -> float:
    """Relative humidity (%) -> the sky's turbidity: dry air up to 30 % keeps the clear default (2),
    then haze thickens quadratically to 6 at saturation (hygroscopic aerosol swelling)."""
    return 2.0 + 4.0 * (max(humidity - 30.0, 0.0) / 70.0) ** 2


def atmosphere(work: "Work", p: AtmosphereControl) -> None:
    work.set("atmosphere", "visibility", clamp(p.visibility, VISIBILITY_M))
    work.set("atmosphere", "turbidity", humidity_turbidity(p.humidity))
    work.set("weather", "wind_speed", p.horizontal_wind)
    work.set("weather", "wind_direction", p.wind_direction % 360.0)
    work.session.atmosphere = {"air_temperature": p.air_temperature, "pressure": p.pressure,
                               "vertical_wind": p.vertical_wind, "model_enable": p.model_enable}
    work.plan.not_rendered["atmosphere_temperature_pressure"] += 1


def weather(work: "Work", p: WeatherControl) -> None:
    if p.scope != 0:
        work.session.regional[f"weather:{p.scope}:{p.region_id}:{p.layer_id}"] = vars(p).copy()
        work.plan.not_rendered["regional_weather"] += 1
        return
    layer = p.layer_id
    if layer == 0:  # ground fog: its top and visibility
        top = clamp(p.base_elevation + p.thickness, FOG_TOP_M) if p.weather_enable else None
        work.set("atmosphere", "fog_top", top)
        if p.weather_enable:
            work.set("atmosphere", "visibility", clamp(p.visibility, VISIBILITY_M))
    elif layer in (1, 2, 3):
        if p.cloud_type in CIRRUS_TYPES or not p.weather_enable:
            work.set("weather", "cirrus_coverage", p.coverage / 100.0 if p.weather_enable else 0.0)
            if p.weather_enable:
                work.set("weather", "cirrus_altitude", clamp(p.base_elevation, CIRRUS_ALTITUDE_M))
        else:
            work.plan.not_rendered[f"cloud_type_{p.cloud_type}"] += 1
    elif layer in PRECIPITATION_LAYERS:
        kind = PRECIPITATION_LAYERS[layer]
        current = work.patch.get("weather", {}).get("precipitation", {}).get(
            "type", work.tree["weather"]["precipitation"]["type"])
        if p.weather_enable:
            work.set("weather", "type", kind, sub="precipitation")
            work.set("weather", "rate", SEVERITY_RATE[p.severity], sub="precipitation")
        elif current == kind:
            work.set("weather", "type", "none", sub="precipitation")
            work.set("weather", "rate", 0.0, sub="precipitation")
    else:
        work.plan.not_rendered[f"weather_layer_{layer}"] += 1


def region(work: "Work", p: EnvironmentalRegionControl) -> None:
    if p.region_state == 2:
        work.session.regions.pop(p.region_id, None)
    else:
        work.session.regions[p.region_id] = vars(p).copy()
    work.plan.not_rendered["environmental_region"] += 1


def maritime(work: "Work", p: MaritimeSurfaceConditionsControl) -> None:
    if p.scope != 0:
        work.session.regional[f"maritime:{p.scope}:{p.region_id}"] = vars(p).copy()
        work.plan.not_rendered["regional_maritime"] += 1
        return
    work.set("ocean", "enabled", p.surface_enable)
    if p.surface_enable:
        work.set("ocean", "level", p.sea_surface_height)


def sea_state(height: float) -> int:
    """WMO sea state code of a significant wave height (m)."""
    for code, bound in enumerate(SEA_STATE_HEIGHTS):
        if height <= bound:
            return code
    return 9


def wave(work: "Work", p: WaveControl) -> None:
    if p.scope != 0:
        work.session.regional[f"wave:{p.scope}:{p.region_id}:{p.wave_id}"] = vars(p).copy()
        work.plan.not_rendered["regional_waves"] += 1
        return
    if p.wave_id == 0:  # the wind sea: its height sets the sea state (None = from the wind)
        work.set("ocean", "sea_state", sea_state(p.height) if p.wave_enable else None)
    elif p.wave_id == 1:  # the swell
        work.set("ocean", "height", p.height if p.wave_enable else 0.0, sub="swell")
        if p.wave_enable:
            work.set("ocean", "period", clamp(p.period, SWELL_PERIOD_S), sub="swell")
            work.set("ocean", "direction", p.direction % 360.0, sub="swell")
    else:
        work.plan.not_rendered["wave_component"] += 1


HANDLERS = {
    CelestialSphereControl: celestial, AtmosphereControl: atmosphere, WeatherControl: weather,
    EnvironmentalRegionControl: region, MaritimeSurfaceConditionsControl: maritime, WaveControl: wave,
}
