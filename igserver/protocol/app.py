"""The FastAPI application of protocol v1, and ``serve`` (what ``igserver serve`` runs).

Routes (details in OpenAPI at /docs and /openapi.json):
  GET /v1/health, GET /v1/ready, GET /metrics
  GET|PUT|PATCH /v1/state
  GET /v1/frame, POST /v1/render, GET /v1/stream.mjpg, WS /v1/ws
  GET|POST /v1/effects, GET|PATCH|DELETE /v1/effects/{id}
  GET /  (viewer page)
"""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from ..scene.model import Scene
from .codec import MSGPACK, PROBLEM_JSON, PROBLEM_MSGPACK, encode, negotiate
from .models import FrameMessage
from .problems import PROBLEM_KINDS, Problem, ProblemError, json_pointer
from .routers import effects, frames, health, query, state, viewer, ws
from .runtime import IGRuntime, ServerSettings

log = logging.getLogger("igserver.protocol")

API_DESCRIPTION = """
Network image generator, protocol v1. Bodies are msgpack (`application/vnd.msgpack`; also
`application/x-msgpack`, `application/msgpack`) or JSON, answered in the caller's format (Accept, else
the request's Content-Type). The message schema is the `Scene` model. Errors are RFC 9457 problem details
(`application/problem+json`, or the same members as `application/problem+msgpack`) with a JSON Pointer
to every offending field; a rejected message changes nothing.
"""


def problem_response(request: Request, problem: ProblemError) -> Response:
    runtime = getattr(request.app.state, "runtime", None)
    if runtime is not None:
        runtime.metrics.protocol_errors.inc(kind=problem.kind)
    fmt = negotiate(request.headers.get("accept"), request.headers.get("content-type"))
    media = PROBLEM_MSGPACK if fmt == MSGPACK else PROBLEM_JSON
    document = problem.document(request.url.path)
    return Response(encode(document, fmt), status_code=problem.status, media_type=media, headers=problem.headers)


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
        return problem_response(request, ProblemError(kind, str(exc.detail), status=exc.status_code))

    @app.exception_handler(Exception)
    async def on_unexpected(request: Request, exc: Exception):
        log.exception("unhandled error on %s", request.url.path)
        return problem_response(request, ProblemError("internal", type(exc).__name__))


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

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        await runtime.start()
        try:
            yield
        finally:
            await runtime.stop()

    app = FastAPI(
        title="igserver",
        version="1",
        summary="Image generator for training simulators",
        description=API_DESCRIPTION,
        lifespan=lifespan,
    )
    app.state.runtime = runtime
    _install_error_handlers(app)
    for module in (health, state, frames, ws, effects, query, viewer):
        app.include_router(module.router)

    # documents that no route returns as a pydantic model still belong in the schema
    original_openapi = app.openapi

    def openapi():
        if app.openapi_schema is None:
            schema = original_openapi()
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            for model in (Problem, FrameMessage):
                components[model.__name__] = model.model_json_schema(ref_template="#/components/schemas/{model}")
                for name, sub in components[model.__name__].pop("$defs", {}).items():
                    components.setdefault(name, sub)
            components.setdefault("Scene", Scene.model_json_schema(ref_template="#/components/schemas/{model}"))
            schema["x-problem-kinds"] = {k: {"status": s, "title": t} for k, (s, t) in PROBLEM_KINDS.items()}
        return app.openapi_schema or schema

    app.openapi = openapi
    return app


def uvicorn_config(app: FastAPI, host: str, port: int, **kwargs):
    import uvicorn

    # image frames do not compress: per-message deflate would only cost CPU and latency (DESIGN §8)
    return uvicorn.Config(
        app, host=host, port=port, ws_per_message_deflate=False, log_level=kwargs.pop("log_level", "warning"),
        lifespan="on", **kwargs,
    )


def serve(
    scene_path: str | Path | None = "demo",
    host: str = "127.0.0.1",
    port: int = 8600,
    width: int | None = None,
    height: int | None = None,
    settings: ServerSettings | None = None,
    device_index: int | None = None,
) -> None:
    """Load the scene, start the app under uvicorn, print the viewer URL; returns when the server stops."""
    import uvicorn

    from ..scene.files import load_scene
    from ..scene.patch import apply_patch

    scene = load_scene(scene_path) if scene_path else Scene()
    size = {k: v for k, v in (("width", width), ("height", height)) if v}
    if size:
        scene = apply_patch(scene, {"camera": size})
    app = create_app(scene=scene, settings=settings, device_index=device_index)
    server = uvicorn.Server(uvicorn_config(app, host, port))
    shown = f"[{host}]" if ":" in host else host
    print(f"igserver: viewer at http://{shown}:{port}/  (API docs: http://{shown}:{port}/docs)", flush=True)
    server.run()


def main(argv: list[str] | None = None) -> int:
    """``python -m igserver.protocol``: the same as ``igserver serve`` (used by the benchmark)."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m igserver.protocol")
    parser.add_argument("--scene", default=None, help="scene file or name in igserver/scenes/ (default: built-in defaults)")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=8600)
    parser.add_argument("--width", type=int)
    parser.add_argument("--height", type=int)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO)
    serve(args.scene, args.host, args.port, args.width, args.height)
    return 0
