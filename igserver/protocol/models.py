"""Typed documents the protocol sends besides the scene itself (documented in OpenAPI).

The state messages are ``igserver.scene.Scene`` unchanged; these are the envelopes around it.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, Field

SCENE_REF = {"$ref": "#/components/schemas/Scene"}
PATCH_SCHEMA = {"$ref": "#/components/schemas/ScenePatch"}  # built in openapi.py: the Scene, all optional
EFFECT_REF = {"$ref": "#/components/schemas/Effect"}
EFFECT_PATCH_REF = {"$ref": "#/components/schemas/EffectPatch"}

# Headers the routes set by hand, documented on their 200 answers (openapi.py)
FRAME_HEADERS = {
    "X-IG-Frame": {"description": "IG frame number", "schema": {"type": "integer"}},
    "X-IG-Host-Frame": {"description": "host_frame of the state the frame shows", "schema": {"type": "integer"}},
    "X-IG-Width": {"description": "frame width (px)", "schema": {"type": "integer"}},
    "X-IG-Height": {"description": "frame height (px)", "schema": {"type": "integer"}},
    "X-IG-Render-Ms": {"description": "render time in the render process (ms)", "schema": {"type": "number"}},
    "X-IG-Encode-Ms": {"description": "image encoding time in the server (ms)", "schema": {"type": "number"}},
    "X-IG-EV100": {"description": "exposure the frame was rendered with (EV100)", "schema": {"type": "number"}},
    "X-IG-Illuminance-Lux": {"description": "natural horizontal illuminance at the camera (lux)",
                             "schema": {"type": "number"}},
}
# A frame's operating point (render/overload.py)
QUALITY_HEADER_DOC = {
    "description": "operating point of the frame (target=0: the scene holds no quality.target_fps): "
                   "scale=0.75; rungs=precip:medium,volumes:medium,water:low; error=5.57; target=25; met=true "
                   "(error: estimated 8-bit sRGB RMSE; met=false: the target is out of reach at the cheapest point)",
    "schema": {"type": "string"}}
FRAME_HEADERS["X-IG-Quality"] = QUALITY_HEADER_DOC
STATE_HEADERS = {
    "X-IG-Revision": {"description": "accepted state revision", "schema": {"type": "integer"}},
    "X-IG-Host-Frame": {"description": "host_frame of the accepted state (PUT/PATCH)", "schema": {"type": "integer"}},
}


def body_doc(schema: dict, description: str) -> dict:
    """openapi_extra for a route that decodes its own body (msgpack or JSON)."""
    content = {media: {"schema": schema} for media in ("application/json", "application/vnd.msgpack")}
    return {"requestBody": {"required": True, "description": description, "content": content}}


MSGPACK_ALSO = {"application/vnd.msgpack": {}}

# Query flags: HTTP's spellings of a boolean, and nothing looser. ``?replace=yes`` meaning true (pydantic's
# lax bool) would let a typo replace the whole state; any case is accepted, as Python's requests sends "True".
QUERY_BOOLS = {"true": True, "1": True, "false": False, "0": False}


def strict_query_bool(value: Any) -> bool:
    if isinstance(value, bool):  # the route's default
        return value
    if isinstance(value, str) and value.lower() in QUERY_BOOLS:
        return QUERY_BOOLS[value.lower()]
    raise ValueError(f"expected true, false, 1 or 0, got {str(value)[:20]!r}")


QueryBool = Annotated[bool, BeforeValidator(strict_query_bool)]
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


class QualityReport(BaseModel):
    """A frame's operating point (render/overload.py Decision.fields)."""

    scale: float = Field(..., description="internal render scale (the frame was upscaled from scale x its size)")
    rungs: dict[str, str] = Field(..., description="each pipeline's preset level (e.g. low, or low>medium between two)")
    error: float = Field(..., description="estimated picture error, 8-bit sRGB RMSE")
    target_fps: float
    met: bool = Field(..., description="false: the target is out of reach at the cheapest point")
    predicted_ms: float = Field(..., description="the controller's predicted frame time at this point")


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
    quality: QualityReport | None = Field(None, description="the frame's operating point (X-IG-Quality as a map)")
    channel: str | None = Field(None, description="the channel shown, when the state has channels")


