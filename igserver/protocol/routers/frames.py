"""Frames over HTTP: one frame of the current state, render-exactly-this-state, and the MJPEG stream."""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Annotated, Literal

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import StreamingResponse

from ..channels import choose, describe, state_channel_ids
from ..codec import MSGPACK, encode, negotiate
from ..dependencies import Message, ReplyFormat, Runtime, reply
from ..encoded_frame import EncodedFrame, quality_headers
from ..flow import drained, transport_of
from ..imaging import MEDIA_TYPES
from ..models import PATCH_SCHEMA, PROBLEM_RESPONSES, ChannelList, QUALITY_HEADER_DOC, QueryBool, body_doc
from ..problems import ProblemError
from ...render.worker import RenderError
from ...scene.channels import channel_sizes
from ...scene.model import Scene

log = logging.getLogger("igserver.protocol")

router = APIRouter(tags=["frames"])

Format = Literal["jpeg", "png", "raw"]
FRAME_HEADERS_DOC = {
    "X-IG-Host-Frame": {"description": "host_frame of the state the frame shows", "schema": {"type": "integer"}},
    "X-IG-Frame": {"description": "IG frame number", "schema": {"type": "integer"}},
    "X-IG-Sim-Time": {"description": "sim_time the frame shows (s, the IG clock)", "schema": {"type": "number"}},
    "X-IG-Render-Ms": {"description": "render time in the render process (ms)", "schema": {"type": "number"}},
    "X-IG-EV100": {"description": "exposure the frame was rendered with (EV100)", "schema": {"type": "number"}},
    "X-IG-Illuminance-Lux": {"description": "natural horizontal illuminance at the camera (lux)",
                             "schema": {"type": "number"}},
    "X-IG-Quality": QUALITY_HEADER_DOC,
    "X-IG-Channel": {"description": "the channel the image shows (empty: the camera of a scene without channels)",
                     "schema": {"type": "string"}},
}
IMAGE_CONTENT = {media: {} for media in MEDIA_TYPES.values()}
MJPEG_BOUNDARY = "igframe"
CHANNELS_BOUNDARY = "igchannel"  # POST /v1/render's answer of a state with channels: one part per channel


def frame_fields(encoded: EncodedFrame, fmt: str) -> dict:
    """What every channel of a frame shares: the frame numbers, render time, exposure, operating point."""
    frame = encoded.frame
    return {
        "type": "frame",
        "frame": frame.ig_frame,
        "host_frame": frame.host_frame,
        "format": fmt,
        "render_ms": round(frame.render_ms, 3),
        "ev100": round(frame.ev100, 3),
        "illuminance_lux": float(f"{frame.illuminance_lux:.6g}"),
        "quality": getattr(frame, "overload", None),
    }


def frame_message(encoded: EncodedFrame, fmt: str, data: bytes, encode_ms: float, channel: str | None = None) -> dict:
    """One channel's image as a map (None: the first channel): the WebSocket message, and POST /v1/render's
    answer to msgpack callers. ``channel`` is named when the scene has channels."""
    part = encoded.part(channel)
    message = {**frame_fields(encoded, fmt), "width": part.width, "height": part.height, "data": data,
               "encode_ms": round(encode_ms, 3)}
    if getattr(encoded.frame, "channels", None):
        message["channel"] = encoded.channel_ids[0] if channel is None else channel
    return message


def channels_message(encoded: EncodedFrame, fmt: str, images: dict[str, tuple[bytes, float]]) -> dict:
    """Several channels of one frame in one map: the shared fields once, ``channels`` keyed by channel id
    (in the scene's order), each with its width, height, data and encode_ms."""
    channels = {}
    for channel, (data, encode_ms) in images.items():
        part = encoded.part(channel)
        channels[channel] = {"width": part.width, "height": part.height, "data": data,
                             "encode_ms": round(encode_ms, 3)}
    return {**frame_fields(encoded, fmt), "channels": channels}


async def image_response(runtime, encoded: EncodedFrame, fmt: str, quality: int, request: Request,
                         channel: str | None = None) -> Response:
    """One channel's image (None: the first) in the body, or its frame map for msgpack callers."""
    data, encode_ms = await encoded.encoded_async(fmt, quality, runtime.metrics, channel)
    runtime.metrics.frames_sent.inc(stream="http")
    headers = {**encoded.headers(channel), "X-IG-Encode-Ms": f"{encode_ms:.3f}", "Cache-Control": "no-store"}
    if negotiate(request.headers.get("accept"), None) == MSGPACK:
        return Response(encode(frame_message(encoded, fmt, data, encode_ms, channel), MSGPACK), media_type=MSGPACK,
                        headers=headers)
    return Response(data, media_type=MEDIA_TYPES[fmt], headers=headers)


