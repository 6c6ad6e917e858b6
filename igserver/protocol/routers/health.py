"""Liveness, readiness, metrics and the problem-type documentation."""

from __future__ import annotations

import time

from fastapi import APIRouter, Request, Response
from fastapi.responses import JSONResponse, PlainTextResponse
from pydantic import Field

from ..dependencies import Runtime
from ..models import Health, Ready
from ..problems import PROBLEM_BASE, PROBLEM_KINDS, ProblemError

router = APIRouter(tags=["health"])


class ReadyReport(Ready):
    """/v1/ready: ready means a frame can be served now within the normal frame time."""

    progress: dict | None = Field(None, description="table precompute or compiling ahead in progress: {phase, fraction 0..1, elapsed_s}")
    last_precompute: dict | None = Field(None, description="the last finished precompute: {phase, elapsed_s}")
    unresponsive: str | None = Field(None, description="the watchdog's finding while the render process does not answer")
    fault: dict | None = Field(None, description="the last abandoned state: {revision, detail, fallback_revision}")


@router.get("/v1/health", response_model=Health, summary="The server process is alive")
async def health(runtime: Runtime) -> Health:
    return Health(uptime_s=round(time.time() - runtime.started_at, 3))


@router.get(
    "/v1/ready",
    response_model=ReadyReport,
    summary="A frame can be served in normal frame time (first frame and its table precompute done, render "
    "process answering); 503 while starting, precomputing, stopped or restarting, with the reason and progress",
    responses={503: {"model": ReadyReport, "description": "not ready"}},
)
async def ready(runtime: Runtime):
    # info() reads attributes only (no lock): answers at once even while a restart is in progress.
    # Readiness is decided first: the first frame may land between two reads, and the service counts a
    # frame before it marks itself warm, so figures read after a "ready" always include that frame.
    service = runtime.service
    reason = runtime.not_ready_reason()
    info = service.info()
    body = ReadyReport(
        ready=reason is None,
        renderer=info.get("renderer"),
        gl_version=info.get("version"),
        software=info.get("software"),
        restarts=info.get("restarts", 0),
        pid=info.get("pid"),
        frames=info.get("frames", 0),
        revision=runtime.store.revision,
        error=reason,
        progress=service.progress,
        last_precompute=service.last_progress and {k: service.last_progress[k] for k in ("phase", "elapsed_s")},
        unresponsive=runtime.unresponsive_now() if info.get("ready") else None,
        fault=runtime.gateway.fault,
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
