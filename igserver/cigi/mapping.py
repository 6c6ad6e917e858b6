"""One host message -> one scene patch (docs/cigi.md has the table).

``map_message`` reads the packets in order against the current scene and a copy of the session, and
returns a ``Plan``: the patch (validated whole by the caller, like a protocol v1 PATCH), the session to
keep if it is accepted, and the queries to answer afterwards. Packets that refer to what does not exist
(an entity number never created) make the whole message malformed; packets this IG reads but does not
render (regional weather, sun/moon enables) are kept in the session and counted in ``not_rendered``.
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Callable

from ..scene.model import Scene
from . import environment, views
from .components import component
from .codec import Malformed, Packet
from .datagram import Message
from ..render.camera import body_to_world
from .geo import LocalFrame, angles, cigi_body
from .packets_host import (ArticulatedPartControl, ComponentControl, ConformalClampedEntityControl,
                           EntityControl, HatHotRequest, IGControl, LosSegmentRequest, LosVectorRequest,
                           RateControl, ShortArticulatedPartControl, ShortComponentControl, ViewControl,
                           ViewDefinition)
from .session import DATABASE_NOT_AVAILABLE, ENTITY_PREFIX, CigiEntity, Session, ViewAttachment, entity_id, owned_by
from .types import TypeMap

ATTITUDE_KEYS = ("heading", "pitch", "roll")


@dataclass
class Plan:
    patch: dict
    session: Session
    queries: list[Packet] = field(default_factory=list)
    not_rendered: Counter = field(default_factory=Counter)  # what was read and kept, but not drawn
    skipped: Counter = field(default_factory=Counter)  # honoured packet types with unsupported contents
    ig_mode: int = 1
    replaced: bool = False  # a database load replaced the whole scene
    answers_to: tuple | None = None  # (scene, session) the queries are answered against, once accepted


class Work:
    """The lists and sections of the scene a message changes, as plain trees (the wire form of a patch)."""

    def __init__(self, scene: Scene, session: Session, types: TypeMap, load_scene: Callable[[str], Scene] | None,
                 tree: dict | None = None):
        # ``tree``: scene.model_dump(mode="json") when the caller has it (read here, never changed in place)
        self.tree = tree if tree is not None else scene.model_dump(mode="json")
        self.session = session
        self.types = types
        self.load_scene = load_scene
        self.frame = LocalFrame.of(scene.location)
        self.sim_time = scene.time.sim_time
        self.patch: dict[str, Any] = {}
        self.plan = Plan(self.patch, session)
        self.lists = {name: {item["id"]: item for item in self.tree[name]} for name in ("entities", "effects", "lights")}
        self.changed_lists: set[str] = set()
        self.moved = False  # an entity pose changed: children, effects, lights and the camera follow
        self.views_changed = False  # a view was defined or turned: the channels follow (views.py)

    def set(self, section: str, key: str, value: Any, sub: str | None = None) -> None:
        node = self.patch.setdefault(section, {})
        if sub is not None:
            node = node.setdefault(sub, {})
        node[key] = value

    def item(self, kind: str, item_id: str) -> dict | None:
        return self.lists[kind].get(item_id)

    def put(self, kind: str, item: dict) -> None:
        self.lists[kind][item["id"]] = item
        self.changed_lists.add(kind)

    def drop(self, kind: str, keep: Callable[[str], bool]) -> None:
        before = len(self.lists[kind])
        self.lists[kind] = {k: v for k, v in self.lists[kind].items() if keep(k)}
        if len(self.lists[kind]) != before:
            self.changed_lists.add(kind)

    def entity(self, number: int, what: str) -> CigiEntity:
        entity = self.session.entities.get(number)
        if entity is None or self.item("entities", entity_id(number)) is None:
            raise Malformed("unknown_entity", f"{what} refers to entity {number}, which does not exist")
        return self.session.touch(number)


# -- IG Control -----------------------------------------------------------------------------------------

def ig_control(work: Work, p: IGControl, sync_setting: bool) -> bool:
    """Frame counters, timestamp, mode, database. Returns False when the rest of the message is to be
    ignored (the host asked for reset/standby or offline maintenance)."""
    session = work.session
    session.host_frame = p.host_frame
    session.ig_mode = p.ig_mode
    work.plan.ig_mode = p.ig_mode
    if p.database_number and p.database_number != session.database:
        load_database(work, p.database_number)
    session.sync = sync_setting or p.timestamp_valid
    work.patch["host_frame"] = p.host_frame
    if session.sync:
        work.set("time", "sim_time", session.sim_time_of(p.timestamp))
    if p.ig_mode == 0:  # reset/standby: everything CIGI made goes, the rest of the message is not applied
        for kind in work.lists:
            work.drop(kind, lambda item_id: not item_id.startswith(ENTITY_PREFIX))
        session.entities.clear()
        session.view = None
        views.drop_views(work)
        session.regions.clear()
        session.regional.clear()
        return False
    return p.ig_mode != 3


def load_database(work: Work, number: int) -> None:
    name = work.types.database(number)
    session = work.session
    if name is None or work.load_scene is None:
        session.database_status = DATABASE_NOT_AVAILABLE
        return
    scene = work.load_scene(name)
    keep_camera_size = {k: work.tree["camera"][k] for k in ("width", "height")}
    tree = scene.model_dump(mode="json")
    tree["camera"].update(keep_camera_size)
    tree["time"]["sim_time"] = work.sim_time
    work.tree = tree
    work.patch.clear()
    work.patch.update(tree)
    work.lists = {name: {item["id"]: item for item in tree[name]} for name in ("entities", "effects", "lights")}
    work.changed_lists.update(work.lists)
    work.frame = LocalFrame.of(scene.location)
    session.entities.clear()
    session.view = None
    session.views.clear()  # the database's scene brings its own channels
    session.database = number
    session.database_status = -number  # loading: the engine reports it loaded once its frames are ready
    work.plan.replaced = True


# -- entities -------------------------------------------------------------------------------------------

def entity_control(work: Work, p: EntityControl) -> None:
    session = work.session
    number, key = p.entity_id, entity_id(p.entity_id)
    if p.entity_state == 2:  # destroyed: with everything attached to it, and its effects and lights
        if number in session.entities:
            doomed = session.descendants(number)
            for n in doomed:
                session.entities.pop(n, None)
            doomed_ids = {entity_id(n) for n in doomed}
            work.drop("entities", lambda i: i not in doomed_ids)
            for kind in ("effects", "lights"):
                work.drop(kind, lambda i: not any(owned_by(i, n) for n in doomed))
            if session.view is not None and session.view.entity in doomed:
                session.view = None
        return
    parent = p.parent_id if p.attach_state else None
    if parent is not None:
        if parent == number or session.would_cycle(number, parent):
            raise Malformed("out_of_range", f"entity {number} cannot be attached to {parent} (a cycle)")
        work.entity(parent, f"entity {number}'s attachment")
        position = (p.lat, p.lon, p.alt)  # CIGI body offsets from the parent
    else:
        position = work.frame.to_enu(p.lat, p.lon, p.alt)
    previous = session.entities.get(number)
    kind = work.types.entity_type(p.entity_type)
    entry = CigiEntity(number, p.entity_type, parent, position, (p.yaw, p.pitch, p.roll),
                       updated_at=work.sim_time)
    if previous is not None and previous.entity_type == p.entity_type:
        entry.velocity, entry.angular_rate = previous.velocity, previous.angular_rate
    session.entities[number] = entry
    item = work.item("entities", key)
    if item is None or previous is None or previous.entity_type != p.entity_type:
        item = {"id": key, "model": kind.model, "scale": list(kind.scale), "parts": {}}
    item = dict(item, visible=p.entity_state == 1)
    work.put("entities", item)
    work.moved = True


def conformal_clamped(work: Work, p: ConformalClampedEntityControl) -> None:
    """Lat/lon/yaw of an entity kept on the surface: z is the ground or the mean sea level."""
    entity = work.entity(p.entity_id, "Conformal Clamped Entity Control")
    x, y, _ = work.frame.to_enu(p.lat, p.lon, 0.0)
    surface = work.tree["ocean"]["level"] if work.tree["ocean"]["enabled"] else work.tree["ground"]["level"]
    entity.parent = None
    entity.position = (x, y, surface)
    entity.attitude = (p.yaw, 0.0, 0.0)
    entity.updated_at = work.sim_time
    work.moved = True


def rate_control(work: Work, p: RateControl) -> None:
    entity = work.entity(p.entity_id, "Rate Control")
    if p.apply_to_part:
        work.plan.skipped["rate_control_part"] += 1
        return
    if p.local:  # body axes (forward, right, down) -> ENU through the entity's attitude now
        velocity = work.session.world_pose(p.entity_id)[1] @ cigi_body(p.x_rate, p.y_rate, p.z_rate)
        entity.velocity = tuple(float(v) for v in velocity)
    else:  # world axes: x north, y east, z down
        entity.velocity = (p.y_rate, p.x_rate, -p.z_rate)
    entity.angular_rate = (p.yaw_rate, p.pitch_rate, p.roll_rate)
    if not any(entity.velocity) and not any(entity.angular_rate):
        entity.velocity = None


# -- articulated parts ----------------------------------------------------------------------------------

def _part(work: Work, number: int, part_id: int) -> tuple[dict, str] | None:
    entity = work.entity(number, "Articulated Part Control")
    name = work.types.entity_type(entity.entity_type).parts.get(str(part_id))
    if name is None:
        work.plan.skipped["unmapped_part"] += 1
        return None
    item = dict(work.item("entities", entity_id(number)))
    item["parts"] = dict(item.get("parts") or {})
    pose = dict(item["parts"].get(name) or {"heading": 0.0, "pitch": 0.0, "roll": 0.0, "offset": [0.0, 0.0, 0.0]})
    pose["offset"] = list(pose.get("offset", [0.0, 0.0, 0.0]))
    item["parts"][name] = pose
    return item, name


# DOF select -> (pose key, offset index or None, sign): CIGI x forward/y right/z down -> part offset
# (x starboard, y forward, z up); yaw -> heading
DOF = {1: ("offset", 1, 1.0), 2: ("offset", 0, 1.0), 3: ("offset", 2, -1.0),
       4: ("heading", None, 1.0), 5: ("pitch", None, 1.0), 6: ("roll", None, 1.0)}


def _set_dof(pose: dict, select: int, value: float) -> None:
    key, index, sign = DOF[select]
    if index is None:
        pose[key] = value
    else:
        pose[key][index] = sign * value


def articulated_part(work: Work, p: ArticulatedPartControl) -> None:
    found = _part(work, p.entity_id, p.part_id)
    if found is None:
        return
    item, name = found
    pose = item["parts"][name]
    for enabled, select, value in ((p.x_enable, 1, p.x), (p.y_enable, 2, p.y), (p.z_enable, 3, p.z),
                                   (p.yaw_enable, 4, p.yaw), (p.pitch_enable, 5, p.pitch),
                                   (p.roll_enable, 6, p.roll)):
        if enabled:
            _set_dof(pose, select, value)
    work.put("entities", item)


def short_articulated_part(work: Work, p: ShortArticulatedPartControl) -> None:
    for part_id, select, value in ((p.part_id1, p.dof_select1, p.dof1), (p.part_id2, p.dof_select2, p.dof2)):
        if select == 0:
            continue
        found = _part(work, p.entity_id, part_id)
        if found is not None:
            item, name = found
            _set_dof(item["parts"][name], select, value)
            work.put("entities", item)


# -- the eyepoint ---------------------------------------------------------------------------------------

def view_control(work: Work, p: ViewControl) -> None:
    if p.view_id != 0:  # another view: a channel of the same eyepoint
        views.view_control(work, p)
        return
    work.entity(p.entity_id, "View Control")
    view = work.session.view
    view = ViewAttachment(p.entity_id) if view is None or view.entity != p.entity_id else dataclasses.replace(view)
    ox, oy, oz = view.offset
    yaw, pitch, roll = view.attitude
    view.offset = (p.x if p.x_enable else ox, p.y if p.y_enable else oy, p.z if p.z_enable else oz)
    view.attitude = (p.yaw if p.yaw_enable else yaw, p.pitch if p.pitch_enable else pitch,
                     p.roll if p.roll_enable else roll)
    work.session.view = view
    work.moved = True
    work.views_changed = True  # the other views' offsets are from this one


def view_definition(work: Work, p: ViewDefinition) -> None:
    if p.view_id != 0:
        views.view_definition(work, p)
        return
    work.views_changed = True  # channel "0" has the camera's frustum
    if p.projection != 0:
        work.plan.skipped["orthographic_view"] += 1
    camera = work.tree["camera"]
    frustum = dict(work.patch.get("camera", {}).get("frustum") or camera.get("frustum")
                   or {"left": -30.0, "right": 30.0, "bottom": -20.0, "top": 20.0})
    for name in ("left", "right", "top", "bottom"):
        if getattr(p, f"{name}_enable"):
            frustum[name] = getattr(p, name)
    work.set("camera", "frustum", frustum)
    if p.near_enable:
        work.set("camera", "near", p.near)
    if p.far_enable:
        work.set("camera", "far", p.far)


# -- after the packets: poses follow the session --------------------------------------------------------

def place_everything(work: Work) -> None:
    """Entity poses from the session (parents carry children), effects and lights at their entities,
    the camera at its eyepoint."""
    session = work.session
    poses = {n: session.world_attitude(n) for n in session.entities}
    for number, (position, attitude) in poses.items():
        item = work.item("entities", entity_id(number))
        if item is None:
            continue
        update = {"position": list(position), **dict(zip(ATTITUDE_KEYS, attitude))}
        if any(item.get(k) != v for k, v in update.items()):
            work.put("entities", dict(item, **update))
    for kind in ("effects", "lights"):
        for item_id, item in list(work.lists[kind].items()):
            number = _owner(item_id)
            if number is None or number not in poses:
                continue
            x, y, z = poses[number][0]
            if kind == "lights":
                z += session.lights.get(item_id, {}).get("height", 0.0)
            if item.get("position") != [x, y, z]:
                work.put(kind, dict(item, position=[x, y, z]))
    view = session.view
    if view is not None and view.entity in session.entities:
        origin, matrix = session.world_pose(view.entity)
        eye = origin + matrix @ cigi_body(*view.offset)
        heading, pitch, roll = angles(matrix @ body_to_world(*view.attitude))
        for key, value in (("position", [float(v) for v in eye]), ("heading", heading), ("pitch", pitch),
                           ("roll", roll)):
            work.set("camera", key, value)


def _owner(item_id: str) -> int | None:
    if not item_id.startswith(ENTITY_PREFIX):
        return None
    number = item_id[len(ENTITY_PREFIX):].split(".", 1)[0]
    return int(number) if number.isdigit() else None


HANDLERS: dict[type, Callable[[Work, Any], None]] = {
    EntityControl: entity_control, ConformalClampedEntityControl: conformal_clamped, RateControl: rate_control,
    ArticulatedPartControl: articulated_part, ShortArticulatedPartControl: short_articulated_part,
    ComponentControl: component, ShortComponentControl: component, ViewControl: view_control,
    ViewDefinition: view_definition, **environment.HANDLERS,
}
QUERIES = (HatHotRequest, LosSegmentRequest, LosVectorRequest)


def map_message(message: Message, scene: Scene, session: Session, types: TypeMap, sync: bool = False,
                load_scene: Callable[[str], Scene] | None = None, tree: dict | None = None) -> Plan:
    """The plan of one parsed host message against ``scene`` (``session`` is not modified; ``tree``: the
    scene as a JSON tree, when the caller has it)."""
    work = Work(scene, session.copy(), types, load_scene, tree)
    packets = iter(message.packets)
    if ig_control(work, next(packets), sync):
        for packet in packets:
            if isinstance(packet, QUERIES):
                work.plan.queries.append(packet)
                continue
            HANDLERS[type(packet)](work, packet)
    if work.moved:
        place_everything(work)
    if work.views_changed:
        views.place_views(work)
    for kind in work.changed_lists:
        work.patch[kind] = list(work.lists[kind].values())
    return work.plan
