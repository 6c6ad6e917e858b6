"""Bounds on what clients can make the server hold: concurrent work of one kind, and the accept loop when
the process runs out of descriptors.

Each bound is a setting (settings.py). Work over its bound is refused at once with a problem of kind
``overloaded`` (503 and ``Retry-After``): queueing it would only move the pile-up into memory.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import time

from .problems import PROBLEM_KINDS, ProblemError

log = logging.getLogger("igserver.protocol")

# registered here with the bounds that answer it; the problem-type page lists it with the others
PROBLEM_KINDS.setdefault("overloaded", (503, "Server busy: too many requests of this kind at once"))

RETRY_AFTER_S = 1


class Gate:
    """At most ``limit`` holders at once; one more is refused (no queue). Used from the event loop only."""

    def __init__(self, limit: int, what: str):
        self.limit = limit
        self.what = what
        self.held = 0
        self.refused = 0

    @contextlib.contextmanager
    def enter(self):
        if self.held >= self.limit:
            self.refused += 1
            raise ProblemError("overloaded", f"{self.limit} {self.what} are in progress already; retry later",
                               headers={"Retry-After": str(RETRY_AFTER_S)})
        self.held += 1
        try:
            yield
        finally:
            self.held -= 1


# --------------------------------------------------------------------------- out of descriptors

_EXHAUSTED = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})
ACCEPT_LOG_INTERVAL_S = 10.0


class _AcceptRound:
    """The listening socket for one round of asyncio's accept loop: after the first out-of-descriptors
    error it answers "nothing pending", which ends the round.

    asyncio (3.11) goes on round the loop after that error (``backlog`` times: 2048 under uvicorn), logging a
    traceback and scheduling a retry each time; the retries fire the next rounds: a process short of
    descriptors wrote hundreds of thousands of tracebacks and could no longer answer /v1/health."""

    def __init__(self, sock):
        self.sock = sock
        self.exhausted = False

    def accept(self):
        if self.exhausted:
            raise BlockingIOError(errno.EAGAIN, "accept round ended")
        try:
            return self.sock.accept()
        except OSError as exc:
            if exc.errno in _EXHAUSTED:
                self.exhausted = True
            raise

    def __getattr__(self, name):
        return getattr(self.sock, name)


def guard_accept_loop(loop: asyncio.AbstractEventLoop) -> None:
    """Make ``loop`` stop an accept round at the first out-of-descriptors error, and log that error at most
    once per ``ACCEPT_LOG_INTERVAL_S``, as one line with a count. Call before the server listens."""
    accept = getattr(loop, "_accept_connection", None)
    if accept is not None:  # a selector event loop (another loop keeps its own accept logic)
        def accept_round(protocol_factory, sock, *args, **kwargs):
            if isinstance(sock, _AcceptRound):  # a retry scheduled by the previous round
                sock = sock.sock
            return accept(protocol_factory, _AcceptRound(sock), *args, **kwargs)

        loop._accept_connection = accept_round  # type: ignore[attr-defined]

    previous = loop.get_exception_handler()
    state = {"last": -float("inf"), "suppressed": 0}

    def handler(loop, context):
        exc = context.get("exception")
        if isinstance(exc, OSError) and exc.errno in _EXHAUSTED and "accept" in context.get("message", ""):
            now = time.monotonic()
            if now - state["last"] < ACCEPT_LOG_INTERVAL_S:
                state["suppressed"] += 1
                return
            more = f" ({state['suppressed']} more since the last report)" if state["suppressed"] else ""
            log.error("cannot accept connections: %s%s; raise the descriptor limit (ulimit -n) or lower "
                      "max_connections / idle_timeout_s", exc.strerror or exc, more)
            state.update(last=now, suppressed=0)
            return
        if previous is not None:
            previous(loop, context)
        else:
            loop.default_exception_handler(context)

    loop.set_exception_handler(handler)