async def channels_response(runtime, encoded: EncodedFrame, fmt: str, quality: int, request: Request) -> Response:
    """Every channel of a frame: a msgpack map keyed by channel id for msgpack callers, else
    ``multipart/mixed``, one image part per channel (X-IG-Channel, X-IG-Width, X-IG-Height) in the scene's
    order; the frame's own headers (numbers, render time, exposure) on the response."""
    images = await encoded.encoded_channels(fmt, quality, encoded.channel_ids, runtime.metrics)
    runtime.metrics.frames_sent.inc(stream="http")
    headers = {k: v for k, v in encoded.headers().items() if k not in ("X-IG-Width", "X-IG-Height", "X-IG-Channel")}
    headers.update({"X-IG-Channels": ",".join(images), "Cache-Control": "no-store",
                    "X-IG-Encode-Ms": f"{sum(ms for _, ms in images.values()):.3f}"})
    if negotiate(request.headers.get("accept"), None) == MSGPACK:
        return Response(encode(channels_message(encoded, fmt, images), MSGPACK), media_type=MSGPACK, headers=headers)
    body = bytearray()
    for channel, (data, _) in images.items():
        part = encoded.part(channel)
        body += (f"--{CHANNELS_BOUNDARY}\r\nContent-Type: {MEDIA_TYPES[fmt]}\r\nContent-Length: {len(data)}\r\n"
                 f"X-IG-Channel: {channel}\r\nX-IG-Width: {part.width}\r\nX-IG-Height: {part.height}\r\n\r\n").encode()
        body += data + b"\r\n"
    body += f"--{CHANNELS_BOUNDARY}--\r\n".encode()
    return Response(bytes(body), media_type=f"multipart/mixed; boundary={CHANNELS_BOUNDARY}", headers=headers)


async def render_or_503(runtime, coroutine):
    try:
        return await coroutine
    except ProblemError:
        raise
    except RenderError as exc:  # its message is written for clients: no traceback, no server paths
        raise ProblemError("render_unavailable", str(exc), headers={"Retry-After": "1"}) from None
    except Exception as exc:
        log.exception("render failed")
        raise ProblemError("render_unavailable", f"render failed ({type(exc).__name__}); see the server log",
                           headers={"Retry-After": "1"}) from None


def check_raw_size(runtime, fmt: str, width: int, height: int, pointer: str = "#/format", pixels: int | None = None,
                   what: str = "camera.width/height") -> None:
    """Raw RGBA frames are bounded (a 7680x4320 raw frame is 133 MB per client per frame). ``pixels``: the
    total of several channels sent in one message, when not width x height."""
    limit = runtime.settings.max_raw_frame_bytes
    nbytes = 4 * (width * height if pixels is None else pixels)
    if fmt == "raw" and nbytes > limit:
        shown = f"{width}x{height} frame" if pixels is None else f"message of {pixels} px"
        raise ProblemError("limits", f"a raw {shown} is {nbytes} bytes, over the "
                           f"{limit}-byte limit: ask for jpeg or png, or lower {what}",
                           [{"pointer": pointer, "detail": "raw frame too large"}])


def check_raw_channels(runtime, fmt: str, scene: Scene, channels: list[str] | None = None,
                       pointer: str = "#/format") -> None:
    """``check_raw_size`` for the images of ``channels`` (None: all) of ``scene`` sent in one message."""
    sizes = {cid: (w, h) for cid, w, h in channel_sizes(scene)}
    chosen = [sizes[c] for c in (channels if channels is not None else sizes) if c in sizes]
    if len(chosen) == 1:
        check_raw_size(runtime, fmt, *chosen[0], pointer, what="the channel's width/height" if scene.channels
                       else "camera.width/height")
    elif chosen:
        check_raw_size(runtime, fmt, 0, 0, pointer, pixels=sum(w * h for w, h in chosen),
                       what="the channels' width/height, or ask for fewer channels")


