"""CIGI 3.3 host-to-IG environment packets (ids 9-14): time of day, atmosphere, regions, weather, sea.

Units as the ICD gives them (degrees, metres, %, °C, mbar); ``check`` holds the ranges the ICD states.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .codec import Malformed, Packet, in_range

B = "B"  # one bit-packed byte


@dataclass
class CelestialSphereControl(Packet):
    ID: ClassVar[int] = 9
    SIZE: ClassVar[int] = 16
    NAME: ClassVar[str] = "Celestial Sphere Control"
    LAYOUT: ClassVar[list] = [
        ("hour", "B"), ("minute", "B"),
        (None, B, (("ephemeris_enable", 0, 1), ("sun_enable", 1, 1), ("moon_enable", 2, 1),
                   ("star_enable", 3, 1), ("date_time_valid", 4, 1))),
        (None, "3x"), ("date", "I"), ("star_intensity", "f"),
    ]
    hour: int = 12  # UTC
    minute: int = 0
    ephemeris_enable: bool = True
    sun_enable: bool = True
    moon_enable: bool = True
    star_enable: bool = True
    date_time_valid: bool = True
    date: int = 6212026  # MMDDYYYY as a decimal number
    star_intensity: float = 100.0  # %

    def check(self) -> None:
        in_range(self, "hour", 0, 23)
        in_range(self, "minute", 0, 59)
        in_range(self, "star_intensity", 0.0, 100.0)
        if self.date_time_valid:
            month, day = self.date // 1_000_000, self.date // 10_000 % 100
            if not (1 <= month <= 12 and 1 <= day <= 31):
                raise Malformed("out_of_range", f"{self.NAME}.date = {self.date} is not MMDDYYYY")


@dataclass
class AtmosphereControl(Packet):
    ID: ClassVar[int] = 10
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "Atmosphere Control"
    LAYOUT: ClassVar[list] = [
        (None, B, (("model_enable", 0, 1),)), ("humidity", "B"), ("air_temperature", "f"),
        ("visibility", "f"), ("horizontal_wind", "f"), ("vertical_wind", "f"), ("wind_direction", "f"),
        ("pressure", "f"), (None, "4x"),
    ]
    model_enable: bool = False
    humidity: int = 30  # %
    air_temperature: float = 15.0  # °C
    visibility: float = 30_000.0  # m
    horizontal_wind: float = 0.0  # m/s
    vertical_wind: float = 0.0  # m/s
    wind_direction: float = 0.0  # deg, the direction the wind blows from
    pressure: float = 1013.25  # mbar

    def check(self) -> None:
        in_range(self, "humidity", 0, 100)
        in_range(self, "visibility", 0.0, 1e9)
        in_range(self, "horizontal_wind", 0.0, 1e3)
        in_range(self, "wind_direction", 0.0, 360.0)


@dataclass
class EnvironmentalRegionControl(Packet):
    ID: ClassVar[int] = 11
    SIZE: ClassVar[int] = 48
    NAME: ClassVar[str] = "Environmental Region Control"
    LAYOUT: ClassVar[list] = [
        ("region_id", "H"),
        (None, B, (("region_state", 0, 2), ("merge_weather", 2, 1), ("merge_aerosol", 3, 1),
                   ("merge_maritime", 4, 1), ("merge_terrestrial", 5, 1))),
        (None, "3x"), ("lat", "d"), ("lon", "d"), ("size_x", "f"), ("size_y", "f"), ("corner_radius", "f"),
        ("rotation", "f"), ("transition_perimeter", "f"), (None, "4x"),
    ]
    ENUMS: ClassVar[dict] = {"region_state": (0, 1, 2)}
    region_id: int = 0
    region_state: int = 1  # 0 inactive, 1 active, 2 destroyed
    merge_weather: bool = False
    merge_aerosol: bool = False
    merge_maritime: bool = False
    merge_terrestrial: bool = False
    lat: float = 0.0
    lon: float = 0.0
    size_x: float = 1000.0  # m
    size_y: float = 1000.0  # m
    corner_radius: float = 0.0  # m
    rotation: float = 0.0  # deg
    transition_perimeter: float = 0.0  # m

    def check(self) -> None:
        in_range(self, "lat", -90.0, 90.0)
        in_range(self, "lon", -180.0, 180.0)
        in_range(self, "size_x", 0.0, 1e8)
        in_range(self, "size_y", 0.0, 1e8)


@dataclass
class WeatherControl(Packet):
    ID: ClassVar[int] = 12
    SIZE: ClassVar[int] = 56
    NAME: ClassVar[str] = "Weather Control"
    LAYOUT: ClassVar[list] = [
        ("region_id", "H"), ("layer_id", "B"), ("humidity", "B"),
        (None, B, (("weather_enable", 0, 1), ("scud_enable", 1, 1), ("random_winds", 2, 1),
                   ("random_lightning", 3, 1), ("cloud_type", 4, 4))),
        (None, B, (("scope", 0, 2), ("severity", 2, 3))),
        ("air_temperature", "f"), ("visibility", "f"), ("scud_frequency", "f"), ("coverage", "f"),
        ("base_elevation", "f"), ("thickness", "f"), ("transition_band", "f"), ("horizontal_wind", "f"),
        ("vertical_wind", "f"), ("wind_direction", "f"), ("pressure", "f"), ("aerosol", "f"),
    ]
    ENUMS: ClassVar[dict] = {"scope": (0, 1, 2), "severity": range(6)}
    region_id: int = 0  # entity or region id (scope 1, 2)
    layer_id: int = 0  # 0 ground fog, 1-3 clouds, 4 rain, 5 snow, 6 sleet, 7 hail, 8 sand, 9 dust
    humidity: int = 30
    weather_enable: bool = True
    scud_enable: bool = False
    random_winds: bool = False
    random_lightning: bool = False
    cloud_type: int = 0  # 0 none, 1 altocumulus ... 5 cirrus ... 10 stratus
    scope: int = 0  # 0 global, 1 regional, 2 entity
    severity: int = 0  # 0..5
    air_temperature: float = 15.0
    visibility: float = 30_000.0  # m
    scud_frequency: float = 0.0  # %
    coverage: float = 0.0  # %
    base_elevation: float = 0.0  # m above MSL
    thickness: float = 0.0  # m
    transition_band: float = 0.0  # m
    horizontal_wind: float = 0.0
    vertical_wind: float = 0.0
    wind_direction: float = 0.0
    pressure: float = 1013.25
    aerosol: float = 0.0  # g/m^3

    def check(self) -> None:
        in_range(self, "humidity", 0, 100)
        in_range(self, "coverage", 0.0, 100.0)
        in_range(self, "visibility", 0.0, 1e9)
        in_range(self, "thickness", 0.0, 1e6)


@dataclass
class MaritimeSurfaceConditionsControl(Packet):
    ID: ClassVar[int] = 13
    SIZE: ClassVar[int] = 24
    NAME: ClassVar[str] = "Maritime Surface Conditions Control"
    LAYOUT: ClassVar[list] = [
        ("region_id", "H"),
        (None, B, (("surface_enable", 0, 1), ("whitecap_enable", 1, 1), ("scope", 2, 2))),
        (None, "3x"), ("sea_surface_height", "f"), ("water_temperature", "f"), ("clarity", "f"), (None, "4x"),
    ]
    ENUMS: ClassVar[dict] = {"scope": (0, 1, 2)}
    region_id: int = 0
    surface_enable: bool = True
    whitecap_enable: bool = True
    scope: int = 0
    sea_surface_height: float = 0.0  # m above MSL
    water_temperature: float = 15.0  # °C
    clarity: float = 100.0  # %


@dataclass
class WaveControl(Packet):
    ID: ClassVar[int] = 14
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "Wave Control"
    LAYOUT: ClassVar[list] = [
        ("region_id", "H"), ("wave_id", "B"),
        (None, B, (("wave_enable", 0, 1), ("scope", 1, 2), ("breaker_type", 3, 2))),
        (None, "2x"), ("height", "f"), ("wavelength", "f"), ("period", "f"), ("direction", "f"),
        ("phase_offset", "f"), ("leading", "f"),
    ]
    ENUMS: ClassVar[dict] = {"scope": (0, 1, 2), "breaker_type": (0, 1, 2)}
    region_id: int = 0
    wave_id: int = 0  # this IG: 0 = the wind sea, 1 = the swell
    wave_enable: bool = True
    scope: int = 0
    breaker_type: int = 0
    height: float = 0.0  # m, trough to crest
    wavelength: float = 0.0  # m
    period: float = 10.0  # s
    direction: float = 0.0  # deg, where the waves come from
    phase_offset: float = 0.0
    leading: float = 0.0

    def check(self) -> None:
        in_range(self, "height", 0.0, 100.0)
        in_range(self, "direction", -360.0, 360.0)
        in_range(self, "period", 0.0, 1e4)
