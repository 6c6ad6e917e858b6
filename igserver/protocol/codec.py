"""Wire codec: msgpack or JSON bodies in, the caller's format out, with limits checked before validation.

Everything a client sends passes ``decode_body`` first: size, nesting depth, string/array/map lengths,
key types and finiteness of every float are checked on the plain tree, so the pydantic model only ever
sees a bounded tree and a NaN is reported with the path where it was found (msgpack carries NaN and
Infinity as ordinary floats; JSON gets them through Python's non-standard ``NaN`` literals).
"""

from __future__ import annotations

import json
import math
from typing import Any

import msgpack
from pydantic import BaseModel, Field

from .problems import ProblemError, json_pointer

MSGPACK = "application/vnd.msgpack"
MSGPACK_TYPES = frozenset({MSGPACK, "application/x-msgpack", "application/msgpack"})
JSON = "application/json"
PROBLEM_JSON = "application/problem+json"
PROBLEM_MSGPACK = "application/problem+msgpack"


class Limits(BaseModel, frozen=True):
    """Bounds on a message body, checked before the scene model sees it (settings: IGSERVER_LIMITS__*)."""

    # a full scene with every list at its maximum is ~150 KiB
    max_body_bytes: int = Field(1 << 20, ge=1, description="body bytes")
    max_depth: int = Field(16, ge=1, le=64, description="nesting depth of maps and arrays")
    max_string: int = Field(4096, ge=1, description="string length")
    max_array: int = Field(1024, ge=1, description="array length")
    max_map: int = Field(256, ge=1, description="keys in one map")


DEFAULT_LIMITS = Limits()


def base_media_type(header: str | None) -> str:
    return (header or "").split(";", 1)[0].strip().lower()


def is_msgpack(media_type: str) -> bool:
    return media_type in MSGPACK_TYPES or media_type.endswith("+msgpack")


def is_json(media_type: str) -> bool:
    return media_type == JSON or media_type.endswith("+json")


def _accept_ranges(accept: str) -> list[tuple[float, int, str]]:
    ranges = []
    for index, item in enumerate(accept.split(",")):
        parts = [p.strip() for p in item.split(";")]
        media = parts[0].lower()
        if not media:
            continue
        q = 1.0
        for param in parts[1:]:
            if param.startswith("q="):
                try:
                    q = float(param[2:])
                except ValueError:
                    q = 0.0
        ranges.append((q, index, media))
    # highest q first; on equal q, the order the client wrote them
    ranges.sort(key=lambda r: (-r[0], r[1]))
    return ranges


def negotiate(accept: str | None, content_type: str | None) -> str:
    """Response format: ``MSGPACK`` or ``JSON``. The Accept header wins, else the request's Content-Type.

    A wildcard or absent Accept falls back to the request's format, so a msgpack host that sends no
    Accept header gets msgpack back.
    """
    request_format = MSGPACK if is_msgpack(base_media_type(content_type)) else JSON
    if not accept:
        return request_format
    for q, _, media in _accept_ranges(accept):
        if q <= 0:
            continue
        if is_msgpack(media):
            return MSGPACK
        if is_json(media):
            return JSON
        if media in ("*/*", "application/*"):
            return request_format
    return request_format


def acceptable(accept: str | None) -> bool:
    """False when Accept lists only formats this API never answers in (406); absent Accept takes anything."""
    if not accept:
        return True
    for q, _, media in _accept_ranges(accept):
        if q > 0 and (is_msgpack(media) or is_json(media) or media in ("*/*", "application/*")):
            return True
    return False


def _reject_ext(code: int, data: bytes) -> Any:
    raise ValueError(f"msgpack extension type {code} is not part of the protocol")


def _no_json_constants(name: str) -> float:
    # Python's json accepts NaN/Infinity; the protocol does not. Map them to floats so the tree walk
    # reports them with their path like msgpack NaNs.
    return float(name.replace("Infinity", "inf"))


def _loads_msgpack(body: bytes, limits: Limits) -> Any:
    try:
        return msgpack.unpackb(
            body,
            raw=False,
            strict_map_key=True,
            ext_hook=_reject_ext,
            max_str_len=limits.max_string,
            max_bin_len=limits.max_body_bytes,
            max_array_len=limits.max_array,
            max_map_len=limits.max_map,
            max_ext_len=0,
            timestamp=0,
        )
    except msgpack.StackError:  # nested deeper than msgpack's own stack (a ValueError: catch it first)
        raise ProblemError("limits", f"msgpack nesting deeper than {limits.max_depth}") from None
    except ValueError as exc:  # includes ExtraData, FormatError and the length limits
        text = str(exc)
        if "max_ext_len" in text:  # max_ext_len=0 refuses every extension type, timestamps included
            raise ProblemError("malformed", "msgpack extension types are not part of the protocol") from None
        if "exceeds max_" in text:
            raise ProblemError("limits", f"msgpack: {text}") from None
        raise ProblemError("malformed", f"invalid msgpack: {text}") from None
    except Exception as exc:  # UnicodeDecodeError, TypeError on odd keys
        name = type(exc).__name__
        raise ProblemError("malformed", f"invalid msgpack: {name}: {exc}") from None