class ChannelInfo(BaseModel):
    """One channel a frame delivers (GET /v1/channels)."""

    id: str = Field(..., description='channel id ("" for the camera of a state without channels)')
    implicit: bool = Field(..., description="true: the camera of a state without channels")
    width: int = Field(..., description="px")
    height: int = Field(..., description="px")
    heading: float = Field(..., description="deg, offset from the camera's heading, right positive")
    pitch: float = Field(..., description="deg, offset from the camera's pitch, up positive")
    roll: float = Field(..., description="deg, offset from the camera's roll")
    fov_left: float = Field(..., description="deg, half-angle from the axis to the left edge")
    fov_right: float = Field(..., description="deg")
    fov_up: float = Field(..., description="deg")
    fov_down: float = Field(..., description="deg")
    near: float = Field(..., description="m, in effect (the camera's when the channel leaves it unset)")
    far: float = Field(..., description="m, in effect")


class ChannelList(BaseModel):
    """GET /v1/channels: the channels of the current state, in order."""

    revision: int = Field(..., description="accepted state revision")
    channels: list[ChannelInfo]


class ChannelImage(BaseModel):
    """One channel's image in a ChannelsFrameMessage."""

    width: int
    height: int
    data: bytes = Field(..., description="encoded image (raw: RGBA rows, top row first)")
    encode_ms: float


class ChannelsFrameMessage(BaseModel):
    """Several channels of one frame (WebSocket after hello ``channels``; POST /v1/render of a state with
    channels, for msgpack callers): one IG frame number and host_frame for all of them."""

    type: Literal["frame"] = "frame"
    frame: int = Field(..., description="IG frame number (every channel's)")
    host_frame: int = Field(..., description="host_frame of the state every channel shows")
    format: Literal["jpeg", "png", "raw"]
    render_ms: float = Field(..., description="render time of the frame (all channels) in the render process")
    ev100: float = Field(0.0, description="exposure of every channel (one exposure per frame)")
    illuminance_lux: float = 0.0
    quality: QualityReport | None = None
    channels: dict[str, ChannelImage] = Field(..., description="by channel id, in the state's order")
    missing: list[str] | None = Field(None, description="channels asked for in hello that this frame has not "
                                      "(they left the state)")


# --- WebSocket /v1/ws messages (documented in the AsyncAPI document and /v1/ws-protocol; routers/ws.py)
class HelloMessage(BaseModel):
    """Client -> server, optional and first: sets the credit window and the image format."""

    type: Literal["hello"] = "hello"
    credits: int = Field(2, ge=0, le=1024, description="frames the server may send before the next ack "
                         "(at most the server's ws_max_credits)")
    format: Literal["jpeg", "png", "raw"] = "jpeg"
    quality: int = Field(85, ge=1, le=100, description="JPEG quality")
    channels: list[str] | None = Field(None, max_length=16, description="channel ids of the current state: each "
                                       "frame message then carries these channels of one state together "
                                       "(ChannelsFrameMessage); [] = every channel; absent = the first channel "
                                       "alone (FrameMessage)")
    id: int | str | None = None


class StateMessage(BaseModel):
    """Client -> server: merge a partial state (``patch``) or replace the whole state (``replace``)."""

    type: Literal["patch", "replace"]
    state: dict = Field(..., description="a ScenePatch (patch) or a Scene (replace)")
    id: int | str | None = Field(None, description="echoed in the error reply when the message is rejected")


class AckMessage(BaseModel):
    """Client -> server: one frame consumed, one credit back."""

    type: Literal["ack"] = "ack"
    frame: int | None = Field(None, description="the IG frame number consumed (informative)")


class CreditMessage(BaseModel):
    """Client -> server: grant more credits."""

    type: Literal["credit"] = "credit"
    n: int = Field(1, ge=0, le=1024)


class ErrorMessage(BaseModel):
    """Server -> client: a message was rejected and nothing changed."""

    type: Literal["error"] = "error"
    id: int | str | None = Field(None, description="the rejected message's id, when it had one")
    problem: dict = Field(..., description="RFC 9457 problem members (see the Problem schema)")