CHANNEL_QUERY = Query(None, max_length=32, description="channel id (GET /v1/channels; default: the first "
                      "channel, or the camera of a scene without channels)")


@router.get(
    "/v1/channels",
    summary="The channels of the current state",
    description="Each channel a frame delivers, in order: `id`, `width`, `height` (px), `heading`, `pitch`, "
    "`roll` (deg, offsets from the camera), `fov_left`, `fov_right`, `fov_up`, `fov_down` (deg, half-angles), "
    "`near`, `far` (m, in effect). A scene without channels has one implicit channel, the camera "
    "(id `\"\"`, `implicit: true`).",
    response_model=ChannelList,
    responses={200: {"content": {MSGPACK: {}}, "headers": {"X-IG-Revision": {"description": "accepted state "
                     "revision", "schema": {"type": "integer"}}}}},
)
async def get_channels(runtime: Runtime, fmt: ReplyFormat):
    store = runtime.store
    body = {"revision": store.revision, "channels": describe(store.scene)}
    return reply(body, fmt, headers={"X-IG-Revision": str(store.revision)})


@router.get(
    "/v1/frame",
    summary="A frame of the latest accepted state",
    response_class=Response,
    responses={200: {"content": IMAGE_CONTENT, "headers": FRAME_HEADERS_DOC}, 503: {"description": "render down"}},
)
async def get_frame(
    request: Request,
    runtime: Runtime,
    format: Format = Query("jpeg"),
    quality: int = Query(85, ge=1, le=100, description="JPEG quality"),
    channel: str | None = CHANNEL_QUERY,
):
    scene = runtime.store.scene
    channel = choose(state_channel_ids(scene), channel)
    check_raw_channels(runtime, format, scene, [channel])
    encoded = await render_or_503(runtime, runtime.pump.frame_of_current_state())
    channel = choose(encoded.channel_ids, channel)  # a state that fell back meanwhile may lack it
    return await image_response(runtime, encoded, format, quality, request, channel)


@router.post(
    "/v1/render",
    summary="Accept a state (patch, or ?replace=true) and answer with the frame of exactly that state",
    description="For hosts that step frame by frame. The image is in the body (headers carry the frame "
    "numbers), or, with `Accept: application/vnd.msgpack`, a frame map like the WebSocket's. A state with "
    "channels is answered with every channel: `multipart/mixed`, one image part per channel (headers "
    "`X-IG-Channel`, `X-IG-Width`, `X-IG-Height`), or for msgpack callers one map whose `channels` is keyed by "
    "channel id; `?channel=ID` answers that channel's image alone.",
    response_class=Response,
    openapi_extra=body_doc(PATCH_SCHEMA, "a partial Scene (or a complete one with ?replace=true)"),
    responses={200: {"content": {**IMAGE_CONTENT, MSGPACK: {}, f"multipart/mixed; boundary={CHANNELS_BOUNDARY}": {}},
                     "headers": FRAME_HEADERS_DOC},
               **PROBLEM_RESPONSES},
)
async def render_state(
    request: Request,
    runtime: Runtime,
    message: Message,
    replace: Annotated[QueryBool, Query(description="the body is a complete state, not a patch")] = False,
    format: Format = Query("jpeg"),
    quality: int = Query(85, ge=1, le=100),
    channel: str | None = Query(None, max_length=32, description="answer only this channel's image "
                                "(default: every channel of a scene with channels, else the camera's image)"),
):
    store = runtime.store
    scene = store.validate_replace(message) if replace else store.validate_patch(message)
    # checked against the new state, before it is accepted: a refused request changes nothing
    every = bool(scene.channels) and channel is None
    channel = None if every else choose(state_channel_ids(scene), channel)
    check_raw_channels(runtime, format, scene, None if every else [channel])
    scene = store.set_validated(scene, message)
    runtime.metrics.state_updates.inc(method="render")
    revision, accepted_at = store.revision, store.accepted_at
    encoded = await render_or_503(runtime, runtime.gateway.render(scene, revision, accepted_at))
    runtime.pump.publish(encoded)  # stream watchers see the stepped frames too
    if every:
        response = await channels_response(runtime, encoded, format, quality, request)
    else:
        response = await image_response(runtime, encoded, format, quality, request, channel)
    runtime.metrics.latency_ms.observe((time.perf_counter() - accepted_at) * 1e3, stream="http")
    return response


