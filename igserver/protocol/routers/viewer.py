"""The operator's page: the live MJPEG stream and a few controls, served as package data."""

from __future__ import annotations

from functools import lru_cache
from importlib import resources

from fastapi import APIRouter
from fastapi.responses import HTMLResponse

router = APIRouter(tags=["viewer"])


@lru_cache(maxsize=1)
def viewer_html() -> str:
    return resources.files("igserver.protocol").joinpath("viewer.html").read_text(encoding="utf-8")


@router.get("/", response_class=HTMLResponse, summary="Viewer page: live stream and controls")
async def viewer() -> HTMLResponse:
    return HTMLResponse(viewer_html(), headers={"Cache-Control": "no-cache"})
