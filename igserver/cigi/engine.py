"""The CIGI side of the IG without sockets: a host datagram in -> the one state changed (or nothing);
a frame start -> the Start of Frame message (with the answers to the queries received since).

Everything runs on the event loop thread, like every other state update, so a REST PATCH and a CIGI
message apply in the order they arrived. Rejected datagrams change neither the scene nor the session.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import replace
from typing import Callable

from ..protocol.metrics import LabelledCounter, MillisecondHistogram, ServiceMetrics
from ..protocol.problems import ProblemError
from ..protocol.state import StateStore
from ..scene.model import Scene
from .codec import BIG, Malformed, Packet
from .datagram import MAX_DATAGRAM, parse
from .mapping import Plan, map_message, place_everything, Work
from .packets_ig import StartOfFrame
from .queries import answer
from .session import DATABASE_NOT_AVAILABLE, Session
from .types import load_type_map

log = logging.getLogger("igserver.cigi")
STANDBY, OPERATE = 0, 1
TICKS_PER_S = 100_000  # CIGI timestamps count 10 µs


class CigiCounters:
    """The CIGI counters in the server's /metrics registry."""

    def __init__(self, metrics: ServiceMetrics):
        r = metrics.registry
        self.datagrams = LabelledCounter("igserver_cigi_datagrams", "CIGI datagrams received, by result "
                                         "(accepted, rejected, dropped: from a sender not allowed)", r, ["result"])
        self.rejected = LabelledCounter("igserver_cigi_rejected", "CIGI datagrams rejected whole, by reason", r,
                                        ["kind"])
        self.unknown = LabelledCounter("igserver_cigi_unknown_packets", "CIGI packets skipped (unknown or "
                                       "unsupported id)", r, ["packet_id"])
        self.packets = LabelledCounter("igserver_cigi_packets", "CIGI packets applied, by packet", r, ["packet"])
        self.not_rendered = LabelledCounter("igserver_cigi_not_rendered", "CIGI contents read and kept but not "
                                            "rendered (regional weather, ...)", r, ["what"])
        self.skipped = LabelledCounter("igserver_cigi_skipped", "CIGI packet contents skipped (an unmapped "
                                       "part, a component class without meaning here, ...)", r, ["what"])
        self.sent = LabelledCounter("igserver_cigi_sent", "CIGI packets sent to the host", r, ["packet"])
        self.sof_delay_ms = MillisecondHistogram("igserver_cigi_sof_delay_seconds",
                                                 "Frame start -> its Start of Frame handed to the socket", r)


