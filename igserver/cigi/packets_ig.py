"""CIGI 3.3 IG-to-host packets this IG sends: Start of Frame and the query responses (ids 101-104)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .codec import MAGIC, Malformed, Packet

B = "B"


@dataclass
class StartOfFrame(Packet):
    ID: ClassVar[int] = 101
    SIZE: ClassVar[int] = 24
    NAME: ClassVar[str] = "Start of Frame"
    LAYOUT: ClassVar[list] = [
        ("version", "B"), ("database_number", "b"), ("ig_status", "B"),
        (None, B, (("ig_mode", 0, 2), ("timestamp_valid", 2, 1), ("earth_model", 3, 1), ("minor_version", 4, 4))),
        ("magic", "H"), ("ig_frame", "I"), ("timestamp", "I"), ("last_host_frame", "I"), (None, "4x"),
    ]
    version: int = 3
    database_number: int = 0  # negative: the requested database is not available
    ig_status: int = 0  # 0 = normal; otherwise an IG error code
    ig_mode: int = 0  # 0 reset/standby, 1 operate, 2 debug, 3 offline
    timestamp_valid: bool = True
    earth_model: bool = False  # False: WGS 84
    minor_version: int = 3
    magic: int = MAGIC
    ig_frame: int = 0
    timestamp: int = 0  # 10 µs ticks of the IG's sim_time
    last_host_frame: int = 0

    def check(self) -> None:
        if self.version != 3:
            raise Malformed("version", f"CIGI major version {self.version}")


@dataclass
class HatHotResponse(Packet):
    ID: ClassVar[int] = 102
    SIZE: ClassVar[int] = 16
    NAME: ClassVar[str] = "HAT/HOT Response"
    LAYOUT: ClassVar[list] = [
        ("request_id", "H"), (None, B, (("valid", 0, 1), ("response_type", 1, 1), ("host_frame_lsn", 4, 4))),
        (None, "3x"), ("height", "d"),
    ]
    request_id: int = 0
    valid: bool = False
    response_type: int = 0  # 0 HAT, 1 HOT
    host_frame_lsn: int = 0  # least significant nibble of the host frame the answer belongs to
    height: float = 0.0  # m


@dataclass
class HatHotExtendedResponse(Packet):
    ID: ClassVar[int] = 103
    SIZE: ClassVar[int] = 40
    NAME: ClassVar[str] = "HAT/HOT Extended Response"
    LAYOUT: ClassVar[list] = [
        ("request_id", "H"), (None, B, (("valid", 0, 1), ("host_frame_lsn", 4, 4))), (None, "3x"),
        ("hat", "d"), ("hot", "d"), ("material_code", "I"), ("normal_azimuth", "f"), ("normal_elevation", "f"),
        (None, "4x"),
    ]
    request_id: int = 0
    valid: bool = False
    host_frame_lsn: int = 0
    hat: float = 0.0  # m above the surface
    hot: float = 0.0  # m, surface height above MSL
    material_code: int = 0  # this IG: 1 sea, 2 ground, 3 entity
    normal_azimuth: float = 0.0  # deg clockwise from north
    normal_elevation: float = 90.0  # deg above the horizontal


@dataclass
class LosResponse(Packet):
    ID: ClassVar[int] = 104
    SIZE: ClassVar[int] = 16
    NAME: ClassVar[str] = "Line of Sight Response"
    LAYOUT: ClassVar[list] = [
        ("request_id", "H"),
        (None, B, (("valid", 0, 1), ("entity_valid", 1, 1), ("visible", 2, 1), ("host_frame_lsn", 4, 4))),
        ("count", "B"), ("entity_id", "H"), ("range", "d"),
    ]
    request_id: int = 0
    valid: bool = False  # an intersection was found
    entity_valid: bool = False  # it is with entity_id
    visible: bool = True  # the segment reached its end unobstructed
    host_frame_lsn: int = 0
    count: int = 1
    entity_id: int = 0
    range: float = 0.0  # m from the source to the intersection


IG_PACKETS: dict[int, type[Packet]] = {cls.ID: cls for cls in (
    StartOfFrame, HatHotResponse, HatHotExtendedResponse, LosResponse)}
