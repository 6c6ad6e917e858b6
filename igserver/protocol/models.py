"""Typed documents the protocol sends besides the scene itself (documented in OpenAPI).

The state messages are ``igserver.scene.Scene`` unchanged; these are the envelopes around it.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

SCENE_REF = {"$ref": "#/components/schemas/Scene"}
PATCH_SCHEMA = {
    "type": "object",
    "description": "A partial Scene: maps merge key by key, lists and values replace. Validated whole: "
    "the result must be a valid Scene, else nothing changes.",
}
EFFECT_REF = {"$ref": "#/components/schemas/Effect"}


def body_doc(schema: dict, description: str) -> dict:
    """openapi_extra for a route that decodes its own body (msgpack or JSON)."""
    content = {media: {"schema": schema} for media in ("application/json", "application/vnd.msgpack")}
    return {"requestBody": {"required": True, "description": description, "content": content}}


MSGPACK_ALSO = {"application/vnd.msgpack": {}}
PROBLEM_RESPONSES = {
    code: {
        "description": text,
        "content": {"application/problem+json": {"schema": {"$ref": "#/components/schemas/Problem"}},
                    "application/problem+msgpack": {}},
    }
    for code, text in (
        (400, "malformed body"),
        (413, "body, string, array or nesting over a limit"),
        (415, "unsupported Content-Type"),
        (422, "a field is of the wrong type, out of range, NaN/Inf or unknown"),
    )
}


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    protocol: int = 1
    uptime_s: float


class Ready(BaseModel):
    ready: bool
    renderer: str | None = None
    gl_version: str | None = None
    software: bool | None = None
    restarts: int = 0
    pid: int | None = None
    frames: int = 0
    revision: int = Field(0, description="accepted state revision")
    error: str | None = Field(None, description="last render or start failure, while not ready")


class Accepted(BaseModel):
    """Answer to PUT/PATCH with ``Prefer: return=minimal`` (the full state otherwise)."""

    revision: int
    host_frame: int


class FrameMessage(BaseModel):
    """A frame as a msgpack map (WebSocket, and POST /v1/render for msgpack callers)."""

    type: Literal["frame"] = "frame"
    frame: int = Field(..., description="IG frame number")
    host_frame: int = Field(..., description="host_frame of the state this frame shows")
    width: int
    height: int
    format: Literal["jpeg", "png", "raw"]
    data: bytes = Field(..., description="encoded image (raw: RGBA rows, top row first)")
    render_ms: float = Field(..., description="render time in the render process")
    encode_ms: float = Field(..., description="encoding time in the server")
    ev100: float = Field(0.0, description="exposure the frame was rendered with (EV100)")
    illuminance_lux: float = Field(0.0, description="natural horizontal illuminance at the camera (lux)")
