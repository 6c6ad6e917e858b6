"""Flow control for pushed streams over HTTP (MJPEG): send the next part only once the previous one has left.

A multipart stream has no acknowledgements of its own. Whatever the server writes ahead of the reader queues
in the server's transport buffer (asyncio) and the kernel's send buffer (autotuned up to megabytes): a slow
reader then reads a backlog of old parts instead of the newest frame. So the stream hands a part to the
transport only when everything before it has left the server — the transport buffer is empty and the kernel
holds no unsent byte of the connection (``SIOCOUTQNSD``; TCP sends only what the reader's receive window
takes, so unsent bytes mean the reader has not made room) — and it picks the frame at that moment, the newest.
What the reader's own socket receive buffer already holds is out of the server's sight: a reader that wants
less than its buffer's worth of latency reads at its pace over the WebSocket with credits (``/v1/ws``).

The ASGI app cannot see its connection, so the HTTP protocol puts the transport into the request scope
(``scope["extensions"]["igserver.transport"]``): ``uvicorn_config`` runs uvicorn with ``TransportInScope``.
"""

from __future__ import annotations

import asyncio
import fcntl
import struct
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
from websockets.protocol import State

SCOPE_KEY = "igserver.transport"
SIOCOUTQNSD = 0x894B  # linux/sockios.h: bytes in the send queue not yet sent
POLL_S = (0.001, 0.02)  # the wait polls from 1 ms, doubling up to 20 ms (a drained part is noticed within that)


class TransportInScope(H11Protocol):
    """uvicorn's h11 protocol, with the connection's transport in every request's scope extensions, and a
    deadline on the client's side of each request.

    uvicorn times out only a kept-alive connection that stays silent, and any byte restarts that wait: a
    connection that never sends, or sends a request head a byte at a time, or stops in the middle of a body,
    is held for ever (a descriptor and a task each). Here the request head must be complete within
    ``timeout_keep_alive`` (the ``idle_timeout_s`` setting) of the connection's start or of the previous
    response's end, whatever trickles in meanwhile, and a body may not stall longer than that between two
    reads. A response being sent (an MJPEG stream) is not the client's to hurry: no deadline then.
    """

    _deadline: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self.app = _with_transport(self.app, transport)
        self._arm_deadline()

    def handle_websocket_upgrade(self, event: h11.Request) -> None:
        # uvicorn builds the WebSocket protocol with the configured app, not this connection's: give that
        # protocol the transport too (it calls its app once the handshake is done, after this returns)
        ws_class, transport = self.ws_protocol_class, self.transport

        def ws_protocol_with_transport(*args, **kwargs):
            protocol = ws_class(*args, **kwargs)
            protocol.app = _with_transport(protocol.app, transport)
            return protocol

        self.ws_protocol_class = ws_protocol_with_transport
        try:
            super().handle_websocket_upgrade(event)
        finally:
            self.ws_protocol_class = ws_class

    def data_received(self, data: bytes) -> None:
        head_pending = self.conn.their_state is h11.IDLE
        super().data_received(data)
        # a head still incomplete keeps its deadline; a body's restarts with each piece
        if not (head_pending and self.conn.their_state is h11.IDLE):
            self._arm_deadline()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._arm_deadline()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm_deadline()
        super().connection_lost(exc)

    def _disarm_deadline(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def _arm_deadline(self) -> None:
        self._disarm_deadline()
        if self.transport.is_closing() or self.transport.get_protocol() is not self:
            return  # closed, or upgraded to a WebSocket (its own protocol and pings)
        if self.conn.their_state in (h11.IDLE, h11.SEND_BODY):
            self._deadline = self.loop.call_later(self.timeout_keep_alive, self._deadline_passed)

    def _deadline_passed(self) -> None:
        self._deadline = None
        if self.conn.their_state in (h11.IDLE, h11.SEND_BODY) and not self.transport.is_closing():
            self.transport.close()


class WebSocketsProtocol(WebSocketsSansIOProtocol):
    """uvicorn's WebSocket protocol, stopping cleanly at shutdown when the client's close has arrived.

    A client that sent its close and stops reading leaves the connection CLOSING (the reply is queued
    behind unread frames). uvicorn's shutdown then sends a close of its own, which the WebSocket state
    machine refuses: the exception ended ``igserver serve`` on SIGTERM with status 1 and a traceback.
    Nothing is left to say on such a connection, and a client that does not read would hold a graceful
    close (which waits for the write buffer to drain) for ever: it is aborted."""

    def shutdown(self) -> None:
        if self.handshake_complete and not self.close_sent and self.conn.state is not State.OPEN:
            self.stop_keepalive()
            self.queue.put_nowait({"type": "websocket.disconnect", "code": 1012})
            self.transport.abort()
            return
        super().shutdown()


def _with_transport(app, transport: asyncio.Transport):
    async def app_with_transport(scope, receive, send):
        scope.setdefault("extensions", {})[SCOPE_KEY] = transport
        return await app(scope, receive, send)

    return app_with_transport


def transport_of(scope: dict[str, Any]) -> asyncio.Transport | None:
    return (scope.get("extensions") or {}).get(SCOPE_KEY)


def unsent_bytes(transport: asyncio.Transport) -> int:
    """Bytes of this connection still in the server: the transport's buffer plus the kernel's unsent queue."""
    pending = transport.get_write_buffer_size()
    sock = transport.get_extra_info("socket")
    # a socket the peer's disconnect has closed meanwhile has no descriptor (-1): nothing in the kernel
    if sock is not None and sock.fileno() >= 0:
        try:
            pending += struct.unpack("i", fcntl.ioctl(sock.fileno(), SIOCOUTQNSD, b"\0\0\0\0"))[0]
        except OSError:  # not a TCP socket on Linux (a Unix socket, another OS): the transport buffer alone
            pass
    return pending


async def drained(transport: asyncio.Transport | None, stopping: asyncio.Event | None = None,
                  kernel: bool = True) -> bool:
    """Wait until everything written to the connection has left the server (``kernel`` False: has left the
    process, into the kernel's send queue); False if it closed (or the server is stopping) first. Without a
    transport (another ASGI server) returns at once."""
    delay = POLL_S[0]
    pending = unsent_bytes if kernel else (lambda t: t.get_write_buffer_size())
    while transport is not None and pending(transport):
        if transport.is_closing() or (stopping is not None and stopping.is_set()):
            return False
        await asyncio.sleep(delay)
        delay = min(2 * delay, POLL_S[1])
    return transport is None or not transport.is_closing()
