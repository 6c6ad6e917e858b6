"""The CIGI UDP endpoint inside the serve process (asyncio ``DatagramProtocol``).

Host messages are applied on the event loop as they arrive (the same thread as REST, so both apply in
arrival order) and show in the next frame. At every frame start a Start of Frame goes to the host,
carrying the IG frame counter, the last host frame and the IG mode: Standby until the render process
has drawn its first frame (tables precompute), Operate once frames flow. While no frames start (the IG
starting, or idle without a viewer) a Standby/Operate SOF still goes out at ``HEARTBEAT_S``, so a host
always hears the IG. While a host is talking, the listener keeps the frame pump running.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import time

from .engine import CigiEngine

log = logging.getLogger("igserver.cigi")
HEARTBEAT_S = 0.1  # s, SOF rate while no frames start
HOST_TIMEOUT_S = 5.0  # s without a host message: stop keeping the frame pump running for it


def _address(text: str) -> str:
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        return text


class CigiListener(asyncio.DatagramProtocol):
    def __init__(self, runtime, engine: CigiEngine):
        self.runtime = runtime
        self.engine = engine
        settings = runtime.settings
        self.allow = {_address(a) for a in settings.cigi_allow}
        self.fixed_host = settings.cigi_host
        self.host_port = settings.cigi_host_port
        self.host: tuple[str, int] | None = (settings.cigi_host, self.host_port) if settings.cigi_host else None
        self.transport: asyncio.DatagramTransport | None = None
        self.last_message = 0.0  # monotonic s of the last accepted host message
        self.last_sof = 0.0
        self._subscription = None
        self._heartbeat: asyncio.Task | None = None
        self.capture = None  # a PcapWriter-like object with add(payload, src, dst): tests and tools
        # the IG's readiness as of the last heartbeat (<= HEARTBEAT_S old): asking the render process at a
        # frame start (it reads /proc) would cost the SOF its sub-millisecond start
        self.ready = False

    # -- asyncio
    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        sender = _address(addr[0])
        if self.allow and sender not in self.allow:
            self.engine.counters.datagrams.inc(result="dropped")
            return
        if self.capture is not None:
            self.capture.add(data, (addr[0], addr[1]), self.transport.get_extra_info("sockname")[:2])
        try:
            plan = self.engine.handle(data, defer=True)
        except Exception:  # never let a datagram stop the listener
            log.exception("CIGI datagram could not be handled")
            self.engine.counters.datagrams.inc(result="rejected")
            self.engine.counters.rejected.inc(kind="internal")
            return
        if plan is None:
            return
        if plan.replaced and self.runtime.compile_ahead(self.engine.store.scene):
            self.ready = False  # Standby from the next Start of Frame, not the next heartbeat
        if not self.fixed_host:
            self.host = (addr[0], self.host_port)
        self.last_message = time.monotonic()
        self._keep_frames_flowing()
        if plan.queries:  # numpy work (a new sea builds its spectrum) off the event loop, as REST queries
            asyncio.get_running_loop().run_in_executor(None, self._answer, plan)

    def _answer(self, plan) -> None:
        try:
            self.engine.answer(plan)
        except Exception:  # a query must not take the listener down
            log.exception("CIGI query could not be answered")

    def error_received(self, exc) -> None:  # ICMP port unreachable from a host not listening yet
        log.debug("CIGI socket: %s", exc)

    # -- frames
    def frame_started(self, *_args) -> None:
        """Called at each frame start (its state chosen, the render not yet submitted): SOF, then extrapolate."""
        t0 = time.perf_counter()
        self._send_sof(self.ready)
        self.engine.counters.sof_delay_ms.observe((time.perf_counter() - t0) * 1e3)
        # entities with a Rate Control move on for the frames after this one (this one's state is chosen)
        self.engine.extrapolate()

    def _send_sof(self, ready: bool) -> None:
        self.last_sof = time.monotonic()
        if self.host is None or self.transport is None:  # nobody to tell yet: the frame still counts
            self.engine.ig_frame = (self.engine.ig_frame + 1) & 0xFFFFFFFF
            return
        message = self.engine.start_of_frame(ready)
        self.transport.sendto(message, self.host)
        if self.capture is not None:
            self.capture.add(message, self.transport.get_extra_info("sockname")[:2], self.host)

    def _keep_frames_flowing(self) -> None:
        """A talking host gets frames (and so SOFs) as a viewer does: hold a pump subscription."""
        if self._subscription is None:
            self._subscription = self.runtime.pump.subscription()
            self._subscription.__enter__()

    async def heartbeat(self) -> None:
        while True:
            await asyncio.sleep(HEARTBEAT_S)
            now = time.monotonic()
            if self._subscription is not None and now - self.last_message > HOST_TIMEOUT_S:
                self._subscription.__exit__(None, None, None)
                self._subscription = None
            self.ready = ready = self.runtime.ready()
            # no frame started lately: tell the host anyway (Standby while precomputing), but not while a
            # frame renders (its SOF went out; a synchronous host would run ahead of the frames)
            if now - self.last_sof >= HEARTBEAT_S and (not ready or self.runtime.gateway.busy_since is None):
                self._send_sof(ready)

    def close(self) -> None:
        if self._heartbeat is not None:
            self._heartbeat.cancel()
        if self._subscription is not None:
            self._subscription.__exit__(None, None, None)
            self._subscription = None
        if self.transport is not None:
            self.transport.close()


def install_frame_hook(gateway, callback) -> None:
    """Call ``callback()`` at every frame start: before each ``render``/``submit`` of the gateway."""
    for name in ("render", "submit"):
        original = getattr(gateway, name, None)
        if original is None:
            continue

        def hooked(*args, _original=original, **kwargs):
            callback()
            return _original(*args, **kwargs)

        setattr(gateway, name, hooked)


async def start_cigi(runtime) -> CigiListener:
    """Bind the CIGI socket and start the listener (raises OSError when the port is taken)."""
    from ..scene.files import load_scene

    settings = runtime.settings
    engine = CigiEngine(runtime.store, runtime.metrics, sync=settings.cigi_sync,
                        entity_types=settings.cigi_entity_types, load_scene=load_scene)
    loop = asyncio.get_running_loop()
    _, listener = await loop.create_datagram_endpoint(lambda: CigiListener(runtime, engine),
                                                      local_addr=(settings.cigi_bind, settings.cigi_port))
    install_frame_hook(runtime.gateway, listener.frame_started)
    listener._heartbeat = loop.create_task(listener.heartbeat(), name="igserver-cigi-heartbeat")
    runtime.metrics.gauge("igserver_cigi_ig_frame", "CIGI IG frame counter", lambda: engine.ig_frame)
    runtime.metrics.gauge("igserver_cigi_last_host_frame", "Last CIGI host frame received",
                          lambda: engine.session.host_frame)
    log.info("CIGI 3.3 on udp %s:%d (IG messages to port %d)", settings.cigi_bind,
             listener.transport.get_extra_info("sockname")[1], settings.cigi_host_port)
    return listener


def udp_bind_problem(host: str, port: int) -> str | None:
    """Why ``host:port`` cannot be bound for UDP now (None when it can): ``igserver serve`` asks before it
    starts, so a taken CIGI port is one line and exit status 2, like a taken TCP port."""
    import socket

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    probe = socket.socket(family, socket.SOCK_DGRAM)
    try:
        probe.bind((host, port))
    except OSError as exc:
        return exc.strerror or str(exc)
    finally:
        probe.close()
    return None
