"""RFC 9457 problem details: every error the protocol answers, in the caller's format.

A problem carries ``type`` (a URI per kind of error), ``title``, ``status``, ``detail``, ``instance`` (the
request path) and, for bad messages, ``errors``: one entry per offending field with a JSON Pointer
(``pointer``: ``#/camera/pitch``) and a message (``detail``). msgpack callers get the same members in
msgpack (``application/problem+msgpack``).
"""

from __future__ import annotations

from typing import Any, Iterable

from pydantic import BaseModel, Field, ValidationError

PROBLEM_BASE = "/v1/problems/"

# kind -> (HTTP status, title). The kinds are also the label values of igserver_protocol_errors_total.
PROBLEM_KINDS: dict[str, tuple[int, str]] = {
    "malformed": (400, "Malformed message body"),
    "non_finite": (422, "Non-finite number (NaN or Infinity)"),
    "validation": (422, "Message does not match the scene model"),
    "limits": (413, "Message exceeds a size, length or nesting limit"),
    "unsupported_media_type": (415, "Unsupported media type"),
    "not_acceptable": (406, "Not acceptable"),
    "unauthorized": (401, "Bearer token missing or wrong"),
    "forbidden": (403, "Host or Origin not allowed"),
    "not_found": (404, "Not found"),
    "conflict": (409, "Conflict"),
    "method_not_allowed": (405, "Method not allowed"),
    "bad_request": (400, "Bad request"),
    "render_unavailable": (503, "Render process unavailable"),
    "internal": (500, "Internal server error"),
}


class FieldError(BaseModel):
    pointer: str = Field(..., description="JSON Pointer (RFC 6901) to the offending field, as a URI fragment")
    detail: str


class Problem(BaseModel):
    """The problem-details document (documented in OpenAPI; sent as JSON or msgpack)."""

    type: str
    title: str
    status: int
    detail: str | None = None
    instance: str | None = None
    kind: str
    errors: list[FieldError] = Field(default_factory=list)


def json_pointer(loc: Iterable[Any]) -> str:
    """('camera', 'position', 0) -> '#/camera/position/0' (RFC 6901 escaping of ~ and /)."""
    parts = [str(p).replace("~", "~0").replace("/", "~1") for p in loc]
    return "#/" + "/".join(parts) if parts else "#"


class ProblemError(Exception):
    """Raised anywhere in request handling; the app's handler turns it into a problem response."""

    def __init__(
        self,
        kind: str,
        detail: str | None = None,
        errors: list[dict[str, str]] | None = None,
        status: int | None = None,
        headers: dict[str, str] | None = None,
    ):
        default_status, self.title = PROBLEM_KINDS[kind]
        self.kind = kind
        self.status = status or default_status
        self.detail = detail
        self.errors = errors or []
        self.headers = headers
        super().__init__(detail or self.title)

    def document(self, instance: str | None = None) -> dict[str, Any]:
        doc: dict[str, Any] = {
            "type": PROBLEM_BASE + self.kind,
            "title": self.title,
            "status": self.status,
            "kind": self.kind,
        }
        if self.detail:
            doc["detail"] = self.detail
        if instance:
            doc["instance"] = instance
        if self.errors:
            doc["errors"] = self.errors
        return doc


def from_validation_error(exc: ValidationError, prefix: tuple = ()) -> ProblemError:
    """pydantic errors -> one problem listing every offending field with its pointer."""
    errors = []
    kind = "validation"
    for err in exc.errors(include_url=False):
        loc = prefix + tuple(err.get("loc", ()))
        errors.append({"pointer": json_pointer(loc), "detail": err.get("msg", "invalid value")})
        if err.get("type") == "finite_number":
            kind = "non_finite"
    return ProblemError(kind, summary(errors), errors)


def summary(errors: list[dict[str, str]]) -> str:
    """A problem's detail from its field errors: the first one, with its pointer, and how many more."""
    first = errors[0] if errors else {"pointer": "#", "detail": "invalid"}
    text = f"{first['pointer']}: {first['detail']}"
    if len(errors) > 1:
        text += f" (and {len(errors) - 1} more)"
    return text
