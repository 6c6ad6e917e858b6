"""The two REST clients: the calls of ``api.Api`` over httpx, blocking (``IGClient``) or asyncio
(``AsyncIGClient``), the MJPEG stream as an iterator, and the WebSocket stream."""

from __future__ import annotations

import asyncio
import time
from typing import AsyncIterator, Iterator

import httpx

from .api import Api, channel_param
from .multipart import MultipartJpegParser, iter_multipart_jpegs
from .steps import Call, Run
from .stream import AsyncFrameStream, FrameStream
from .wire import DEFAULT_URL, check

MJPEG_HEADERS = {"Accept": "*/*"}


class IGClient(Api):
    """Blocking client (httpx, one keep-alive connection). ``token``: the server's bearer token, if it has one."""

    def __init__(self, url: str = DEFAULT_URL, timeout: float = 30.0, token: str | None = None):
        super().__init__(url, token)
        self.http = httpx.Client(base_url=self.url, timeout=timeout, headers=self.headers)

    def __enter__(self) -> "IGClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.http.close()

    def _drive(self, steps):
        run = Run(steps)
        for step in run:
            with run.failing(httpx.TransportError):
                run.reply = self.http.request(**step.request()) if isinstance(step, Call) else time.sleep(step.seconds)
        return run.value

    def mjpeg(self, frames: int = 0, fps: float = 0, channel: str | None = None) -> Iterator[bytes]:
        """JPEG images of the MJPEG stream (``channel``'s; None: the first channel, or the camera), parsed
        from the multipart body."""
        params = {"frames": frames, "fps": fps, **channel_param(channel)}
        with self.http.stream("GET", "/v1/stream.mjpg", params=params, headers=MJPEG_HEADERS) as response:
            check(response)
            yield from iter_multipart_jpegs(response.iter_bytes())

    def stream(self, credits: int = 2, format: str = "jpeg", quality: int = 85, auto_ack: bool = True,
               channels: list[str] | None = None) -> FrameStream:
        """The WebSocket. ``channels``: each frame carries these channels of one state together
        (``Frame.channels``; ``[]``: every channel); None: the first channel alone."""
        return FrameStream(self.ws_url(), credits, format, quality, auto_ack, self.auth_headers(), channels)


class AsyncIGClient(Api):
    """asyncio client (httpx.AsyncClient). Same methods as IGClient, awaited (``mjpeg`` is an async iterator)."""

    def __init__(self, url: str = DEFAULT_URL, timeout: float = 30.0, token: str | None = None):
        super().__init__(url, token)
        self.http = httpx.AsyncClient(base_url=self.url, timeout=timeout, headers=self.headers)

    async def __aenter__(self) -> "AsyncIGClient":
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()

    async def close(self) -> None:
        await self.http.aclose()

    async def _drive(self, steps):
        run = Run(steps)
        for step in run:
            with run.failing(httpx.TransportError):
                run.reply = await (self.http.request(**step.request()) if isinstance(step, Call)
                                   else asyncio.sleep(step.seconds))
        return run.value

    async def mjpeg(self, frames: int = 0, fps: float = 0, channel: str | None = None) -> AsyncIterator[bytes]:
        """JPEG images of the MJPEG stream: ``async for jpeg in ig.mjpeg(frames=10)``."""
        params = {"frames": frames, "fps": fps, **channel_param(channel)}
        async with self.http.stream("GET", "/v1/stream.mjpg", params=params, headers=MJPEG_HEADERS) as response:
            check(response)
            parser = MultipartJpegParser()
            async for chunk in response.aiter_bytes():
                for jpeg in parser.feed(chunk):
                    yield jpeg

    def stream(self, credits: int = 2, format: str = "jpeg", quality: int = 85,
               auto_ack: bool = True, channels: list[str] | None = None) -> AsyncFrameStream:
        return AsyncFrameStream(self.ws_url(), credits, format, quality, auto_ack, self.auth_headers(), channels)
