"""What CIGI knows beyond the scene: entity numbers, attachments, rates, the eyepoint's attachment,
regional weather, frame counters. The scene holds the result (``cigi.N`` entities, the camera); this
holds how the host described it, so that a parent's move carries its children and the camera along.

A session is copied before a datagram is mapped and replaced only when the datagram's patch is
accepted: a rejected datagram leaves it as it was, like the scene.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..render.camera import body_to_world
from .geo import angles, cigi_body

ENTITY_PREFIX = "cigi."


def entity_id(number: int) -> str:
    return f"{ENTITY_PREFIX}{number}"


def owned_by(item_id: str, number: int) -> bool:
    """An effect or light a Component Control made for entity ``number`` (``cigi.N.fxC``, ``cigi.N.lightC``)."""
    return item_id.startswith(f"{ENTITY_PREFIX}{number}.")


@dataclass
class CigiEntity:
    number: int
    entity_type: int
    parent: int | None = None  # attached to this entity number (pose relative to it)
    # ENU m when top level; CIGI body offsets (x forward, y right, z down, m) from the parent when attached
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    attitude: tuple[float, float, float] = (0.0, 0.0, 0.0)  # deg (yaw, pitch, roll), relative when attached
    velocity: tuple[float, float, float] | None = None  # m/s, ENU (Rate Control), top-level entities
    angular_rate: tuple[float, float, float] = (0.0, 0.0, 0.0)  # deg/s (yaw, pitch, roll)
    updated_at: float = 0.0  # s, sim_time of the host's last pose


@dataclass
class ViewAttachment:
    entity: int
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, CIGI body axes of the entity
    attitude: tuple[float, float, float] = (0.0, 0.0, 0.0)  # deg (yaw, pitch, roll) relative to it


@dataclass
class ViewSpec:
    """A view N > 0 as the host defined it (a channel: cigi/views.py)."""

    attitude: tuple[float, float, float] = (0.0, 0.0, 0.0)  # deg (yaw, pitch, roll) relative to its entity
    frustum: dict | None = None  # signed CIGI half-angles {left, right, top, bottom}, deg; None: not defined
    near: float | None = None  # m
    far: float | None = None


DATABASE_NOT_AVAILABLE = -128  # Start of Frame's Database Number for a database the IG cannot load


@dataclass
class Session:
    entities: dict[int, CigiEntity] = field(default_factory=dict)
    view: ViewAttachment | None = None
    views: dict[int, ViewSpec] = field(default_factory=dict)  # views N > 0: channels (replaced, never edited)
    regions: dict[int, dict] = field(default_factory=dict)  # Environmental Region Control, as sent
    regional: dict[str, dict] = field(default_factory=dict)  # weather/sea for a region or entity: not rendered
    lights: dict[str, dict] = field(default_factory=dict)  # light id -> {"intensity" while on, "height"}
    celestial: dict = field(default_factory=dict)  # sun/moon/star enables, star intensity: not rendered
    atmosphere: dict = field(default_factory=dict)  # air temperature, pressure, ...: not rendered
    host_frame: int = 0  # the last host frame received
    ig_mode: int = 1  # the mode the host asked for last
    database: int = 0  # the database number loaded (0 = the scene the server started with)
    # What Start of Frame reports (CIGI 3.3): the database loaded, its negative while it loads, or
    # DATABASE_NOT_AVAILABLE for a number the IG has no scene for.
    database_status: int = 0
    sync: bool = False  # the host's timestamps drive sim_time
    timestamp_wraps: int = 0  # the 32-bit 10 µs timestamp wraps every 11.9 h
    last_timestamp: int | None = None

    def copy(self) -> "Session":
        """A copy whose containers are new: the mapping replaces entries (``touch``), never edits them."""
        return dataclasses.replace(self, entities=dict(self.entities), views=dict(self.views), regions=dict(self.regions),
                                   regional=dict(self.regional), lights=dict(self.lights),
                                   celestial=dict(self.celestial), atmosphere=dict(self.atmosphere))

    def touch(self, number: int) -> CigiEntity:
        """Entity ``number`` as a private copy, ready to change."""
        entity = dataclasses.replace(self.entities[number])
        self.entities[number] = entity
        return entity

    def sim_time_of(self, timestamp: int) -> float:
        """s, the host's timestamp (10 µs ticks) unwrapped past 2^32 (a jump back of over half the range is a wrap)."""
        if self.last_timestamp is not None and timestamp < self.last_timestamp - 2**31:
            self.timestamp_wraps += 1
        self.last_timestamp = timestamp
        return (self.timestamp_wraps * 2**32 + timestamp) * 1e-5

    def world_pose(self, number: int, depth: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(ENU position, body->ENU rotation) of entity ``number`` (through its parents)."""
        entity = self.entities[number]
        own = body_to_world(*entity.attitude)
        if entity.parent is None or entity.parent not in self.entities or depth > 16:
            return np.array(entity.position, dtype=np.float64), own
        parent_position, parent_rotation = self.world_pose(entity.parent, depth + 1)
        return parent_position + parent_rotation @ cigi_body(*entity.position), parent_rotation @ own

    def world_attitude(self, number: int) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(position, (heading, pitch, roll)) of entity ``number`` in the scene's terms."""
        position, matrix = self.world_pose(number)
        return tuple(float(v) for v in position), angles(matrix)

    def descendants(self, number: int) -> list[int]:
        """``number`` and every entity attached to it, however deep."""
        out, frontier = [number], [number]
        while frontier:
            parent = frontier.pop()
            children = [n for n, e in self.entities.items() if e.parent == parent and n not in out]
            out += children
            frontier += children
        return out

    def would_cycle(self, number: int, parent: int) -> bool:
        seen = {number}
        while parent is not None:
            if parent in seen:
                return True
            seen.add(parent)
            entry = self.entities.get(parent)
            parent = entry.parent if entry else None
        return False
