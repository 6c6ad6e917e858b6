"""Frames over HTTP: one frame of the current state, render-exactly-this-state, and the MJPEG stream."""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Annotated, Literal

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import StreamingResponse

from ..codec import MSGPACK, encode, negotiate
from ..dependencies import Message, Runtime
from ..flow import drained, transport_of
from ..frames import EncodedFrame, quality_headers
from ..imaging import MEDIA_TYPES
from ..models import PATCH_SCHEMA, PROBLEM_RESPONSES, QUALITY_HEADER_DOC, QueryBool, body_doc
from ..problems import ProblemError
from ...render.worker import RenderError

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
}
IMAGE_CONTENT = {media: {} for media in MEDIA_TYPES.values()}
MJPEG_BOUNDARY = "igframe"


def frame_message(encoded: EncodedFrame, fmt: str, data: bytes, encode_ms: float) -> dict:
    """The frame as a map: the WebSocket message, and POST /v1/render's answer to msgpack callers."""
    frame = encoded.frame
    return {
        "type": "frame",
        "frame": frame.ig_frame,
        "host_frame": frame.host_frame,
        "width": frame.width,
        "height": frame.height,
        "format": fmt,
        "data": data,
        "render_ms": round(frame.render_ms, 3),
        "encode_ms": round(encode_ms, 3),
        "ev100": round(frame.ev100, 3),
        "illuminance_lux": float(f"{frame.illuminance_lux:.6g}"),
        "quality": getattr(frame, "overload", None),
    }


async def image_response(runtime, encoded: EncodedFrame, fmt: str, quality: int, request: Request) -> Response:
    data, encode_ms = await encoded.encoded_async(fmt, quality, runtime.metrics)
    runtime.metrics.frames_sent.inc(stream="http")
    headers = {**encoded.headers(), "X-IG-Encode-Ms": f"{encode_ms:.3f}", "Cache-Control": "no-store"}
    if negotiate(request.headers.get("accept"), None) == MSGPACK:
        return Response(encode(frame_message(encoded, fmt, data, encode_ms), MSGPACK), media_type=MSGPACK,
                        headers=headers)
    return Response(data, media_type=MEDIA_TYPES[fmt], headers=headers)


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


def check_raw_size(runtime, fmt: str, width: int, height: int, pointer: str = "#/format") -> None:
    """Raw RGBA frames are bounded (a 7680x4320 raw frame is 133 MB per client per frame)."""
    limit = runtime.settings.max_raw_frame_bytes
    if fmt == "raw" and width * height * 4 > limit:
        raise ProblemError("limits", f"a raw {width}x{height} frame is {width * height * 4} bytes, over the "
                           f"{limit}-byte limit: ask for jpeg or png, or lower camera.width/height",
                           [{"pointer": pointer, "detail": "raw frame too large"}])


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
):
    camera = runtime.store.scene.camera
    check_raw_size(runtime, format, camera.width, camera.height)
    encoded = await render_or_503(runtime, runtime.pump.frame_of_current_state())
    return await image_response(runtime, encoded, format, quality, request)


@router.post(
    "/v1/render",
    summary="Accept a state (patch, or ?replace=true) and answer with the frame of exactly that state",
    description="For hosts that step frame by frame. The image is in the body (headers carry the frame "
    "numbers), or, with `Accept: application/vnd.msgpack`, a frame map like the WebSocket's.",
    response_class=Response,
    openapi_extra=body_doc(PATCH_SCHEMA, "a partial Scene (or a complete one with ?replace=true)"),
    responses={200: {"content": {**IMAGE_CONTENT, MSGPACK: {}}, "headers": FRAME_HEADERS_DOC},
               **PROBLEM_RESPONSES},
)
async def render_state(
    request: Request,
    runtime: Runtime,
    message: Message,
    replace: Annotated[QueryBool, Query(description="the body is a complete state, not a patch")] = False,
    format: Format = Query("jpeg"),
    quality: int = Query(85, ge=1, le=100),
):
    store = runtime.store
    scene = store.validate_replace(message) if replace else store.validate_patch(message)
    check_raw_size(runtime, format, scene.camera.width, scene.camera.height)
    scene = store.set_validated(scene, message)
    runtime.metrics.state_updates.inc(method="render")
    revision, accepted_at = store.revision, store.accepted_at
    encoded = await render_or_503(runtime, runtime.gateway.render(scene, revision, accepted_at))
    runtime.pump.publish(encoded)  # stream watchers see the stepped frames too
    response = await image_response(runtime, encoded, format, quality, request)
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
):
    quality = quality or runtime.settings.jpeg_quality
    interval = 1.0 / fps if fps else 0.0
    transport = transport_of(request.scope)

    async def parts():
        runtime.stream_clients["mjpeg"] += 1
        sent, last, last_revision = 0, None, -1
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
                    encoded = await runtime.pump.next_frame(last, timeout=min(runtime.settings.keepalive_s, 0.25))
                    if encoded is None and (last is None or time.perf_counter() - t_sent < runtime.settings.keepalive_s):
                        continue
                    encoded = encoded or last
                    if last is not None and encoded.ig_frame > last.ig_frame + 1:
                        runtime.metrics.frames_dropped.inc(encoded.ig_frame - last.ig_frame - 1, stream="mjpeg")
                    data, _ = await encoded.encoded_async("jpeg", quality, runtime.metrics)
                    head = (
                        f"--{MJPEG_BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(data)}\r\n"
                        f"X-IG-Frame: {encoded.ig_frame}\r\nX-IG-Host-Frame: {encoded.host_frame}\r\n"
                        f"X-IG-Render-Ms: {encoded.frame.render_ms:.3f}\r\n"
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
                    last = encoded
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
