"""HAT/HOT and line-of-sight answers from the scene: the sea (the very maths of
``POST /v1/query/water-height``), the land behind a slope beach (water/land.py, as the sea pass draws
it), the ground plane and entity bounding boxes.

Surfaces at a point (x, y): the sea surface when the ocean is on, the beach's land where it rises above
the sea, the ground plane when it is drawn, and the top of every entity box whose footprint holds the
point. HOT is the highest of those at or below the
query's altitude (the highest overall when all are above it); HAT = altitude - HOT. Material codes in
the extended response: 1 sea, 2 ground (the ground plane, a beach's land), 3 entity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.model import Scene
from ..render.camera import body_to_world
from ..water.land import land_elevation
from .geo import LocalFrame, cigi_body
from .packets_host import HatHotRequest, LosSegmentRequest, LosVectorRequest
from .packets_ig import HatHotExtendedResponse, HatHotResponse, LosResponse
from .session import ENTITY_PREFIX, Session
from .types import TypeMap

SEA, GROUND, ENTITY = 1, 2, 3
UP = np.array([0.0, 0.0, 1.0])
LOS_STEP_M = 2.0  # m between sea samples along a line of sight (the bisection then refines to < 1 mm)
LOS_MAX_SAMPLES = 4096
LAND_NORMAL_STEP_M = 0.5  # central differences of the land's height for its normal
_sea_cache: dict[tuple[int, int], tuple] = {}


def sea_of(scene: Scene):
    """The CPU sea of ``scene`` (built once per ocean/weather object: building it sets up the spectrum)."""
    key = (id(scene.ocean), id(scene.weather))
    hit = _sea_cache.get(key)
    if hit is None:
        from ..water import sea_surface

        if len(_sea_cache) > 8:
            _sea_cache.clear()
        hit = (scene.ocean, scene.weather, sea_surface(scene.ocean, scene.weather))  # refs keep the ids valid
        _sea_cache[key] = hit
    return hit[2]


def sea_height(scene: Scene, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(heights ENU z, normals) of the sea at ``points`` (n, 2) at the scene's sim_time."""
    result = sea_of(scene).query(np.asarray(points, dtype=np.float64).reshape(-1, 2), scene.time.sim_time)
    return np.asarray(result["height"]) + scene.ocean.level, np.asarray(result["normal"])


