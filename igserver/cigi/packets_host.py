"""CIGI 3.3 host-to-IG packets (ICD SISO-STD-013-2014 layouts; ids 1-26; the environment's, 9-14, are
in packets_env.py and re-exported here).

Units as the ICD gives them: angles in degrees, distances in metres, latitude/longitude in degrees
(WGS 84), times in the packet's own units (hours/minutes, 10 µs timestamp ticks). ``check`` holds the
ranges the ICD states; a packet outside them makes the whole datagram malformed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .codec import MAGIC, Malformed, Packet, in_range
from .packets_env import (AtmosphereControl, CelestialSphereControl, EnvironmentalRegionControl,  # noqa: F401
                          MaritimeSurfaceConditionsControl, WaveControl, WeatherControl)  # (re-exported)

B = "B"  # one bit-packed byte


@dataclass
class IGControl(Packet):
    ID: ClassVar[int] = 1
    SIZE: ClassVar[int] = 24
    NAME: ClassVar[str] = "IG Control"
    LAYOUT: ClassVar[list] = [
        ("version", "B"), ("database_number", "b"),
        (None, B, (("ig_mode", 0, 2), ("timestamp_valid", 2, 1), ("extrapolation_enable", 3, 1),
                   ("minor_version", 4, 4))),
        (None, "x"), ("magic", "H"), ("host_frame", "I"), ("timestamp", "I"), ("last_ig_frame", "I"),
        (None, "4x"),
    ]
    version: int = 3
    database_number: int = 0  # 0 = keep the loaded database
    ig_mode: int = 1  # 0 reset/standby, 1 operate, 2 debug, 3 offline maintenance
    timestamp_valid: bool = False
    extrapolation_enable: bool = False
    minor_version: int = 3
    magic: int = MAGIC
    host_frame: int = 0
    timestamp: int = 0  # 10 µs ticks
    last_ig_frame: int = 0

    def check(self) -> None:
        if self.version != 3:
            raise Malformed("version", f"CIGI major version {self.version}, this IG speaks 3")


@dataclass
class EntityControl(Packet):
    ID: ClassVar[int] = 2
    SIZE: ClassVar[int] = 48
    NAME: ClassVar[str] = "Entity Control"
    LAYOUT: ClassVar[list] = [
        ("entity_id", "H"),
        (None, B, (("entity_state", 0, 2), ("attach_state", 2, 1), ("collision_detection", 3, 1),
                   ("inherit_alpha", 4, 1), ("ground_clamp", 5, 2))),
        (None, B, (("animation_direction", 0, 1), ("animation_loop", 1, 1), ("animation_state", 2, 2),
                   ("extrapolation_enable", 4, 1))),
        ("alpha", "B"), (None, "x"), ("entity_type", "H"), ("parent_id", "H"),
        ("roll", "f"), ("pitch", "f"), ("yaw", "f"), ("lat", "d"), ("lon", "d"), ("alt", "d"),
    ]
    ENUMS: ClassVar[dict] = {"entity_state": (0, 1, 2), "ground_clamp": (0, 1, 2)}
    entity_id: int = 0
    entity_state: int = 1  # 0 inactive/standby, 1 active, 2 destroyed
    attach_state: bool = False  # True: x/y/z offsets and angles relative to parent_id
    collision_detection: bool = False
    inherit_alpha: bool = False
    ground_clamp: int = 0  # 0 none, 1 non-conformal, 2 conformal
    animation_direction: bool = False
    animation_loop: bool = False
    animation_state: int = 0
    extrapolation_enable: bool = False
    alpha: int = 255
    entity_type: int = 0
    parent_id: int = 0
    roll: float = 0.0  # deg, right wing down
    pitch: float = 0.0  # deg, nose up
    yaw: float = 0.0  # deg clockwise from north
    lat: float = 0.0  # deg (or x offset, m, forward, when attached)
    lon: float = 0.0  # deg (or y offset, m, right)
    alt: float = 0.0  # m above MSL (or z offset, m, down)

    def check(self) -> None:
        in_range(self, "roll", -180.0, 180.0)
        in_range(self, "pitch", -90.0, 90.0)
        in_range(self, "yaw", 0.0, 360.0)
        if not self.attach_state:
            in_range(self, "lat", -90.0, 90.0)
            in_range(self, "lon", -180.0, 180.0)


@dataclass
class ConformalClampedEntityControl(Packet):
    ID: ClassVar[int] = 3
    SIZE: ClassVar[int] = 24
    NAME: ClassVar[str] = "Conformal Clamped Entity Control"
    LAYOUT: ClassVar[list] = [("entity_id", "H"), ("yaw", "f"), ("lat", "d"), ("lon", "d")]
    entity_id: int = 0
    yaw: float = 0.0
    lat: float = 0.0
    lon: float = 0.0

    def check(self) -> None:
        in_range(self, "yaw", 0.0, 360.0)
        in_range(self, "lat", -90.0, 90.0)
        in_range(self, "lon", -180.0, 180.0)


@dataclass
class ComponentControl(Packet):
    ID: ClassVar[int] = 4
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "Component Control"
    LAYOUT: ClassVar[list] = [
        ("component_id", "H"), ("instance_id", "H"), (None, B, (("component_class", 0, 6),)),
        ("component_state", "B"), ("data1", "I"), ("data2", "I"), ("data3", "I"), ("data4", "I"),
        ("data5", "I"), ("data6", "I"),
    ]
    ENUMS: ClassVar[dict] = {"component_class": range(16)}
    component_id: int = 0
    instance_id: int = 0
    component_class: int = 0  # 0 entity ... 15 symbol (ICD table)
    component_state: int = 0
    data1: int = 0  # raw 32-bit words: their meaning is the IG's (docs/cigi.md)
    data2: int = 0
    data3: int = 0
    data4: int = 0
    data5: int = 0
    data6: int = 0


@dataclass
class ShortComponentControl(Packet):
    ID: ClassVar[int] = 5
    SIZE: ClassVar[int] = 16
    NAME: ClassVar[str] = "Short Component Control"
    LAYOUT: ClassVar[list] = [
        ("component_id", "H"), ("instance_id", "H"), (None, B, (("component_class", 0, 6),)),
        ("component_state", "B"), ("data1", "I"), ("data2", "I"),
    ]
    ENUMS: ClassVar[dict] = {"component_class": range(16)}
    component_id: int = 0
    instance_id: int = 0
    component_class: int = 0
    component_state: int = 0
    data1: int = 0
    data2: int = 0


@dataclass
class ArticulatedPartControl(Packet):
    ID: ClassVar[int] = 6
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "Articulated Part Control"
    LAYOUT: ClassVar[list] = [
        ("entity_id", "H"), ("part_id", "B"),
        (None, B, (("part_enable", 0, 1), ("x_enable", 1, 1), ("y_enable", 2, 1), ("z_enable", 3, 1),
                   ("roll_enable", 4, 1), ("pitch_enable", 5, 1), ("yaw_enable", 6, 1))),
        (None, "2x"), ("x", "f"), ("y", "f"), ("z", "f"), ("roll", "f"), ("pitch", "f"), ("yaw", "f"),
    ]
    entity_id: int = 0
    part_id: int = 0
    part_enable: bool = True
    x_enable: bool = False
    y_enable: bool = False
    z_enable: bool = False
    roll_enable: bool = False
    pitch_enable: bool = False
    yaw_enable: bool = False
    x: float = 0.0  # m, forward
    y: float = 0.0  # m, right
    z: float = 0.0  # m, down
    roll: float = 0.0  # deg
    pitch: float = 0.0
    yaw: float = 0.0

    def check(self) -> None:
        in_range(self, "roll", -180.0, 180.0)
        in_range(self, "pitch", -90.0, 90.0)
        in_range(self, "yaw", -360.0, 360.0)


@dataclass
class ShortArticulatedPartControl(Packet):
    ID: ClassVar[int] = 7
    SIZE: ClassVar[int] = 16
    NAME: ClassVar[str] = "Short Articulated Part Control"
    LAYOUT: ClassVar[list] = [
        ("entity_id", "H"), ("part_id1", "B"), ("part_id2", "B"),
        (None, B, (("dof_select1", 0, 3), ("dof_select2", 3, 3), ("part_enable1", 6, 1),
                   ("part_enable2", 7, 1))),
        (None, "x"), ("dof1", "f"), ("dof2", "f"),
    ]
    ENUMS: ClassVar[dict] = {"dof_select1": range(7), "dof_select2": range(7)}
    entity_id: int = 0
    part_id1: int = 0
    part_id2: int = 0
    dof_select1: int = 0  # 0 unused, 1 x, 2 y, 3 z offset (m), 4 yaw, 5 pitch, 6 roll (deg)
    dof_select2: int = 0
    part_enable1: bool = True
    part_enable2: bool = True
    dof1: float = 0.0
    dof2: float = 0.0


@dataclass
class RateControl(Packet):
    ID: ClassVar[int] = 8
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "Rate Control"
    LAYOUT: ClassVar[list] = [
        ("entity_id", "H"), ("part_id", "B"), (None, B, (("apply_to_part", 0, 1), ("local", 1, 1))),
        (None, "2x"), ("x_rate", "f"), ("y_rate", "f"), ("z_rate", "f"),
        ("roll_rate", "f"), ("pitch_rate", "f"), ("yaw_rate", "f"),
    ]
    entity_id: int = 0
    part_id: int = 0
    apply_to_part: bool = False
    local: bool = False  # False: world axes (x north, y east, z down); True: body axes
    x_rate: float = 0.0  # m/s
    y_rate: float = 0.0
    z_rate: float = 0.0
    roll_rate: float = 0.0  # deg/s
    pitch_rate: float = 0.0
    yaw_rate: float = 0.0


@dataclass
class ViewControl(Packet):
    ID: ClassVar[int] = 16
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "View Control"
    LAYOUT: ClassVar[list] = [
        ("view_id", "H"), ("group_id", "B"),
        (None, B, (("x_enable", 0, 1), ("y_enable", 1, 1), ("z_enable", 2, 1), ("roll_enable", 3, 1),
                   ("pitch_enable", 4, 1), ("yaw_enable", 5, 1))),
        ("entity_id", "H"), ("x", "f"), ("y", "f"), ("z", "f"), ("roll", "f"), ("pitch", "f"), ("yaw", "f"),
    ]
    view_id: int = 0
    group_id: int = 0
    x_enable: bool = True
    y_enable: bool = True
    z_enable: bool = True
    roll_enable: bool = True
    pitch_enable: bool = True
    yaw_enable: bool = True
    entity_id: int = 0
    x: float = 0.0  # m forward of the entity's origin
    y: float = 0.0  # m right
    z: float = 0.0  # m down
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def check(self) -> None:
        in_range(self, "roll", -180.0, 180.0)
        in_range(self, "pitch", -90.0, 90.0)
        in_range(self, "yaw", -360.0, 360.0)


@dataclass
class ViewDefinition(Packet):
    ID: ClassVar[int] = 21
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "View Definition"
    LAYOUT: ClassVar[list] = [
        ("view_id", "H"), ("group_id", "B"),
        (None, B, (("near_enable", 0, 1), ("far_enable", 1, 1), ("left_enable", 2, 1), ("right_enable", 3, 1),
                   ("top_enable", 4, 1), ("bottom_enable", 5, 1), ("mirror_mode", 6, 2))),
        (None, B, (("pixel_replication", 0, 3), ("projection", 3, 1), ("reorder", 4, 1), ("view_type", 5, 3))),
        (None, "x"), ("near", "f"), ("far", "f"), ("left", "f"), ("right", "f"), ("top", "f"), ("bottom", "f"),
    ]
    view_id: int = 0
    group_id: int = 0
    near_enable: bool = True
    far_enable: bool = True
    left_enable: bool = True
    right_enable: bool = True
    top_enable: bool = True
    bottom_enable: bool = True
    mirror_mode: int = 0
    pixel_replication: int = 0
    projection: int = 0  # 0 perspective, 1 orthographic
    reorder: bool = False
    view_type: int = 0
    near: float = 0.1  # m
    far: float = 100_000.0  # m
    left: float = -30.0  # deg from the view axis, negative = left
    right: float = 30.0
    top: float = 20.0
    bottom: float = -20.0


@dataclass
class HatHotRequest(Packet):
    ID: ClassVar[int] = 24
    SIZE: ClassVar[int] = 32
    NAME: ClassVar[str] = "HAT/HOT Request"
    LAYOUT: ClassVar[list] = [
        ("request_id", "H"), (None, B, (("request_type", 0, 2), ("entity_relative", 2, 1))),
        ("update_period", "B"), ("entity_id", "H"), ("lat", "d"), ("lon", "d"), ("alt", "d"),
    ]
    ENUMS: ClassVar[dict] = {"request_type": (0, 1, 2)}
    request_id: int = 0
    request_type: int = 0  # 0 HAT, 1 HOT, 2 extended (both, with the normal)
    entity_relative: bool = False  # True: x/y/z offsets from entity_id (body axes)
    update_period: int = 0  # frames; 0 = answer once
    entity_id: int = 0
    lat: float = 0.0
    lon: float = 0.0
    alt: float = 0.0

    def check(self) -> None:
        if not self.entity_relative:
            in_range(self, "lat", -90.0, 90.0)
            in_range(self, "lon", -180.0, 180.0)


@dataclass
class LosSegmentRequest(Packet):
    ID: ClassVar[int] = 25
    SIZE: ClassVar[int] = 64
    NAME: ClassVar[str] = "Line of Sight Segment Request"
    LAYOUT: ClassVar[list] = [
        ("request_id", "H"),
        (None, B, (("request_type", 0, 1), ("source_entity_relative", 1, 1),
                   ("destination_entity_relative", 2, 1), ("response_entity_relative", 3, 1),
                   ("destination_entity_valid", 4, 1))),
        ("alpha_threshold", "B"), ("entity_id", "H"),
        ("source_lat", "d"), ("source_lon", "d"), ("source_alt", "d"),
        ("destination_lat", "d"), ("destination_lon", "d"), ("destination_alt", "d"),
        ("material_mask", "I"), ("update_period", "B"), (None, "x"), ("destination_entity_id", "H"),
    ]
    request_id: int = 0
    request_type: int = 0  # 0 basic, 1 extended (answered with a basic response)
    source_entity_relative: bool = False
    destination_entity_relative: bool = False
    response_entity_relative: bool = False
    destination_entity_valid: bool = False
    alpha_threshold: int = 0
    entity_id: int = 0
    source_lat: float = 0.0
    source_lon: float = 0.0
    source_alt: float = 0.0
    destination_lat: float = 0.0
    destination_lon: float = 0.0
    destination_alt: float = 0.0
    material_mask: int = 0xFFFFFFFF
    update_period: int = 0
    destination_entity_id: int = 0

    def check(self) -> None:
        for end, relative in (("source", self.source_entity_relative),
                              ("destination", self.destination_entity_relative)):
            if not relative:
                in_range(self, f"{end}_lat", -90.0, 90.0)
                in_range(self, f"{end}_lon", -180.0, 180.0)


@dataclass
class LosVectorRequest(Packet):
    ID: ClassVar[int] = 26
    SIZE: ClassVar[int] = 56
    NAME: ClassVar[str] = "Line of Sight Vector Request"
    LAYOUT: ClassVar[list] = [
        ("request_id", "H"),
        (None, B, (("request_type", 0, 1), ("source_entity_relative", 1, 1), ("response_entity_relative", 2, 1))),
        ("alpha_threshold", "B"), ("entity_id", "H"), ("azimuth", "f"), ("elevation", "f"),
        ("min_range", "f"), ("max_range", "f"), ("source_lat", "d"), ("source_lon", "d"), ("source_alt", "d"),
        ("material_mask", "I"), ("update_period", "B"), (None, "3x"),
    ]
    request_id: int = 0
    request_type: int = 0
    source_entity_relative: bool = False
    response_entity_relative: bool = False
    alpha_threshold: int = 0
    entity_id: int = 0
    azimuth: float = 0.0  # deg clockwise from north
    elevation: float = 0.0  # deg above the horizontal
    min_range: float = 0.0  # m
    max_range: float = 10_000.0  # m
    source_lat: float = 0.0
    source_lon: float = 0.0
    source_alt: float = 0.0
    material_mask: int = 0xFFFFFFFF
    update_period: int = 0

    def check(self) -> None:
        in_range(self, "azimuth", -360.0, 360.0)
        in_range(self, "elevation", -90.0, 90.0)
        in_range(self, "min_range", 0.0, 1e7)
        in_range(self, "max_range", self.min_range, 1e7)
        if not self.source_entity_relative:
            in_range(self, "source_lat", -90.0, 90.0)
            in_range(self, "source_lon", -180.0, 180.0)


HOST_PACKETS: dict[int, type[Packet]] = {cls.ID: cls for cls in (
    IGControl, EntityControl, ConformalClampedEntityControl, ComponentControl, ShortComponentControl,
    ArticulatedPartControl, ShortArticulatedPartControl, RateControl, CelestialSphereControl,
    AtmosphereControl, EnvironmentalRegionControl, WeatherControl, MaritimeSurfaceConditionsControl,
    WaveControl, ViewControl, ViewDefinition, HatHotRequest, LosSegmentRequest, LosVectorRequest,
)}