def _loads_json(body: bytes) -> Any:
    try:
        return json.loads(body, parse_constant=_no_json_constants)
    except RecursionError:
        raise ProblemError("limits", "JSON nesting too deep") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ProblemError("malformed", f"invalid JSON: {exc}") from None


def _plain_numbers(items: list) -> bool:
    """Every item an int or a finite float (the common row of a long array)."""
    for item in items:
        kind = type(item)
        if not (kind is int or (kind is float and math.isfinite(item))):
            return False
    return True


def check_tree(value: Any, limits: Limits = DEFAULT_LIMITS) -> None:
    """Walk a decoded tree (iteratively: no recursion to exhaust) and enforce the limits.

    Raises ProblemError naming the JSON Pointer of the first offending value.
    """
    stack: list[tuple[Any, tuple, int]] = [(value, (), 0)]
    while stack:
        node, path, depth = stack.pop()
        if depth > limits.max_depth:
            raise ProblemError("limits", f"nesting deeper than {limits.max_depth} at {json_pointer(path)}")
        if isinstance(node, float):
            if not math.isfinite(node):
                where = json_pointer(path)
                raise ProblemError(
                    "non_finite",
                    f"{where}: {node!r} is not a finite number",
                    [{"pointer": where, "detail": "NaN and Infinity are not accepted"}],
                )
        elif isinstance(node, str):
            if len(node) > limits.max_string:
                raise ProblemError("limits", f"{json_pointer(path)}: string longer than {limits.max_string}")
        elif isinstance(node, (bytes, bytearray)):
            where = json_pointer(path)
            raise ProblemError(
                "validation",
                f"{where}: binary data is not accepted in a state message",
                [{"pointer": where, "detail": "expected a number, string, boolean, array or map"}],
            )
        elif isinstance(node, dict):
            if len(node) > limits.max_map:
                raise ProblemError("limits", f"{json_pointer(path)}: map with more than {limits.max_map} keys")
            for key, item in node.items():
                if not isinstance(key, str):
                    raise ProblemError("malformed", f"{json_pointer(path)}: map keys must be strings")
                stack.append((item, path + (key,), depth + 1))
        elif isinstance(node, (list, tuple)):
            if len(node) > limits.max_array:
                raise ProblemError("limits", f"{json_pointer(path)}: array longer than {limits.max_array}")
            # plain numbers, and short rows of them such as [x, y], need no walk (no path tuples for the
            # thousands of coordinates of a query); anything else, a bad number included, is walked
            numbers_ok, rows_ok = depth + 1 <= limits.max_depth, depth + 2 <= limits.max_depth
            for index, item in enumerate(node):
                kind = type(item)
                if numbers_ok and (kind is int or (kind is float and math.isfinite(item))):
                    continue
                if rows_ok and kind is list and len(item) <= limits.max_array and _plain_numbers(item):
                    continue
                stack.append((item, path + (index,), depth + 1))


def decode(body: bytes, content_type: str | None, limits: Limits = DEFAULT_LIMITS) -> Any:
    """Bytes + Content-Type -> checked plain tree (dicts, lists, str, int, float, bool, None)."""
    media = base_media_type(content_type)
    if len(body) > limits.max_body_bytes:
        raise ProblemError("limits", f"body of {len(body)} bytes exceeds {limits.max_body_bytes}")
    if is_msgpack(media):
        tree = _loads_msgpack(body, limits)
    elif is_json(media):
        tree = _loads_json(body)
    else:
        raise ProblemError(
            "unsupported_media_type",
            f"Content-Type {media!r}: send {MSGPACK} (or application/x-msgpack, application/msgpack) or {JSON}",
        )
    check_tree(tree, limits)
    return tree


def encode(value: Any, media_type: str) -> bytes:
    """Plain tree -> bytes in MSGPACK or JSON (media_type from ``negotiate``)."""
    if media_type == MSGPACK:
        return msgpack.packb(value, use_bin_type=True)
    return json.dumps(value, separators=(",", ":"), allow_nan=False).encode()
