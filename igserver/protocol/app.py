"""The FastAPI application of protocol v1, and ``serve`` (what ``igserver serve`` runs).

Routes (details in OpenAPI at /docs and /openapi.json):
  GET /v1/health, GET /v1/ready, GET /metrics
  GET|PUT|PATCH /v1/state
  GET /v1/channels, GET /v1/frame, POST /v1/render, GET /v1/stream.mjpg, WS /v1/ws
  GET|POST /v1/effects, GET|PATCH|DELETE /v1/effects/{id}
  GET|PATCH /v1/clock
  GET /  (viewer page)
"""

from __future__ import annotations

import contextlib
import logging
import socket
import sys
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response
from fastapi_offline import FastAPIOffline
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import compile_path

from ..assets.images import set_profile_pixel_limit
from ..scene.model import Scene
from .codec import MSGPACK, PROBLEM_JSON, PROBLEM_MSGPACK, encode, negotiate
from .openapi import complete_schema
from .problems import ProblemError, json_pointer
from .routers import clock, docs, effects, frames, health, query, state, viewer, ws
from .runtime import IGRuntime
from .security import EdgeGuard
from .settings import ServerSettings

log = logging.getLogger("igserver.protocol")

API_DESCRIPTION = """
Network image generator, protocol v1. Bodies are msgpack (`application/vnd.msgpack`; also
`application/x-msgpack`, `application/msgpack`) or JSON, answered in the caller's format (Accept, else
the request's Content-Type); writes must carry one of these content types (415 otherwise). The message
schema is the `Scene` model (`ScenePatch` for partial updates); types are strict (`"10"` is not a number).
Errors are RFC 9457 problem details (`application/problem+json`, or the same members as
`application/problem+msgpack`) with a JSON Pointer to every offending field; a rejected message changes
nothing.

Authentication: when the server has a token (always when bound beyond loopback), send
`Authorization: Bearer <token>`; browsers open `/?access_token=<token>` once (a cookie follows).
Writes and WebSockets from a foreign `Origin`, and requests for a foreign `Host`, are refused (403).

The WebSocket `/v1/ws` (frames pushed with credit-based flow control) is described in
[/v1/ws-protocol](/v1/ws-protocol) and as an AsyncAPI 3.0 document at [/asyncapi.json](/asyncapi.json).
"""


def problem_response(request: Request, problem: ProblemError) -> Response:
    runtime = getattr(request.app.state, "runtime", None)
    if runtime is not None:
        runtime.metrics.protocol_errors.inc(kind=problem.kind)
    fmt = negotiate(request.headers.get("accept"), request.headers.get("content-type"))
    media = PROBLEM_MSGPACK if fmt == MSGPACK else PROBLEM_JSON
    document = problem.document(request.url.path)
    return Response(encode(document, fmt), status_code=problem.status, media_type=media, headers=problem.headers)


def allowed_methods(request: Request) -> list[str]:
    """The methods served at this request's path, read from the OpenAPI paths (one route per method)."""
    methods: set[str] = set()
    for template, item in request.app.openapi().get("paths", {}).items():
        if compile_path(template)[0].match(request.url.path):
            methods |= {m.upper() for m in item if m in ("get", "put", "post", "patch", "delete")}
    if "GET" in methods:
        methods.add("HEAD")
    return sorted(methods)


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(ProblemError)
    async def on_problem(request: Request, exc: ProblemError):
        return problem_response(request, exc)

    @app.exception_handler(RequestValidationError)
    async def on_request_validation(request: Request, exc: RequestValidationError):
        # query and path parameters (the bodies are decoded by the protocol's own codec)
        errors = [{"pointer": json_pointer(e.get("loc", ())), "detail": e.get("msg", "invalid")} for e in exc.errors()]
        detail = f"{errors[0]['pointer']}: {errors[0]['detail']}" if errors else None
        return problem_response(request, ProblemError("validation", detail, errors))

    @app.exception_handler(StarletteHTTPException)
    async def on_http(request: Request, exc: StarletteHTTPException):
        kind = {404: "not_found", 405: "method_not_allowed"}.get(exc.status_code, "bad_request")
        headers = dict(exc.headers or {})
        if exc.status_code == 405:  # Allow lists every method of the path (RFC 9110 §15.5.6), not one route's
            headers["Allow"] = ", ".join(allowed_methods(request))
        return problem_response(request, ProblemError(kind, str(exc.detail), status=exc.status_code, headers=headers))

    @app.exception_handler(Exception)
    async def on_unexpected(request: Request, exc: Exception):
        log.exception("unhandled error on %s", request.url.path)
        return problem_response(request, ProblemError("internal", "see the server log"))


