"""Each protocol call written once, for the blocking and the asyncio clients alike.

A call is a generator: it yields the I/O it needs (``Call``: an HTTP request; ``Pause``; ``Send`` and
``Receive``: WebSocket messages), is sent each answer back (or has the I/O's error raised at its
``yield``), and returns the call's result. ``operation`` makes it a method; the object's ``_drive`` runs
it, with blocking I/O (a result) or awaiting each step (a coroutine). So what is sent, how answers are
read and which errors a call handles is spelled once; only the I/O loop differs (``Run``).
"""

from __future__ import annotations

import functools
import types
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Generator, Iterator

from .wire import MSGPACK, pack


@dataclass(frozen=True)
class Call:
    """One HTTP request; the answer sent back is the ``httpx.Response``."""

    method: str
    path: str
    body: Any = None  # a msgpack message (None: no body)
    params: dict | None = None
    headers: dict | None = None

    def request(self) -> dict:
        """Keyword arguments of ``httpx.Client.request`` (and of the async one)."""
        headers = dict(self.headers or {})
        content = None
        if self.body is not None:
            content = pack(self.body)
            headers = {"Content-Type": MSGPACK, "Accept": MSGPACK, **headers}
        return {"method": self.method, "url": self.path, "content": content, "params": self.params,
                "headers": headers or None}


@dataclass(frozen=True)
class Pause:
    seconds: float


@dataclass(frozen=True)
class Send:
    """A WebSocket message out."""

    data: bytes


@dataclass(frozen=True)
class Receive:
    """The next WebSocket message in (its bytes are sent back)."""

    timeout: float | None


Steps = Generator[Any, Any, Any]


class Run:
    """Drives one call: iterate it for its steps, and after each set ``reply``, or let ``failing`` catch
    the step's error for the call to handle. ``value`` is the call's result once the loop ends."""

    def __init__(self, steps: Steps):
        self._steps = steps
        self.reply: Any = None
        self._error: BaseException | None = None
        self.value: Any = None

    def __iter__(self) -> Iterator[Any]:
        try:
            step = next(self._steps)
            while True:
                yield step
                reply, error = self.reply, self._error
                self.reply = self._error = None
                step = self._steps.throw(error) if error is not None else self._steps.send(reply)
        except StopIteration as stop:
            self.value = stop.value

    @contextmanager
    def failing(self, *errors: type[BaseException]):
        """I/O errors the call sees raised at its ``yield`` (and may handle: ``wait_ready`` retries)."""
        try:
            yield
        except errors as exc:
            self._error = exc


class operation:
    """A call (a generator function of the client) as a method: ``client._drive`` runs it."""

    def __init__(self, steps):
        self.steps = steps
        functools.update_wrapper(self, steps)

    def __get__(self, client, owner=None):
        return self if client is None else types.MethodType(self, client)

    def __call__(self, client, *args, **kwargs):
        return client._drive(self.steps(client, *args, **kwargs))
