"""Python host client for igserver protocol v1 (sync and asyncio), and the ``igclient`` CLI (``cli``).

    from igserver.client import IGClient
    with IGClient("http://127.0.0.1:8600", token=None) as ig:   # token: the server's IGSERVER_TOKEN, if it has one
        ig.patch_state({"host_frame": 1, "camera": {"heading": 90}})
        frame = ig.get_frame()                 # Frame: .data (JPEG), .host_frame, .frame, .render_ms
        with ig.stream(credits=2) as stream:   # WebSocket, msgpack both ways
            stream.send_patch({"host_frame": 2, "camera": {"pitch": 5}})
            frame = stream.recv()              # acks automatically: the server sends the next one

``AsyncIGClient`` / ``AsyncFrameStream`` are the same for asyncio. States are ``igserver.scene.Scene``
(or plain dicts); every message is validated by the server, and a rejection raises ``IGError`` carrying
the RFC 9457 problem (``.problem["errors"]`` lists the offending fields' JSON Pointers).

Modules: ``wire`` (messages, frames, errors), ``steps`` (each call written once for both clients), ``api``
(the REST calls), ``http`` (the two clients), ``stream`` (the WebSocket), ``multipart`` (the MJPEG body),
``latency`` (the latency benchmark), ``cli`` (``igclient``).
"""

from .http import AsyncIGClient, IGClient
from .multipart import MultipartJpegParser, iter_multipart_jpegs
from .stream import AsyncFrameStream, FrameStream
from .wire import Frame, IGError

__all__ = ["AsyncFrameStream", "AsyncIGClient", "Frame", "FrameStream", "IGClient", "IGError",
           "MultipartJpegParser", "iter_multipart_jpegs"]