def create_app(
    service=None,
    scene: Scene | None = None,
    settings: ServerSettings | None = None,
    device_index: int | None = None,
) -> FastAPI:
    """The app around a ``RenderService`` (created here, and started/stopped with the app, when None)."""
    if service is None:
        from ..render.worker import RenderService

        service = RenderService(scene or Scene(), device_index=device_index)
    runtime = IGRuntime(service, scene, settings)
    set_profile_pixel_limit(runtime.settings.max_profile_pixels)  # the scene model checks profiles with it

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        await runtime.start()
        try:
            yield
        finally:
            await runtime.stop()

    # Swagger UI and ReDoc from the fastapi-offline package: /docs works on an air-gapped network
    # (ReDoc's page is routers/docs.py's; Swagger's validator badge would be fetched from outside)
    app = FastAPIOffline(
        redoc_url=None,
        swagger_ui_parameters={"validatorUrl": None},
        title="igserver",
        version="1",
        summary="Image generator for training simulators",
        description=API_DESCRIPTION,
        lifespan=lifespan,
    )
    app.state.runtime = runtime
    _install_error_handlers(app)
    for module in (health, state, frames, ws, effects, clock, query, viewer, docs):
        app.include_router(module.router)
    app.add_middleware(EdgeGuard, settings=runtime.settings)

    original_openapi = app.openapi

    def openapi():
        if app.openapi_schema is None:
            app.openapi_schema = complete_schema(original_openapi())
        return app.openapi_schema

    app.openapi = openapi
    return app


def uvicorn_config(app: FastAPI, host: str, port: int, **kwargs):
    import uvicorn

    from .flow import TransportInScope, WebSocketsProtocol

    # image frames do not compress: per-message deflate would only cost CPU and latency (docs/design.md#performance);
    # the HTTP protocol puts the connection's transport in the scope for the MJPEG flow control, and
    # bounds how long a client may take to send a request (flow.py)
    settings = app.state.runtime.settings
    return uvicorn.Config(
        app, host=host, port=port, ws_per_message_deflate=False, log_level=kwargs.pop("log_level", "warning"),
        lifespan="on", http=TransportInScope, ws=WebSocketsProtocol, timeout_keep_alive=settings.idle_timeout_s,
        limit_concurrency=settings.max_connections, h11_max_incomplete_event_size=settings.max_header_bytes,
        **kwargs,
    )


def listening_socket(host: str, port: int) -> socket.socket:
    """Bind before anything is printed, so a port in use is the first (and only) thing the operator reads."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError:
        sock.close()
        raise
    return sock


def serve(
    scene_path: str | Path | None = "demo",
    width: int | None = None,
    height: int | None = None,
    settings: ServerSettings | None = None,
    device_index: int | None = None,
    preset: str | None = None,
    service=None,
    scene: Scene | None = None,
) -> int:
    """Load the scene, bind, start the app under uvicorn, print the viewer URL; returns when the server stops.

    Exit status 2 (with a message, no traceback) when the scene, the port or the security settings are wrong.
    ``preset``: the initial scene's quality preset (``quality.preset``). ``service``: a render service in
    place of the render process (tests, ``igserver cluster``). ``scene``: the initial scene itself, in place
    of ``scene_path``.
    """
    import uvicorn

    from ..scene.files import load_scene
    from ..scene.patch import apply_patch

    settings = settings or ServerSettings()
    host, port = settings.host, settings.port
    try:
        token = settings.bearer_token()
    except OSError as exc:
        print(f"igserver: cannot read the token file: {exc}", file=sys.stderr)
        return 2
    if settings.binds_beyond_loopback() and not token:
        print(f"igserver: refusing to listen on {host} without a token: anyone on the network could drive the IG. "
              "Set IGSERVER_TOKEN (or --token-file), or bind 127.0.0.1.", file=sys.stderr)
        return 2
    if scene is None:
        scene = load_scene(scene_path) if scene_path else Scene()
    size = {k: v for k, v in (("width", width), ("height", height)) if v}
    if size:
        scene = apply_patch(scene, {"camera": size})
    if preset:
        scene = apply_patch(scene, {"quality": {"preset": preset}})
    if settings.target_fps:
        scene = apply_patch(scene, {"quality": {"target_fps": settings.target_fps}})
    try:
        sock = listening_socket(host, port)
    except OSError as exc:
        print(f"igserver: cannot listen on {host}:{port}: {exc.strerror or exc} "
              "(another igserver running? pick another --port)", file=sys.stderr)
        return 2
    if settings.cigi:
        from ..cigi.listener import udp_bind_problem

        problem = udp_bind_problem(settings.cigi_bind, settings.cigi_port)
        if problem:
            sock.close()
            print(f"igserver: cannot listen for CIGI on udp {settings.cigi_bind}:{settings.cigi_port}: {problem} "
                  "(another IG running? pick another --cigi-port)", file=sys.stderr)
            return 2
    app = create_app(service, scene=scene, settings=settings, device_index=device_index)
    server = uvicorn.Server(uvicorn_config(app, host, port))
    shown = f"[{host}]" if ":" in host else host
    login = "?access_token=<token>" if token else ""
    print(f"igserver: viewer at http://{shown}:{port}/{login}  (API docs: http://{shown}:{port}/docs)", flush=True)
    with _exit_signals_end_the_run():
        server.run(sockets=[sock])
    return 0


@contextlib.contextmanager
def _exit_signals_end_the_run():
    """SIGTERM and SIGINT stop the server with status 0. uvicorn shuts down gracefully on either, then raises
    the signal again for the handler it found: with the defaults that ends the process by the signal
    (status -15 for ``docker stop``) or with a KeyboardInterrupt traceback. Here that handler does nothing:
    the shutdown is complete by then."""
    import signal

    saved = {signum: signal.signal(signum, lambda *_: None) for signum in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)