class CigiEngine:
    def __init__(self, store: StateStore, metrics: ServiceMetrics | None = None, sync: bool = False,
                 entity_types: str | None = None, load_scene: Callable[[str], Scene] | None = None):
        self.store = store
        self.counters = CigiCounters(metrics or ServiceMetrics())
        self.sync = sync
        self.types = load_type_map(str(entity_types) if entity_types else None)
        self.load_scene = load_scene
        self.session = Session()
        self.ig_frame = 0  # IG frame counter (one per frame start)
        self.pending: deque[Packet] = deque(maxlen=4096)  # answers going out with the next Start of Frame
        self.last_error: str | None = None
        self._logged: set[str] = set()
        self._dumped: tuple[int, dict] | None = None  # (revision, its scene as a JSON tree)
        self._loading: int | None = None  # the state revision a database load made, until it is ready

    # -- host messages
    def handle(self, data: bytes, defer: bool = False) -> Plan | None:
        """Apply one host datagram; returns its plan, or None when it was rejected (counted, logged once per
        kind). Its queries are answered here, or with ``defer`` left to the caller (``answer(plan)``)."""
        try:
            message = parse(data)
            scene = self.store.scene
            plan = map_message(message, scene, self.session, self.types, self.sync, self.load_scene,
                               self._tree(scene))
            scene = self.store.validate_patch(plan.patch)
        except Malformed as exc:
            self._reject(exc.kind, exc.detail)
            return None
        except ProblemError as exc:
            self._reject("validation", exc.detail or str(exc))
            return None
        except ValueError as exc:  # a database scene that would not load
            self._reject("database", str(exc))
            return None
        self.store.set_validated(scene, plan.patch)
        self.session = plan.session
        if plan.replaced:
            self._loading = self.store.revision
        c = self.counters
        c.datagrams.inc(result="accepted")
        for packet_id, count in message.unknown.items():
            c.unknown.inc(count, packet_id=str(packet_id))
        for packet in message.packets:
            c.packets.inc(packet=packet.NAME)
        for what, count in plan.not_rendered.items():
            c.not_rendered.inc(count, what=what)
        for what, count in plan.skipped.items():
            c.skipped.inc(count, what=what)
        if plan.queries:
            plan.answers_to = (self.store.scene, self.session)  # the state the answers are about
            if not defer:
                self.answer(plan)
        return plan

    def answer(self, plan: Plan) -> None:
        """Answer ``plan``'s queries (they go out with the next Start of Frame). Thread-safe: the scene
        and session it reads are snapshots that are replaced, never changed (the listener runs it off the
        event loop: the first query on a new sea builds its spectrum)."""
        scene, session = plan.answers_to
        self.pending.extend(answer(scene, session, self.types, request) for request in plan.queries)

    def _tree(self, scene: Scene) -> dict:
        """``scene`` as a JSON tree, dumped once per state revision (only the clock's sim_time moves)."""
        if self._dumped is None or self._dumped[0] != self.store.revision:
            self._dumped = (self.store.revision, scene.model_dump(mode="json"))
        tree = self._dumped[1]
        return dict(tree, time=dict(tree["time"], sim_time=scene.time.sim_time))

    def _reject(self, kind: str, detail: str) -> None:
        self.counters.datagrams.inc(result="rejected")
        self.counters.rejected.inc(kind=kind)
        self.last_error = f"{kind}: {detail}"
        if kind not in self._logged:  # once per kind: a broken host must not flood the log
            self._logged.add(kind)
            log.warning("CIGI datagram rejected (%s): %s (further '%s' rejections are only counted)",
                        kind, detail, kind)

    # -- frames
    def ig_mode(self, ready: bool) -> int:
        """Standby while the IG cannot render yet (tables precompute) or the host asked for standby."""
        return OPERATE if ready and self.session.ig_mode in (1, 2) else STANDBY

    def database_loaded(self, ready: bool) -> None:
        """A database load ends when a frame of its state (or a later one) has rendered and the IG is
        ready (its programs compiled ahead): Start of Frame then reports the number, not its negative."""
        if self._loading is None or not ready or self.store.rendered_revision < self._loading:
            return
        self._loading = None
        if self.session.database_status < 0 and self.session.database_status != DATABASE_NOT_AVAILABLE:
            self.session = replace(self.session, database_status=self.session.database)

    def start_of_frame(self, ready: bool, sim_time: float | None = None) -> bytes:
        """One IG message: Start of Frame, then as many pending answers as fit in a datagram."""
        self.ig_frame = (self.ig_frame + 1) & 0xFFFFFFFF
        self.database_loaded(ready)
        t = self.store.clock.sim_time() if sim_time is None else sim_time
        sof = StartOfFrame(database_number=self.session.database_status, ig_mode=self.ig_mode(ready),
                           ig_frame=self.ig_frame, timestamp=int(t * TICKS_PER_S) & 0xFFFFFFFF,
                           last_host_frame=self.session.host_frame & 0xFFFFFFFF)
        parts = [sof.encode(BIG)]
        size = sof.SIZE
        self.counters.sent.inc(packet=sof.NAME)
        while self.pending and size + self.pending[0].SIZE <= MAX_DATAGRAM:
            packet = self.pending.popleft()
            parts.append(packet.encode(BIG))
            size += packet.SIZE
            self.counters.sent.inc(packet=packet.NAME)
        return b"".join(parts)

    def extrapolate(self) -> bool:
        """Move entities with a Rate Control on to now (between host frames); True when the state changed."""
        moving = [n for n, e in self.session.entities.items()
                  if e.parent is None and (e.velocity is not None or any(e.angular_rate))]
        if not moving or self.session.sync:
            return False  # in synchronous mode the host's frames are the only clock
        scene = self.store.scene
        work = Work(scene, self.session.copy(), self.types, None)
        for number in moving:
            entity = work.session.touch(number)
            dt = scene.time.sim_time - entity.updated_at
            if entity.velocity is not None:
                entity.position = tuple(p + v * dt for p, v in zip(entity.position, entity.velocity))
            yaw, pitch, roll = (a + r * dt for a, r in zip(entity.attitude, entity.angular_rate))
            entity.attitude = (yaw % 360.0, max(-90.0, min(90.0, pitch)), (roll + 180.0) % 360.0 - 180.0)
        place_everything(work)
        for kind in work.changed_lists:
            work.patch[kind] = list(work.lists[kind].values())
        if not work.patch:
            return False
        try:
            self.store.set_validated(self.store.validate_patch(work.patch), work.patch)
        except ProblemError as exc:  # extrapolated out of the world: stop there
            self._reject("extrapolation", exc.detail or str(exc))
            return False
        return True
