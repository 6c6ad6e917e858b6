"""FastAPI dependencies: the runtime, the decoded (and bounded) message body, the reply format."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, Request, Response

from .codec import MSGPACK, acceptable, base_media_type, decode, encode, is_json, is_msgpack, negotiate
from .problems import ProblemError
from .runtime import IGRuntime


def get_runtime(request: Request) -> IGRuntime:
    return request.app.state.runtime


Runtime = Annotated[IGRuntime, Depends(get_runtime)]


async def read_limited_body(request: Request, max_bytes: int) -> bytes:
    """The body, refusing more than ``max_bytes`` before reading it all (Content-Length) or while reading."""
    declared = request.headers.get("content-length")
    if declared is not None:
        try:
            declared_bytes = int(declared)
        except ValueError:
            raise ProblemError("bad_request", "Content-Length is not a number") from None
        if declared_bytes > max_bytes:
            raise ProblemError("limits", f"body of {declared_bytes} bytes exceeds {max_bytes}")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > max_bytes:
            raise ProblemError("limits", f"body exceeds {max_bytes} bytes")
        chunks.append(chunk)
    return b"".join(chunks)


async def message_body(request: Request, runtime: Runtime) -> Any:
    """The decoded body of a write. The content type is checked first, before a byte is read: a write without
    a JSON or msgpack type is how a foreign web page would send one without a CORS preflight (security.py)."""
    return await decode_message(request, runtime.settings.limits)


async def decode_message(request: Request, limits) -> Any:
    """``message_body`` under explicit limits (a route with longer arrays, e.g. query points, widens them)."""
    media = base_media_type(request.headers.get("content-type"))
    if not (is_json(media) or is_msgpack(media)):
        raise ProblemError("unsupported_media_type", f"a {request.method} needs Content-Type application/json "
                           f"or {MSGPACK} (got {media or 'none'!r})")
    body = await read_limited_body(request, limits.max_body_bytes)
    if not body:
        raise ProblemError("malformed", "empty body: send a msgpack or JSON map")
    return decode(body, request.headers.get("content-type"), limits)


Message = Annotated[Any, Depends(message_body)]


def reply_format(request: Request) -> str:
    accept = request.headers.get("accept")
    if not acceptable(accept):
        raise ProblemError("not_acceptable", f"Accept {accept!r}: this route answers in JSON or {MSGPACK}")
    return negotiate(request.headers.get("accept"), request.headers.get("content-type"))


ReplyFormat = Annotated[str, Depends(reply_format)]


def reply(value: Any, media_type: str, status_code: int = 200, headers: dict[str, str] | None = None) -> Response:
    """A plain tree in the negotiated format (msgpack or JSON)."""
    return Response(encode(value, media_type), status_code=status_code, media_type=media_type, headers=headers)


def wants_minimal(request: Request) -> bool:
    """RFC 7240 ``Prefer: return=minimal``: a 60 Hz host need not get the whole state back each time."""
    return "return=minimal" in request.headers.get("prefer", "").replace(" ", "")


__all__ = ["MSGPACK", "Message", "ReplyFormat", "Runtime", "reply", "wants_minimal", "get_runtime"]