@router.get(
    "/v1/stream.mjpg",
    summary="MJPEG stream (multipart/x-mixed-replace) for browsers and video tools",
    description="Each part is the newest frame at the moment the connection can take it: the next part is "
    "chosen only when the previous one has left the server, so a slow reader skips frames instead of "
    "reading a backlog (what its own socket buffer holds it still reads first).",
    response_class=StreamingResponse,
    responses={200: {"content": {f"multipart/x-mixed-replace; boundary={MJPEG_BOUNDARY}": {}}}},
)
async def mjpeg_stream(
    request: Request,
    runtime: Runtime,
    fps: float = Query(0, ge=0, le=240, description="cap on frames per second (0: as rendered)"),
    frames: int = Query(0, ge=0, description="end the stream after this many frames (0: never)"),
    quality: int = Query(0, ge=0, le=100, description="JPEG quality (0: the server's default)"),
    channel: str | None = Query(None, max_length=32, description="channel id (GET /v1/channels; default: the "
                                "first channel of each frame, or the camera of a scene without channels); the "
                                "stream ends when the channel leaves the state"),
):
    if channel is not None:
        choose(state_channel_ids(runtime.store.scene), channel)
    quality = quality or runtime.settings.jpeg_quality
    interval = 1.0 / fps if fps else 0.0
    transport = transport_of(request.scope)

    async def parts():
        runtime.stream_clients["mjpeg"] += 1
        sent, last, last_revision = 0, None, -1
        after = None  # the newest frame seen: the last sent, or a later one without this channel
        t_sent = time.perf_counter()
        try:
            with runtime.pump.subscription():
                while (not frames or sent < frames) and not runtime.stopping.is_set():
                    # flow control: the next part is chosen only when the last one has left the server, so a
                    # slow reader gets the newest frame at its pace instead of a queue of old parts (flow.py)
                    if not await drained(transport, runtime.stopping):
                        break
                    # keepalive: resend the last frame when nothing new came, so players see the stream is live;
                    # the wait is short so that a server shutdown ends the stream at once
                    encoded = await runtime.pump.next_frame(after, timeout=min(runtime.settings.keepalive_s, 0.25))
                    if encoded is None and (last is None or time.perf_counter() - t_sent < runtime.settings.keepalive_s):
                        continue
                    encoded = encoded or last
                    if last is not None and encoded.ig_frame > last.ig_frame + 1:
                        runtime.metrics.frames_dropped.inc(encoded.ig_frame - last.ig_frame - 1, stream="mjpeg")
                    ids = encoded.channel_ids
                    if channel is not None and channel not in ids:
                        if channel in (getattr(encoded.frame, "missing", None) or ()):
                            after = encoded  # a cluster worker missed this frame: the channel comes with a later one
                            continue
                        break  # the channel left the state
                    shown = ids[0] if channel is None else channel
                    named = f"X-IG-Channel: {shown}\r\n" if getattr(encoded.frame, "channels", None) else ""
                    data, _ = await encoded.encoded_async("jpeg", quality, runtime.metrics, shown)
                    head = (
                        f"--{MJPEG_BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(data)}\r\n"
                        f"X-IG-Frame: {encoded.ig_frame}\r\nX-IG-Host-Frame: {encoded.host_frame}\r\n"
                        f"X-IG-Render-Ms: {encoded.frame.render_ms:.3f}\r\n{named}"
                        + "".join(f"{k}: {v}\r\n" for k, v in quality_headers(encoded.frame).items()) + "\r\n"
                    ).encode()
                    t_sent = time.perf_counter()
                    yield head + data + b"\r\n"
                    runtime.metrics.frames_sent.inc(stream="mjpeg")
                    if encoded.revision != last_revision:
                        if last is not None:  # a client's first frame shows an old state: not a latency
                            runtime.metrics.latency_ms.observe(
                                (time.perf_counter() - encoded.accepted_at) * 1e3, stream="mjpeg")
                        last_revision = encoded.revision
                    last = after = encoded
                    sent += 1
                    if interval:
                        await asyncio.sleep(max(0.0, interval - (time.perf_counter() - t_sent)))
        finally:
            runtime.stream_clients["mjpeg"] -= 1

    return StreamingResponse(
        parts(),
        media_type=f"multipart/x-mixed-replace; boundary={MJPEG_BOUNDARY}",
        headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
    )
