"""Liveness, readiness, metrics and the problem-type documentation."""

from __future__ import annotations

import time

from fastapi import APIRouter, Request, Response
from fastapi.responses import JSONResponse, PlainTextResponse

from ..dependencies import Runtime
from ..models import Health, Ready
from ..problems import PROBLEM_BASE, PROBLEM_KINDS, ProblemError

router = APIRouter(tags=["health"])


@router.get("/v1/health", response_model=Health, summary="The server process is alive")
async def health(runtime: Runtime) -> Health:
    return Health(uptime_s=round(time.time() - runtime.started_at, 3))


@router.get(
    "/v1/ready",
    response_model=Ready,
    summary="The render process is up (renderer, GL version); 503 while starting or restarting",
    responses={503: {"model": Ready, "description": "render process not ready"}},
)
async def ready(runtime: Runtime):
    # info() reads attributes only (no lock): answers at once even while a restart is in progress
    info = runtime.service.info()
    body = Ready(
        ready=bool(info.get("ready")),
        renderer=info.get("renderer"),
        gl_version=info.get("version"),
        software=info.get("software"),
        restarts=info.get("restarts", 0),
        pid=info.get("pid"),
        frames=info.get("frames", 0),
        revision=runtime.store.revision,
        error=None if info.get("ready") else (runtime.pump.last_error or runtime.start_error),
    )
    return JSONResponse(body.model_dump(), status_code=200 if body.ready else 503)


@router.get("/metrics", response_class=PlainTextResponse, summary="Prometheus metrics (text 0.0.4 or OpenMetrics)",
            tags=["metrics"], responses={200: {"content": {"application/openmetrics-text": {}}}})
async def metrics(request: Request, runtime: Runtime) -> Response:
    body, media_type = runtime.metrics.exposition(request.headers.get("accept"))
    return Response(body, media_type=media_type)


@router.get(PROBLEM_BASE + "{kind}", summary="What a problem type means", tags=["problems"])
async def problem_type(kind: str) -> dict:
    if kind not in PROBLEM_KINDS:
        raise ProblemError("not_found", f"no problem type {kind!r}")
    status, title = PROBLEM_KINDS[kind]
    return {"type": PROBLEM_BASE + kind, "title": title, "status": status}