def land_height(scene: Scene, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(heights ENU z, normals) of the land behind a slope beach at ``points`` (n, 2) (water/land.py,
    what the sea pass draws there); NaN where the bathymetry models no land."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    bathy = scene.ocean.bathymetry
    z = land_elevation(bathy, points) + scene.ocean.level
    h = LAND_NORMAL_STEP_M
    dx = land_elevation(bathy, points + [h, 0.0]) - land_elevation(bathy, points - [h, 0.0])
    dy = land_elevation(bathy, points + [0.0, h]) - land_elevation(bathy, points - [0.0, h])
    normal = np.stack([-dx, -dy, np.full_like(dx, 2.0 * h)], axis=-1)
    return z, normal / np.linalg.norm(normal, axis=-1, keepdims=True)


def surface_height(scene: Scene, points: np.ndarray) -> np.ndarray:
    """ENU z of what a line of sight meets at ``points`` (n, 2): the sea, or the land where it rises above it."""
    sea = sea_height(scene, points)[0]
    land = land_height(scene, points)[0]
    return np.where(land > sea, land, sea)


@dataclass
class Box:
    """An entity's bounding box: base centre ``origin``, body->ENU ``matrix``, ``size`` (w, l, h) m."""

    number: int | None  # the CIGI entity number, None for entities made over REST
    origin: np.ndarray
    matrix: np.ndarray
    size: tuple[float, float, float]

    def local(self, point: np.ndarray) -> np.ndarray:
        return self.matrix.T @ (point - self.origin)

    def contains(self, point: np.ndarray) -> bool:
        x, y, z = self.local(point)
        w, l, h = self.size
        return abs(x) <= w / 2 and abs(y) <= l / 2 and 0.0 <= z <= h

    def top_at(self, x: float, y: float) -> float | None:
        """ENU z of the box's top above (x, y), or None outside its footprint (attitude: heading only)."""
        c, s = math.cos(math.radians(self.matrix_heading)), math.sin(math.radians(self.matrix_heading))
        dx, dy = x - self.origin[0], y - self.origin[1]
        across, along = dx * c - dy * s, dx * s + dy * c
        if abs(across) <= self.size[0] / 2 and abs(along) <= self.size[1] / 2:
            return float(self.origin[2] + self.size[2])
        return None

    @property
    def matrix_heading(self) -> float:
        forward = self.matrix[:, 1]
        return math.degrees(math.atan2(forward[0], forward[1]))

    def hit(self, start: np.ndarray, end: np.ndarray) -> float | None:
        """Fraction t in [0, 1] along start->end where the segment enters the box (slab test)."""
        a, b = self.local(start), self.local(end)
        d = b - a
        w, l, h = self.size
        lo, hi = np.array([-w / 2, -l / 2, 0.0]), np.array([w / 2, l / 2, h])
        t0, t1 = 0.0, 1.0
        for axis in range(3):
            if abs(d[axis]) < 1e-12:
                if not lo[axis] <= a[axis] <= hi[axis]:
                    return None
                continue
            ta, tb = sorted(((lo[axis] - a[axis]) / d[axis], (hi[axis] - a[axis]) / d[axis]))
            t0, t1 = max(t0, ta), min(t1, tb)
            if t0 > t1:
                return None
        return t0


def boxes(scene: Scene, session: Session, types: TypeMap) -> list[Box]:
    out = []
    for entity in scene.entities:
        if not entity.visible:
            continue
        number = None
        if entity.id.startswith(ENTITY_PREFIX) and entity.id[len(ENTITY_PREFIX):].isdigit():
            number = int(entity.id[len(ENTITY_PREFIX):])
        if number is not None and number in session.entities:
            size = types.entity_type(session.entities[number].entity_type).bounds()
        elif entity.model == "box":
            size = entity.scale
        else:
            continue  # a model made over REST: its bounds are not known here
        out.append(Box(number, np.array(entity.position, dtype=np.float64),
                       body_to_world(entity.heading, entity.pitch, entity.roll), tuple(size)))
    return out


def _ground_shows(scene: Scene) -> bool:
    """The ground plane is a surface unless it lies under the sea (then it is the sea floor)."""
    return scene.ground.enabled and not (scene.ocean.enabled and scene.ground.level < scene.ocean.level)


def surfaces(scene: Scene, all_boxes: list[Box], x: float, y: float) -> list[tuple[float, np.ndarray, int]]:
    """(height, normal, material) of every surface above or below (x, y)."""
    found = []
    if scene.ocean.enabled:
        height, normal = sea_height(scene, np.array([[x, y]]))
        found.append((float(height[0]), normal[0], SEA))
        land, land_normal = land_height(scene, np.array([[x, y]]))
        if land[0] > height[0]:  # dry land behind a beach (NaN elsewhere: never above)
            found.append((float(land[0]), land_normal[0], GROUND))
    if _ground_shows(scene):
        found.append((scene.ground.level, UP, GROUND))
    for box in all_boxes:
        top = box.top_at(x, y)
        if top is not None:
            found.append((top, box.matrix[:, 2], ENTITY))
    return found


def request_point(frame: LocalFrame, session: Session, entity: int, relative: bool,
                  lat: float, lon: float, alt: float) -> np.ndarray | None:
    """ENU of a request's point: geodetic, or CIGI body offsets from an entity (None: no such entity)."""
    if not relative:
        return np.array(frame.to_enu(lat, lon, alt))
    if entity not in session.entities:
        return None
    origin, matrix = session.world_pose(entity)
    return origin + matrix @ cigi_body(lat, lon, alt)


def hat_hot(scene: Scene, session: Session, types: TypeMap, p: HatHotRequest):
    frame = LocalFrame.of(scene.location)
    point = request_point(frame, session, p.entity_id, p.entity_relative, p.lat, p.lon, p.alt)
    lsn = session.host_frame & 0xF
    # relative to an entity (the ownship), the entity's own box is not a surface under it
    own = p.entity_id if p.entity_relative else None
    others = [b for b in boxes(scene, session, types) if b.number is None or b.number != own]
    found = [] if point is None else surfaces(scene, others, point[0], point[1])
    if not found:
        if p.request_type == 2:
            return HatHotExtendedResponse(request_id=p.request_id, valid=False, host_frame_lsn=lsn)
        return HatHotResponse(request_id=p.request_id, valid=False, response_type=p.request_type & 1,
                              host_frame_lsn=lsn)
    below = [s for s in found if s[0] <= point[2]]
    height, normal, material = max(below or found, key=lambda s: s[0])
    hot = height + frame.alt0  # above MSL, as the host's altitudes are
    hat = float(point[2] - height)
    if p.request_type == 2:
        azimuth = math.degrees(math.atan2(normal[0], normal[1])) % 360.0
        elevation = math.degrees(math.asin(max(-1.0, min(1.0, float(normal[2])))))
        return HatHotExtendedResponse(request_id=p.request_id, valid=True, host_frame_lsn=lsn, hat=hat, hot=hot,
                                      material_code=material, normal_azimuth=azimuth, normal_elevation=elevation)
    return HatHotResponse(request_id=p.request_id, valid=True, response_type=p.request_type,
                          host_frame_lsn=lsn, height=hat if p.request_type == 0 else hot)


def _sea_hit(scene: Scene, start: np.ndarray, end: np.ndarray) -> float | None:
    """First t in [0, 1] where the segment goes below the sea surface (or a beach's land): samples,
    then bisection."""
    length = float(np.linalg.norm(end - start))
    n = int(min(max(length / LOS_STEP_M, 16), LOS_MAX_SAMPLES)) + 1
    t = np.linspace(0.0, 1.0, n)
    points = start[None, :] + t[:, None] * (end - start)[None, :]
    above = points[:, 2] - surface_height(scene, points[:, :2])
    under = np.nonzero(above <= 0.0)[0]
    if under.size == 0:
        return None
    i = int(under[0])
    if i == 0:
        return 0.0
    lo, hi = t[i - 1], t[i]
    for _ in range(40):  # 2^-40 of the segment: far below a millimetre
        mid = 0.5 * (lo + hi)
        p = start + mid * (end - start)
        if p[2] - surface_height(scene, p[None, :2])[0] <= 0.0:
            hi = mid
        else:
            lo = mid
    return hi


def line_of_sight(scene: Scene, session: Session, types: TypeMap, start: np.ndarray, end: np.ndarray):
    """(t of the first obstruction or None, entity number hit or None) along start->end."""
    hits: list[tuple[float, int | None]] = []
    # the segment's ends on both sides of the ground (or on it), by their signs: a product of two heights
    # near the float64 limit would overflow
    if _ground_shows(scene) and np.sign(start[2] - scene.ground.level) * np.sign(end[2] - scene.ground.level) <= 0.0 \
            and start[2] != end[2]:
        hits.append(((start[2] - scene.ground.level) / (start[2] - end[2]), None))
    elif _ground_shows(scene) and start[2] == end[2] == scene.ground.level:
        hits.append((0.0, None))
    if scene.ocean.enabled:
        t = _sea_hit(scene, start, end)
        if t is not None:
            hits.append((t, None))
    for box in boxes(scene, session, types):
        if box.contains(start):
            continue  # the requesting entity's own box (a sensor inside its hull sees out)
        t = box.hit(start, end)
        if t is not None:
            hits.append((t, box.number))
    return min(hits, key=lambda h: h[0]) if hits else (None, None)


def _los_response(p, session: Session, start, end, origin, hit) -> LosResponse:
    t, number = hit
    lsn = session.host_frame & 0xF
    if t is None:
        return LosResponse(request_id=p.request_id, valid=False, visible=True, host_frame_lsn=lsn)
    point = start + t * (end - start)
    return LosResponse(request_id=p.request_id, valid=True, visible=False, host_frame_lsn=lsn,
                       entity_valid=number is not None, entity_id=number or 0,
                       range=float(np.linalg.norm(point - origin)))


def los_segment(scene: Scene, session: Session, types: TypeMap, p: LosSegmentRequest) -> LosResponse:
    frame = LocalFrame.of(scene.location)
    start = request_point(frame, session, p.entity_id, p.source_entity_relative,
                          p.source_lat, p.source_lon, p.source_alt)
    target = p.destination_entity_id if p.destination_entity_valid else p.entity_id
    end = request_point(frame, session, target, p.destination_entity_relative,
                        p.destination_lat, p.destination_lon, p.destination_alt)
    if start is None or end is None:
        return LosResponse(request_id=p.request_id, valid=False, host_frame_lsn=session.host_frame & 0xF)
    return _los_response(p, session, start, end, start, line_of_sight(scene, session, types, start, end))


def los_vector(scene: Scene, session: Session, types: TypeMap, p: LosVectorRequest) -> LosResponse:
    frame = LocalFrame.of(scene.location)
    source = request_point(frame, session, p.entity_id, p.source_entity_relative,
                           p.source_lat, p.source_lon, p.source_alt)
    if source is None:
        return LosResponse(request_id=p.request_id, valid=False, host_frame_lsn=session.host_frame & 0xF)
    az, el = math.radians(p.azimuth), math.radians(p.elevation)
    direction = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    start, end = source + p.min_range * direction, source + p.max_range * direction
    return _los_response(p, session, start, end, source, line_of_sight(scene, session, types, start, end))


def answer(scene: Scene, session: Session, types: TypeMap, request):
    if isinstance(request, HatHotRequest):
        return hat_hot(scene, session, types, request)
    if isinstance(request, LosSegmentRequest):
        return los_segment(scene, session, types, request)
    return los_vector(scene, session, types, request)
